"""Fixtures for tests that run real nodes in real processes over real ROS topics.

Each test gets its own ROS domain (localhost only), so lingering processes of one test can
never answer another. Child processes inherit the environment of ``make test`` (venv and
``install/setup.bash``) plus the source tree on PYTHONPATH.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

SOURCE = Path(__file__).resolve().parents[1]
_DOMAIN_BASE = int(os.environ.get("TACTILE_TEST_DOMAIN_BASE", str(os.getpid() % 50 + 20)))
_counter = iter(range(10_000))


@pytest.fixture
def ros_domain(monkeypatch: pytest.MonkeyPatch) -> int:
    """A ROS domain id unique to this test, set for the test process and its children."""
    domain = _DOMAIN_BASE + next(_counter) % 100
    monkeypatch.setenv("ROS_DOMAIN_ID", str(domain))
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    return domain


class Spawned:
    """A child process whose output goes to a log file shown when a test fails."""

    def __init__(self, argv: list[str], log: Path, env: dict[str, str]) -> None:
        self.argv = argv
        self.log = log
        self._log_file = log.open("wb")
        self.proc = subprocess.Popen(
            argv, stdout=self._log_file, stderr=subprocess.STDOUT, env=env,
            start_new_session=True,
        )

    def output(self) -> str:
        if not self._log_file.closed:
            self._log_file.flush()
        return self.log.read_text(errors="replace")

    def wait_for_output(self, text: str, timeout_s: float = 20.0) -> bool:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if text in self.output():
                return True
            if self.proc.poll() is not None:
                return text in self.output()
            time.sleep(0.05)
        return False

    def send_signal(self, sig: int) -> None:
        if self.proc.poll() is None:
            os.killpg(self.proc.pid, sig)

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


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Multi-process ROS tests share two cores with every other process of the run, so a
    timing bound can be missed by scheduling alone: they get one rerun (pytest-rerunfailures;
    a rerun is reported in the summary, so a test that fails twice still fails the run)."""
    for item in items:
        if "/test/nodes/" in str(item.path):
            item.add_marker(pytest.mark.flaky(reruns=1, reruns_delay=1))
