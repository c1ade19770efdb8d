"""Fixtures for tests that run real nodes in real processes over real ROS topics.

Each test gets its own ROS domain (localhost only), so lingering processes of one test can
never answer another. Child processes inherit the environment of ``make test`` (venv and
``scripts/env.sh``) plus the source tree on PYTHONPATH.
"""

from __future__ import annotations

import multiprocessing.process
import os
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
from hypothesis import settings

# The tests' own helper modules (waiting.py), importable in every import mode.
sys.path.insert(0, str(Path(__file__).resolve().parent))
from ros2_tools import ros2_tools_missing, skip_reason

# No per-example deadline: hypothesis's 200 ms is a timed assertion, which a busy core breaks
# (a motor-model case took 353 ms beside two CPU-bound jobs). A test's own @settings may
# still set one.
settings.register_profile("tactile", deadline=None)
settings.load_profile("tactile")

SOURCE = Path(__file__).resolve().parents[1]
#: The highest ROS domain id: Fast DDS derives its ports from the id and refuses any above
#: ("Calculated port number is too high. Probably the domainId is over 232"), and every
#: node of that test then exits.
MAX_DOMAIN_ID = 232


def domain_ids(base: int) -> range:
    """The block of domain ids a run starting at ``base`` hands out, one per test in turn:
    100 ids, fewer where the block would pass MAX_DOMAIN_ID (a base of 222 gives 222-232)."""
    if not 0 <= base <= MAX_DOMAIN_ID:
        raise pytest.UsageError(f"TACTILE_TEST_DOMAIN_BASE={base} is not a ROS domain id; "
                                f"give one from 0 to {MAX_DOMAIN_ID}.")
    return range(base, min(base + 100, MAX_DOMAIN_ID + 1))


def worker_domains(ids: range, worker: str, workers: int) -> tuple[int, range]:
    """This pytest-xdist worker's share of the run's ids: (its own default domain, the ids
    its tests take in turn). Workers take every ``workers``-th id, so no two share one, and
    each keeps its first id as the domain of the tests that start nodes in-process without
    the ``ros_domain`` fixture (without it, two workers' in-process nodes would meet in the
    run's base domain). Without xdist (``worker`` empty) the whole block is one worker's.
    xdist names the worker that replaces a crashed one gw2, gw3, ... in turn: it takes the
    share of gw0, gw1, ... in turn, the crashed ones' when they crash in that order, so a
    crash fails its own test and not every test after it."""
    index = int(worker.removeprefix("gw")) if worker.startswith("gw") else 0
    share = ids[index % max(workers, 1)::max(workers, 1)]
    if len(share) < 2:
        raise pytest.UsageError(
            f"{len(ids)} ROS domain ids cannot give each of {workers} pytest-xdist workers two; "
            f"run fewer workers (-n) or a lower TACTILE_TEST_DOMAIN_BASE.")
    return share[0], share[1:]


_WORKER_DOMAIN, _DOMAINS = worker_domains(
    domain_ids(int(os.environ.get("TACTILE_TEST_DOMAIN_BASE", str(os.getpid() % 50 + 20)))),
    os.environ.get("PYTEST_XDIST_WORKER", ""),
    int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "1")))
if os.environ.get("PYTEST_XDIST_WORKER"):
    os.environ["ROS_DOMAIN_ID"] = str(_WORKER_DOMAIN)
_counter = iter(range(10_000))


@pytest.fixture
def ros_domain(monkeypatch: pytest.MonkeyPatch) -> int:
    """A ROS domain id unique to this test, set for the test process and its children."""
    domain = _DOMAINS[next(_counter) % len(_DOMAINS)]
    monkeypatch.setenv("ROS_DOMAIN_ID", str(domain))
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    return domain


def _default_sigint() -> None:
    """Children start with Ctrl-C and hang-up at their defaults, as from a terminal. A test
    run started as a background job of a non-interactive shell inherits SIGINT ignored, and
    ``ros2 launch`` then ignores the SIGINT a test sends it (measured: every SIGINT test timed
    out at 5 s); one started under ``nohup`` inherits SIGHUP ignored, and a node then outlives
    the SIGHUP a test sends it."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    signal.signal(signal.SIGHUP, signal.SIG_DFL)


#: The longest a ``wait_for_output(..., while_progressing=True)`` waits [s].
PROGRESS_CEILING_S = 1200.0


class Spawned:
    """A child process whose output goes to a log file shown when a test fails."""

    def __init__(self, argv: list[str], log: Path, env: dict[str, str]) -> None:
        self.argv = argv
        self.log = log
        self._log_file = log.open("wb")
        self.proc = subprocess.Popen(
            argv, stdout=self._log_file, stderr=subprocess.STDOUT, env=env,
            start_new_session=True, preexec_fn=_default_sigint,
        )

    def output(self) -> str:
        if not self._log_file.closed:
            self._log_file.flush()
        return self.log.read_text(errors="replace")

    def wait_for_output(self, text: str, timeout_s: float = 20.0, *,
                        while_progressing: bool = False) -> bool:
        """With ``while_progressing``, ``timeout_s`` counts from the process's last new output
        (at most PROGRESS_CEILING_S in all): for a start that computes and says so, such as
        a model node filling a cold FEM cache (a progress line every few seconds; minutes in
        all beside a busy core)."""
        start = time.monotonic()
        deadline, seen = start + timeout_s, 0
        while time.monotonic() < deadline:
            output = self.output()
            if text in output:
                return True
            if self.proc.poll() is not None:
                return text in self.output()
            if while_progressing and len(output) > seen:
                seen = len(output)
                deadline = min(time.monotonic() + timeout_s, start + PROGRESS_CEILING_S)
            time.sleep(0.05)
        return False

    def send_signal(self, sig: int) -> None:
        if self.proc.poll() is None:
            os.killpg(self.proc.pid, sig)

    def interrupt(self, *, group: bool, timeout_s: float = 60.0) -> tuple[int | None, float]:
        """SIGINT to the process (``group=False``, as a supervisor sends it) or to its whole
        process group (as Ctrl-C in a terminal); (exit status or None, seconds to exit).
        The wait ends as soon as the process exits: the generous bound is for a busy
        machine, where a clean shutdown can take longer than on an idle one (a prompt one is
        judged by what it did, e.g. that ``ros2 launch`` escalated to no SIGTERM)."""
        start = time.monotonic()
        if self.proc.poll() is None:
            if group:
                os.killpg(self.proc.pid, signal.SIGINT)
            else:
                self.proc.send_signal(signal.SIGINT)
        try:
            code: int | None = self.proc.wait(timeout_s)
        except subprocess.TimeoutExpired:
            code = None
        return code, time.monotonic() - start

    def stop(self, timeout_s: float = 10.0) -> int | None:
        if self.proc.poll() is None:
            self.send_signal(signal.SIGINT)
            try:
                self.proc.wait(timeout_s)
            except subprocess.TimeoutExpired:
                self.send_signal(signal.SIGKILL)
                self.proc.wait(5)
        self._log_file.close()
        return self.proc.returncode


@pytest.fixture
def spawn(tmp_path: Path, request: pytest.FixtureRequest) -> Iterator[Callable[..., Spawned]]:
    """Start ``python -m module args...`` (or any argv) as a child; stopped at teardown."""
    children: list[Spawned] = []

    def start(*argv: str, module: str | None = None) -> Spawned:
        env = dict(os.environ)
        env["PYTHONPATH"] = os.pathsep.join(
            [str(SOURCE), *filter(None, [env.get("PYTHONPATH")])])
        env["PYTHONUNBUFFERED"] = "1"
        full = [sys.executable, "-m", module, *argv] if module else list(argv)
        name = (module or Path(argv[0]).name).replace(".", "_")
        child = Spawned(full, tmp_path / f"{name}-{len(children)}.log", env)
        children.append(child)
        return child

    yield start
    failed = getattr(request.node, "rep_call", None)
    for child in reversed(children):
        child.stop()
        if failed is not None and failed.failed:
            sys.stderr.write(f"\n--- output of {' '.join(child.argv)} ---\n{child.output()}")


@pytest.hookimpl(hookwrapper=True, tryfirst=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo[None]) -> Iterator[None]:
    outcome = yield
    report = outcome.get_result()
    setattr(item, f"rep_{report.when}", report)


def _needs_ros2_tools(item: pytest.Item) -> bool:
    """The one definition of the tests that need a ROS 2 installation: skipped where
    ros2_tools.py finds the tools missing, selected by ``make test-ros2``."""
    return (item.get_closest_marker("ros2_tools") is not None
            or item.path.name.startswith("test_ros2_")
            or bool({"ros2", "lifecycle_states"} & set(getattr(item, "fixturenames", ()))))


def pytest_itemcollected(item: pytest.Item) -> None:
    """Each such test carries the ``ros2_tools`` mark, so that ``-m ros2_tools`` (what
    ``make test-ros2`` runs) selects exactly the tests the wheels path skips."""
    if _needs_ros2_tools(item):
        item.add_marker(pytest.mark.ros2_tools)


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Tests of ``ros2 launch`` and the ``ros2`` CLI are skipped where those are missing
    (the summary counts them in one line).

    Multi-process ROS tests share two cores with every other process of the run, so a
    timing bound can be missed by scheduling alone: they get one rerun (pytest-rerunfailures;
    a rerun is reported in the summary, so a test that fails twice still fails the run)."""
    missing = ros2_tools_missing()
    for item in items:
        if "/test/nodes/" in str(item.path):
            item.add_marker(pytest.mark.flaky(reruns=1, reruns_delay=1))
        if missing and _needs_ros2_tools(item):
            item.add_marker(pytest.mark.skip(reason=skip_reason(missing)))
        if _starts_processes(item):
            item.add_marker(pytest.mark.slow)
    # Files with slow tests first, the nodes' (whole protocols at device pace) first of all:
    # pytest-xdist hands out whole files in this order (scripts/test.sh), so the long ones
    # start early and the short ones fill the gaps instead of one long file running alone
    # at the end.
    slow_files = {item.path for item in items if item.get_closest_marker("slow")}
    items.sort(key=lambda item: (item.path.name not in DEVICE_PACED_FILES,
                                 item.path not in slow_files,
                                 "/test/nodes/" not in str(item.path)))


#: The files of the whole protocols run at device pace (1 kHz, real time): minutes of mostly
#: waiting, each a mock device, a driver and a recorder using under half a core.
DEVICE_PACED_FILES = frozenset({"test_bench_protocols.py", "test_array_bringup.py",
                                "test_soak.py", "test_rate_calibration_end_to_end.py"})
#: Their work unit under ``ProtocolLaneScheduling``.
DEVICE_PACED_LANE = "device-paced protocols"


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_make_scheduler(config: pytest.Config, log: object) -> object | None:
    """With two or more workers and ``--dist loadfile`` (scripts/test.sh), one worker starts
    with the device-paced protocol files, the others with the rest
    (``ProtocolLaneScheduling``)."""
    workers = getattr(config.option, "numprocesses", None) or 0
    if config.getvalue("dist") != "loadfile" or workers < 2:
        return None
    return protocol_lane_scheduling()(config, log)


def protocol_lane_scheduling() -> type:
    """pytest-xdist's file scheduling with the device-paced protocols in one lane.

    The protocols wait most of their minutes at device pace while the other tests mostly
    compute. Handed out like any file, they ran side by side on both workers first, and the
    computing tests then shared the cores with each other. Here one worker (the lane) takes
    the protocol files as one unit, one after the other, while the others run the rest beside
    it; once its protocols are sent, the lane's worker shares the rest too. At most one
    protocol runs at a time, and the number of tests running at once stays the number of
    workers. Should the lane's worker die, its unit goes back in the queue and the next
    worker to ask takes it over. Without protocol files in the run there is no lane."""
    from xdist.scheduler import LoadFileScheduling  # only where pytest-xdist runs the tests

    class ProtocolLaneScheduling(LoadFileScheduling):
        def __init__(self, config: pytest.Config, log: object = None) -> None:
            super().__init__(config, log)
            self.lane: object | None = None

        def _split_scope(self, nodeid: str) -> str:
            path = nodeid.split("::", 1)[0]
            if path.rsplit("/", 1)[-1] in DEVICE_PACED_FILES:
                return DEVICE_PACED_LANE
            return super()._split_scope(nodeid)

        def _assign_work_unit(self, node: object) -> None:
            if self.lane is None and DEVICE_PACED_LANE in self.workqueue:
                self.workqueue.move_to_end(DEVICE_PACED_LANE, last=False)
                self.lane = node
            super()._assign_work_unit(node)

        def remove_node(self, node: object) -> str | None:
            if node is self.lane and self._pending_of(self.assigned_work[node]):
                self.lane = None  # it died with tests left: they go back in the queue
            return super().remove_node(node)

    return ProtocolLaneScheduling


#: Fixtures that start processes: a test using one is slow by definition.
PROCESS_FIXTURES = frozenset({"spawn", "ros2", "lifecycle_states", "own_processes"})


def _starts_processes(item: pytest.Item) -> bool:
    return (bool(PROCESS_FIXTURES & set(getattr(item, "fixturenames", ())))
            or any(part in str(item.path) for part in ("/test/nodes/", "/test/launch/")))


#: ``make test-fast`` sets this: the contributor's loop runs only tests that start no
#: process (tests marked ``slow`` are deselected), and a test that starts one anyway fails
#: with a sentence saying to mark it, so the fast loop stays fast as tests are added.
FAST_LOOP = os.environ.get("TACTILE_TEST_FAST") == "1"
_running: list[str] = [""]


class ProcessInFastLoop(RuntimeError):
    """A test that ``make test-fast`` runs started a process."""


def _refuse_process(*_args: object, **_kwargs: object) -> None:
    raise ProcessInFastLoop(
        f"{_running[0] or 'a fixture'} starts a process, which 'make test-fast' does not run: "
        "mark the test (or its module) pytest.mark.slow so that only 'make test' runs it.")


@pytest.fixture(scope="session", autouse=True)
def _fast_loop_starts_no_process() -> Iterator[None]:
    """Set up before any module's fixtures, so that those are checked too."""
    if not FAST_LOOP:
        yield
        return
    saved = subprocess.Popen.__init__, multiprocessing.process.BaseProcess.start
    subprocess.Popen.__init__ = _refuse_process  # type: ignore[method-assign,assignment]
    multiprocessing.process.BaseProcess.start = _refuse_process  # type: ignore[method-assign]
    yield
    subprocess.Popen.__init__, multiprocessing.process.BaseProcess.start = saved


@pytest.hookimpl(tryfirst=True)
def pytest_runtest_setup(item: pytest.Item) -> None:
    _running[0] = item.nodeid


def pytest_terminal_summary(terminalreporter: pytest.TerminalReporter) -> None:
    """One line per reason for the tests that did not run, with their count."""
    reasons: dict[str, int] = {}
    for report in terminalreporter.stats.get("skipped", []):
        reason = report.longrepr[2] if isinstance(report.longrepr, tuple) else str(report)
        reason = reason.removeprefix("Skipped: ")
        reasons[reason] = reasons.get(reason, 0) + 1
    for reason, count in sorted(reasons.items()):
        terminalreporter.write_line(f"not run: {count} test(s): {reason}")


#: Lines that must never appear in a node's output, shutdown included.
SHUTDOWN_FAULTS = ("Traceback", "never retrieved", "context is invalid")


@pytest.fixture
def own_processes(monkeypatch: pytest.MonkeyPatch) -> Callable[[], list[str]]:
    """Lists the processes this test started that still run (children inherit a mark in
    their environment, also the ones that detach, such as a ros2 daemon)."""
    mark = f"{os.getpid()}.{next(_counter)}"
    monkeypatch.setenv("TACTILE_TEST_PROCESS_MARK", mark)
    needle = f"\0TACTILE_TEST_PROCESS_MARK={mark}\0".encode()

    def running() -> list[str]:
        found = []
        for entry in Path("/proc").iterdir():
            if not entry.name.isdigit() or int(entry.name) == os.getpid():
                continue
            try:
                environ = b"\0" + (entry / "environ").read_bytes()
                cmdline = (entry / "cmdline").read_bytes()
            except OSError:
                continue
            if needle in environ and cmdline:
                command = cmdline.replace(b"\0", b" ").decode(errors="replace")
                found.append(f"{entry.name}: {command}")
        return found

    return running


@pytest.fixture
def ros2(ros_domain: int, tmp_path: Path) -> Callable[..., subprocess.CompletedProcess[str]]:
    """The real ``ros2`` command line (built by ``make setup``) in this test's domain; each
    call's command and output are appended to ``ros2-cli.log``. Tests pass ``--no-daemon``
    where a verb has it, so no daemon outlives them. Without a daemon a verb discovers the
    graph itself for ``--spin-time`` and may answer 'Node not found' for a node that runs
    (the ros2 CLI's discovery window, not the node): such a call is repeated, up to 4
    times."""
    if shutil.which("ros2") is None:
        pytest.fail("the ros2 command line is missing: source a ROS 2 installation")
    log = tmp_path / "ros2-cli.log"

    def run(*args: str, timeout_s: float = 60.0) -> subprocess.CompletedProcess[str]:
        for _ in range(4):
            result = subprocess.run(["ros2", *args], capture_output=True, text=True,
                                    timeout=timeout_s, env=dict(os.environ))
            with log.open("a") as f:
                f.write(f"$ ros2 {' '.join(args)}  -> {result.returncode}\n{result.stdout}"
                        f"{result.stderr}\n")
            if "Node not found" not in result.stderr:
                break
        return result

    return run


@pytest.fixture
def lifecycle_states(ros2: Callable[..., subprocess.CompletedProcess[str]]
                     ) -> Callable[[set[str]], dict[str, str]]:
    """``ros2 lifecycle get`` (every lifecycle node in one call), repeated until ``nodes``
    are all discovered and active or 60 s passed; node -> state label."""

    def get(nodes: set[str]) -> dict[str, str]:
        deadline = time.monotonic() + 60.0
        while True:
            out = ros2("lifecycle", "get", "--no-daemon", "--spin-time", "2").stdout
            states = dict(line.split(": ", 1) for line in out.splitlines() if ": " in line)
            states = {name: state.split()[0] for name, state in states.items()}
            if all(states.get(n) == "active" for n in nodes) or time.monotonic() > deadline:
                return states
            time.sleep(0.5)

    return get


def driver_filter_gain_db(points: int = 9) -> float:
    """How much the driver's default filter lowers white noise after the analysis's
    ``points``-point mean [dB]: the mock's noise is the paper's 31.49 dB behind a 9-point
    mean alone, so the dynamic range the analysis measures on the driver's output sits
    this much higher (1.5 dB for the Savitzky-Golay filter)."""
    import numpy as np

    from tactile_sensor.sensing.filters import DEFAULT_FILTER, make_filter

    fir = make_filter(DEFAULT_FILTER, 1000.0, {})
    for _ in range(400):  # a full window first: the filter's start-up is not its response
        fir.update(0.0)
    impulse = np.array([fir.update(1.0 if k == 0 else 0.0) for k in range(400)])
    mean = np.ones(points) / points
    return float(20 * np.log10(np.linalg.norm(mean) / np.linalg.norm(np.convolve(impulse,
                                                                                 mean))))


def _check_compression_metrics(mt: dict) -> None:
    """The paper's compression response (Sec. III-B), with the tolerances explained in
    test_bench_protocols.py."""
    assert mt["cycles"] == 1
    assert mt["full_scale_n"] == pytest.approx(7.0, rel=0.15)  # "approximately 7 N" at 3 mm
    assert mt["sensitivity_v_per_n"] == pytest.approx(0.07, rel=0.25)
    assert mt["dynamic_range_db"] == pytest.approx(31.49 + driver_filter_gain_db(), abs=3.0)
    assert 0 < mt["hysteresis_pct_fs"] < 8.0
    assert mt["prediction"]["rmse_pct_fs"] < 15.0  # Fig. 7b: model and measurement agree


@pytest.fixture
def check_compression_metrics() -> Callable[[dict], None]:
    """Asserts ``tactile-sensor analyze``'s metrics.json of one compression run."""
    return _check_compression_metrics
