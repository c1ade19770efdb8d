"""The test harness's own rules: the ROS domain ids it hands out, the lane that runs the
protocols at device pace beside the other pytest-xdist workers, the watchdog on hung tests."""

from __future__ import annotations

import importlib.util
import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path
from types import ModuleType

import pytest
from xdist.scheduler import LoadScopeScheduling


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


SENT: list[int] = []  # every test sent to any worker, in order


class FakeWorker:
    """What the scheduler sees of a pytest-xdist worker: the tests sent, a shutdown."""

    def __init__(self, name: str) -> None:
        self.name = name
        self.gateway = type("Gateway", (), {"id": name})()
        self.shutting_down = False
        self.sent: list[int] = []

    def shutdown(self) -> None:
        self.shutting_down = True

    def send_runtest_some(self, indices: list[int]) -> None:
        self.sent.extend(indices)
        SENT.extend(indices)


class FakeConfig:
    def __init__(self, workers: int) -> None:
        self.option = type("Option", (), {"loadscopereorder": False})()
        self._workers = workers

    def getvalue(self, name: str) -> list[str]:
        assert name == "tx"
        return [f"{self._workers}*popen"]


COLLECTION = ["nodes/test_a.py::one", "nodes/test_p.py::soak", "nodes/test_a.py::two",
              "nodes/test_q.py::speeds", "physics/test_b.py::fem", "test_c.py::quick"]
PACED = {1, 3}
Scheduling = harness.lane_scheduling(
    LoadScopeScheduling, lambda nodeid: nodeid in {COLLECTION[i] for i in PACED})


def test_every_paced_test_named_exists():
    """A paced test renamed or moved would silently leave the lane."""
    for nodeid in harness.PACED_TESTS:
        path, name = nodeid.split("::")
        source = (Path(__file__).parent / path).read_text()
        assert f"def {name}(" in source, nodeid
        assert harness.is_paced(f"tactile_sensor/test/{nodeid}")
    assert not harness.is_paced("tactile_sensor/test/nodes/test_soak.py::test_a_run_too_short")


def _started(workers: int, collection: list[str] = COLLECTION, scheduling: type = Scheduling
             ) -> tuple[object, list[FakeWorker]]:
    SENT.clear()
    sched = scheduling(FakeConfig(workers))
    nodes = [FakeWorker(f"gw{i}") for i in range(workers)]
    for node in nodes:
        sched.add_node(node)
    for node in nodes:
        sched.add_node_collection(node, collection)
    sched.schedule()
    return sched, nodes


def _run_until_done(sched, nodes: list[FakeWorker], *, stop_before: int | None = None) -> None:
    """Each worker finishes its sent tests in turn, as their reports would arrive."""
    done: dict[str, int] = {node.name: 0 for node in nodes}
    progress = True
    while progress:
        progress = False
        for node in list(sched.nodes):
            if done[node.name] < len(node.sent):
                if stop_before is not None and node.sent[done[node.name]] == stop_before:
                    continue
                sched.mark_test_complete(node, node.sent[done[node.name]])
                done[node.name] += 1
                progress = True


def test_the_lane_runs_every_paced_test_and_nothing_else():
    sched, (gw0, gw1, lane) = _started(3)
    _run_until_done(sched, [gw0, gw1, lane])
    assert set(lane.sent) == PACED and lane.shutting_down
    assert not PACED & set(gw0.sent + gw1.sent)
    assert sorted(gw0.sent + gw1.sent + lane.sent) == list(range(len(COLLECTION)))
    assert not sched.workqueue and sched.tests_finished
    # whole files stay on one worker, so their module fixtures are built once
    assert {0, 2} <= set(gw0.sent) or {0, 2} <= set(gw1.sent)


def test_a_single_worker_runs_the_paced_tests_after_the_rest():
    sched, (only,) = _started(1)
    _run_until_done(sched, [only])
    assert sorted(only.sent) == list(range(len(COLLECTION)))
    assert set(only.sent[-2:]) == PACED


def test_a_crashed_lane_is_replaced_and_the_new_worker_takes_its_tests():
    sched, (gw0, gw1, lane) = _started(3)
    sched.remove_node(lane)  # crashed before reporting anything
    _run_until_done(sched, [gw0, gw1])
    assert not PACED & set(gw0.sent + gw1.sent) and "paced" in sched.workqueue
    replacement = FakeWorker("gw3")
    sched.add_node(replacement)
    sched.add_node_collection(replacement, COLLECTION)
    sched.schedule()
    _run_until_done(sched, [gw0, gw1, replacement])
    assert set(replacement.sent) == PACED and not sched.workqueue


def test_a_worker_with_files_left_when_the_lane_crashes_takes_the_paced_tests_last():
    more = COLLECTION + [f"sim/test_{name}.py::one" for name in "defgh"]
    sched, (gw0, gw1, lane) = _started(3, more)
    sched.remove_node(lane)  # pytest-xdist may not replace it (its crash limit)
    _run_until_done(sched, [gw0, gw1])
    ran = gw0.sent + gw1.sent
    assert sorted(ran) == list(range(len(more))) and not sched.workqueue
    assert set((gw0.sent if set(gw0.sent) >= PACED else gw1.sent)[-2:]) == PACED


REAL_TIME = ["pkg/test/nodes/test_grip.py::grasp", "pkg/test/nodes/test_soak.py::soak",
             "pkg/test/physics/test_fem.py::a", "pkg/test/sim/test_adc.py::pace",
             "pkg/test/physics/test_fem.py::b", "pkg/test/analysis/test_bags.py::m",
             "pkg/test/control/test_loop.py::c", "pkg/test/test_top.py::t",
             "pkg/test/launch/test_launch.py::l", "pkg/test/hardware/test_link.py::h"]
REAL_TIME_SCHEDULING = harness.lane_scheduling(
    LoadScopeScheduling, lambda nodeid: nodeid == REAL_TIME[1])


def test_while_the_lane_runs_the_others_take_the_real_time_files_last():
    sched, (gw0, gw1, lane) = _started(3, REAL_TIME, REAL_TIME_SCHEDULING)
    _run_until_done(sched, [gw0, gw1, lane], stop_before=1)  # the soak still runs
    general = [i for i in SENT if i != 1]
    folders = [REAL_TIME[i].split("/")[2] for i in general]
    real_time = [f in ("nodes", "launch", "sim", "hardware") for f in folders]
    assert real_time == sorted(real_time), folders  # every other file first
    assert lane.sent == [1] and sorted(general) == [0, *range(2, 10)]


def test_once_the_lane_is_done_the_files_go_in_collection_order():
    sched, (gw0, gw1, lane) = _started(3, REAL_TIME, REAL_TIME_SCHEDULING)
    sched.mark_test_complete(lane, 1)  # the soak is done before any other test
    first = len(SENT)
    _run_until_done(sched, [gw0, gw1, lane])
    assert SENT[first:] == sorted(SENT[first:]) and len(SENT[first:]) >= 3, SENT


RECORD = """
import json, os

def _record(name):
    with open(os.environ["LANE_LOG"], "a") as log:
        log.write(json.dumps({"test": name, "worker": os.environ["PYTEST_XDIST_WORKER"],
                              "nice": os.nice(0)}) + "\\n")
"""


@pytest.mark.slow
def test_under_xdist_the_paced_tests_share_one_niced_worker(tmp_path: Path):
    """The real pytest-xdist with the harness as its plugin, on a file named like the
    project's two paced tests, one of them beside six others."""
    soak, rate = sorted(harness.PACED_TESTS, reverse=True)
    for nodeid, name in ((soak, "paced_one"), (rate, "paced_two")):
        path = tmp_path / "test" / nodeid.split("::")[0]
        path.parent.mkdir(parents=True, exist_ok=True)
        others = "" if name == "paced_two" else (
            "import pytest\n\n@pytest.mark.parametrize('i', range(6))\n"
            "def test_other(i):\n    _record(f'other{i}')\n")
        path.write_text(f"{RECORD}\n\ndef {nodeid.split('::')[1]}():\n    _record('{name}')\n"
                        f"\n\n{others}")
    log = tmp_path / "lane.jsonl"
    env = dict(os.environ, LANE_LOG=str(log),
               PYTHONPATH=os.pathsep.join([str(Path(__file__).parent), os.environ.get(
                   "PYTHONPATH", "")]))
    done = subprocess.run(
        [sys.executable, "-m", "pytest", "-c", os.devnull, "--rootdir", str(tmp_path),
         "-p", "conftest", "-n", "3", "--dist", "loadgroup", "-q", "-p", "no:cacheprovider",
         str(tmp_path / "test")],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr
    runs = [json.loads(line) for line in log.read_text().splitlines()]
    assert len(runs) == 8
    paced = [r for r in runs if r["test"] == "paced_one" or r["test"] == "paced_two"]
    assert len(paced) == 2
    lane = {r["worker"] for r in paced}
    others = [r for r in runs if r["test"].startswith("other")]
    assert len(lane) == 1 and not lane & {r["worker"] for r in others}, runs
    base = os.nice(0)
    assert {r["nice"] for r in paced} == {min(base + harness.LANE_NICENESS, 19)}
    assert {r["nice"] for r in others} == {base}


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
