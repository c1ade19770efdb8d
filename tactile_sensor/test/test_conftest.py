"""The test harness's own rules: the ROS domain ids it hands out, the watchdog on hung tests."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
import textwrap
from pathlib import Path
from types import ModuleType, SimpleNamespace

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


def test_a_worker_replacing_a_crashed_one_takes_a_share_of_the_block():
    shares = {i: worker_domains(domain_ids(20), f"gw{i}", 2) for i in range(4)}
    assert shares[2] == shares[0] and shares[3] == shares[1]
    assert shares[0][0] != shares[1][0]


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


class _Config:
    """What pytest-xdist's schedulers read of the configuration: ``-n N --dist loadfile``."""

    def __init__(self, workers: int = 2, dist: str = "loadfile") -> None:
        self.option = SimpleNamespace(numprocesses=workers, loadscopereorder=False)
        self._values = {"tx": [f"{workers}*popen"], "dist": dist}

    def getvalue(self, name: str) -> object:
        return self._values[name]


class _Worker:
    """A pytest-xdist worker as its scheduler sees it: the tests sent, and shutdown."""

    def __init__(self, name: str) -> None:
        self.name, self.sent, self.shutting_down = name, [], False
        self.gateway = SimpleNamespace(id=name)

    def send_runtest_some(self, indices: list[int]) -> None:
        self.sent.extend(indices)

    def shutdown(self) -> None:
        self.shutting_down = True


RUN = [f"tactile_sensor/test/{folder}/test_{name}.py::test_{i}"
       for folder, name in [("nodes", "driver_node"), ("nodes", "gripper_node"),
                            ("physics", "fem"), ("analysis", "metrics"), ("sensing", "tare"),
                            ("control", "grasp"), ("sim", "adc"), ("hardware", "xm430")]
       for i in range(3)] + [
       f"tactile_sensor/test/nodes/{name}::test_{i}" for name in
       ("test_soak.py", "test_bench_protocols.py", "test_array_bringup.py",
        "test_rate_calibration_end_to_end.py") for i in range(2)]
LANE_FILES = {"test_soak.py", "test_bench_protocols.py", "test_array_bringup.py",
              "test_rate_calibration_end_to_end.py"}


def _started(collection: list[str], workers: int = 2) -> tuple[object, list[_Worker]]:
    scheduler = harness.pytest_xdist_make_scheduler(_Config(workers), None)
    nodes = [_Worker(f"gw{i}") for i in range(workers)]
    for node in nodes:
        scheduler.add_node(node)
    for node in nodes:
        scheduler.add_node_collection(node, collection)
    scheduler.schedule()
    return scheduler, nodes


def _finish(scheduler: object, nodes: list[_Worker], collection: list[str]
            ) -> dict[str, list[str]]:
    """Completes the tests each worker was sent, one per worker in turn, as workers would;
    returns which worker ran which test, in order."""
    ran = {node.name: [] for node in nodes}
    while any(len(ran[node.name]) < len(node.sent) for node in nodes):
        for node in nodes:
            if len(ran[node.name]) < len(node.sent):
                index = node.sent[len(ran[node.name])]
                ran[node.name].append(collection[index])
                scheduler.mark_test_complete(node, index)
    assert scheduler.tests_finished
    return ran


def _file(nodeid: str) -> str:
    return nodeid.split("::")[0].rsplit("/", 1)[-1]


def _lane_first(tests: list[str]) -> bool:
    """The protocol files come first and together, then only other files."""
    files = [_file(t) in LANE_FILES for t in tests]
    return files == sorted(files, reverse=True)


def test_one_worker_starts_with_the_protocols_while_the_other_runs_the_rest():
    scheduler, nodes = _started(RUN)
    lane = next(node for node in nodes if _file(RUN[node.sent[0]]) in LANE_FILES)
    other = next(node for node in nodes if node is not lane)
    # The lane was sent every protocol at once, the other none of them, even though the
    # protocol files come last in this collection.
    assert {_file(RUN[i]) for i in lane.sent if _file(RUN[i]) in LANE_FILES} == LANE_FILES
    assert not {_file(RUN[i]) for i in other.sent} & LANE_FILES
    ran = _finish(scheduler, nodes, RUN)
    assert _lane_first(ran[lane.name]) and len(ran[lane.name]) > 8  # then it shared the rest
    assert not {_file(t) for t in ran[other.name]} & LANE_FILES
    assert sorted(t for tests in ran.values() for t in tests) == sorted(RUN)  # each once
    assert all(node.shutting_down for node in nodes)


def test_protocols_of_a_lane_worker_that_died_are_taken_over_by_the_next_to_ask():
    scheduler, nodes = _started(RUN, workers=3)
    lane = next(node for node in nodes if _file(RUN[node.sent[0]]) in LANE_FILES)
    crashed = scheduler.remove_node(lane)  # it died in its first test
    assert crashed == RUN[lane.sent[0]]
    survivors = [node for node in nodes if node is not lane]
    before = {node.name: len(node.sent) for node in survivors}
    done = dict.fromkeys(before, 0)
    taker = None
    while taker is None:
        for node in survivors:  # the workers finish their tests until one asks for more
            scheduler.mark_test_complete(node, node.sent[done[node.name]])
            done[node.name] += 1
            if len(node.sent) > before[node.name]:
                taker = node
                break
    # The first unit handed out after the crash is the whole lane, to one worker.
    assert {_file(RUN[i]) for i in taker.sent[before[taker.name]:]} == LANE_FILES
    ran = _finish(scheduler, survivors, RUN)
    assert sum(bool({_file(t) for t in tests} & LANE_FILES) for tests in ran.values()) == 1
    assert set(RUN) - {RUN[lane.sent[0]]} <= {t for tests in ran.values() for t in tests}


def test_without_protocol_files_every_worker_shares_the_run():
    rest = [nodeid for nodeid in RUN if _file(nodeid) not in LANE_FILES]
    scheduler, nodes = _started(rest)
    ran = _finish(scheduler, nodes, rest)
    assert all(ran.values()) and sorted(t for ts in ran.values() for t in ts) == sorted(rest)


@pytest.mark.parametrize(("workers", "dist"), [(1, "loadfile"), (2, "load"), (2, "loadscope")])
def test_one_worker_or_another_distribution_keep_xdists_scheduling(workers: int, dist: str):
    assert harness.pytest_xdist_make_scheduler(_Config(workers, dist), None) is None


def test_make_test_ros2_refuses_in_one_sentence_naming_what_is_missing(
        monkeypatch: pytest.MonkeyPatch):
    import ros2_tools  # beside conftest.py, which put its folder on sys.path

    monkeypatch.setattr(ros2_tools.shutil, "which", lambda _name: None)
    monkeypatch.setattr(ros2_tools, "_importable", lambda module, _attr: module == "launch")
    missing = ros2_tools.ros2_tools_missing()
    assert missing == "the ros2 command and launch_ros"
    monkeypatch.setenv("DISTRO", "kilted")
    sentence = ros2_tools.refusal(missing)
    assert sentence.startswith("make test-ros2: this shell lacks the ros2 command and "
                               "launch_ros: source a ROS 2 installation")
    assert "/opt/ros/kilted/setup.bash" in sentence
    assert "\n" not in sentence and sentence.endswith("run it again.")


def test_the_wheels_summary_counts_the_skipped_ros2_tests_and_names_their_command():
    import ros2_tools

    reason = ros2_tools.skip_reason("the ros2 command")
    skipped = [SimpleNamespace(longrepr=("f.py", 1, f"Skipped: {reason}")) for _ in range(3)]
    lines: list[str] = []
    reporter = SimpleNamespace(stats={"skipped": skipped}, write_line=lines.append)
    harness.pytest_terminal_summary(reporter)
    assert lines == [f"not run: 3 test(s): {reason}"]
    assert "needs the ros2 command" in reason and "'make test-ros2' runs these tests" in reason


@pytest.mark.parametrize(("path", "fixtures", "marked", "needs"), [
    ("test/launch/test_ros2_launch_bench.py", (), False, True),
    ("test/nodes/test_driver_node.py", ("spawn", "lifecycle_states"), False, True),
    ("test/nodes/test_driver_node.py", ("ros2",), False, True),
    ("test/nodes/test_gripper_commands.py", ("spawn",), True, True),
    ("test/launch/test_launch_files.py", ("tmp_path",), False, False),
])
def test_the_tests_needing_ros2_tools_carry_the_mark_make_test_ros2_selects(
        path: str, fixtures: tuple[str, ...], marked: bool, needs: bool):
    marks = ["ros2_tools"] if marked else []
    item = SimpleNamespace(
        path=Path(path), fixturenames=fixtures, add_marker=lambda m: marks.append(m.name),
        get_closest_marker=lambda name: name if name in marks else None)
    harness.pytest_itemcollected(item)
    assert ("ros2_tools" in marks) is needs
