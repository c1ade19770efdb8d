"""The test harness's own arithmetic: the ROS domain ids it hands out."""

from __future__ import annotations

import importlib.util
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
MAX_DOMAIN_ID, domain_ids = harness.MAX_DOMAIN_ID, harness.domain_ids


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
