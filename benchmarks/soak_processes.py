"""The soak's child processes: started with a log each, stopped, sampled from /proc for
memory and file descriptors, and told of faults through their control FIFOs."""

from __future__ import annotations

import contextlib
import math
import os
import re
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

WAIT_S = 90.0  # the most any condition may take before it counts as failed
SAMPLE_PERIOD_S = 5.0
SELF = "soak (this process)"


def say(text: str) -> None:
    print(text, flush=True)


class Proc:
    """One child process with its log; remembers every pid it ran as."""

    def __init__(self, name: str, argv: list[str], folder: Path, env: dict[str, str]) -> None:
        self.name, self.argv, self.env = name, argv, env
        self.log_path = folder / f"{name}.log"
        self.proc: subprocess.Popen[bytes] | None = None
        self.pids: list[int] = []
        self.exit_codes: list[int | None] = []

    def start(self) -> None:
        with self.log_path.open("ab") as log:
            self.proc = subprocess.Popen(self.argv, env=self.env, stdout=log,
                                         stderr=subprocess.STDOUT, start_new_session=True)
        self.pids.append(self.proc.pid)

    @property
    def pid(self) -> int:
        assert self.proc is not None
        return self.proc.pid

    def alive(self) -> bool:
        return self.proc is not None and self.proc.poll() is None

    def log(self) -> str:
        return self.log_path.read_text(errors="replace") if self.log_path.exists() else ""

    def stop(self, sig: int = signal.SIGINT, timeout_s: float = 30.0) -> int | None:
        if self.proc is None:
            return None
        if self.proc.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                os.kill(self.proc.pid, sig)
            try:
                self.proc.wait(timeout_s)
            except subprocess.TimeoutExpired:
                os.killpg(self.proc.pid, signal.SIGKILL)
                self.proc.wait(10)
        self.exit_codes.append(self.proc.returncode)
        return self.proc.returncode


def wait_until(condition: Callable[[], Any], timeout_s: float = WAIT_S,
               period_s: float = 0.05) -> Any:
    """The condition's first true value, or None after ``timeout_s``."""
    deadline = time.monotonic() + timeout_s
    while True:
        value = condition()
        if value or time.monotonic() > deadline:
            return value or None
        time.sleep(period_s)


def node_argv(spec_name: str, configuration: Any, namespace: str, *extra: str,
              params_file: Path | None = None) -> list[str]:
    """``python -m <node module> --ros-args`` as the launch file gives it, in a namespace
    (``params_file`` after the configuration's: its node sections beat theirs, a global
    ``-p`` would not)."""
    from tactile_sensor.nodes.bringup_runner import node_arguments

    spec = next(s for s in configuration.nodes if s.name == spec_name)
    return [sys.executable, "-m", spec.module, *node_arguments(spec, params_file),
            "-r", f"__ns:={namespace}", "-p", "autostart:=true", *extra]


class Clock(Protocol):
    """What the sampler stamps its samples with (the monitor's clock)."""

    def now(self) -> float: ...


def proc_sample(pid: int) -> tuple[float, int] | None:
    """(VmRSS [MB], open file descriptors) of a live process, None when it is gone."""
    try:
        status = Path(f"/proc/{pid}/status").read_text()
        fds = len(os.listdir(f"/proc/{pid}/fd"))
    except (FileNotFoundError, ProcessLookupError, PermissionError):
        return None
    match = re.search(r"^VmRSS:\s+(\d+) kB", status, re.M)
    return (int(match.group(1)) / 1024.0 if match else math.nan), fds


@dataclass
class Series:
    name: str
    pid: int
    samples: list[tuple[float, float, int]] = field(default_factory=list)  # (t, MB, fds)


class Sampler:
    def __init__(self, processes: Callable[[], dict[str, int]], monitor: Clock) -> None:
        self.processes, self.monitor = processes, monitor
        self.series: dict[tuple[str, int], Series] = {}
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._run, daemon=True)

    def sample_once(self) -> None:
        t = self.monitor.now()
        for name, pid in self.processes().items():
            got = proc_sample(pid)
            if got is not None:
                self.series.setdefault((name, pid), Series(name, pid)).samples.append(
                    (t, *got))

    def _run(self) -> None:
        while not self.stop.wait(SAMPLE_PERIOD_S):
            self.sample_once()


def write_fifo(path: Path, line: str) -> None:
    fd = os.open(path, os.O_WRONLY | os.O_NONBLOCK)
    try:
        os.write(fd, (line + "\n").encode())
    finally:
        os.close(fd)
