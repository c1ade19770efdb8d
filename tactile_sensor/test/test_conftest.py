"""The test harness's own rules: the ROS domain ids it hands out, the watchdog on hung tests."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
import textwrap
from pathlib import Path
from types import ModuleType

import pytest


def _harness() -> ModuleType:  # conftest.py is not importable by name under --import-mode=importlib
    spec = importlib.util.spec_from_file_location(
        "tactile_test_harness", Path(__file__).with_name("conftest.py"))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


harness = _harness()
MAX_DOMAIN_ID, domain_ids, worker_domains = (harness.MAX_DOMAIN_ID, harness.domain_ids,
                                              harness.worker_domains)


@pytest.mark.parametrize(("base", "first", "last"), [
    (20, 20, 119),     # scripts/test.sh's and the pid-derived bases: 100 ids
    (132, 132, 231),
    (222, 222, 232),   # a base near the top: only the ids Fast DDS accepts
    (232, 232, 232),
])
def test_every_domain_id_handed_out_is_one_dds_accepts(base: int, first: int, last: int):
    ids = domain_ids(base)
    assert (ids[0], ids[-1]) == (first, last)
    assert max(ids) <= MAX_DOMAIN_ID


@pytest.mark.parametrize("base", [-1, 233, 300])
def test_a_base_outside_the_domain_ids_is_refused_in_one_sentence(base: int):
    with pytest.raises(pytest.UsageError, match=f"TACTILE_TEST_DOMAIN_BASE={base} is not"):
        domain_ids(base)


@pytest.mark.parametrize("workers", [1, 2, 3, 4])
def test_xdist_workers_never_share_a_domain_id(workers: int):
    shares = [worker_domains(domain_ids(20), f"gw{i}", workers) for i in range(workers)]
    every = [own for own, _ in shares] + [i for _, ids in shares for i in ids]
    assert len(every) == len(set(every)) == 100
    assert all(len(ids) >= 20 for _, ids in shares)


def test_without_xdist_the_whole_block_is_one_workers():
    own, ids = worker_domains(domain_ids(20), "", 1)
    assert own == 20 and (ids[0], ids[-1]) == (21, 119)


def test_more_workers_than_domain_ids_is_refused_in_one_sentence():
    with pytest.raises(pytest.UsageError, match="cannot give each of 8 pytest-xdist workers two"):
        worker_domains(domain_ids(225), "gw0", 8)


@pytest.mark.slow
def test_a_test_that_hangs_holding_the_interpreter_lock_is_ended_with_its_stack(
        tmp_path: Path):
    (tmp_path / "test_hang.py").write_text(textwrap.dedent("""
        import ctypes

        def test_hangs_in_c():
            ctypes.PyDLL(None).sleep(600)  # PyDLL keeps the interpreter lock, as a C hang does
    """))
    project = Path(__file__).resolve().parents[2] / "pyproject.toml"
    done = subprocess.run(
        [sys.executable, "-m", "pytest", "-c", str(project), "--rootdir", str(tmp_path),
         "-o", "faulthandler_timeout=2", "-p", "no:cacheprovider",
         str(tmp_path / "test_hang.py")],
        cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert done.returncode != 0
    assert "Timeout (0:00:02)!" in done.stderr, done.stderr
    assert "test_hang.py\", line 5 in test_hangs_in_c" in done.stderr, done.stderr
