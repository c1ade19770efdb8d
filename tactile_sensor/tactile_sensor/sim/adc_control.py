"""The mock ADC's control FIFO (``tactile-sensor mock adc --control PATH``): each line
written to the named pipe runs one of the device's commands (unplug, garbage, drop,
stats)."""

from __future__ import annotations

import contextlib
import errno
import os
import select
import stat
import threading
from pathlib import Path
from typing import Protocol

from tactile_sensor.sim.errors import SimError


class CommandTarget(Protocol):
    """What the FIFO drives: ``MockAdcDevice.command``."""

    def command(self, line: str) -> str: ...


class ControlFifo:
    """A named pipe at ``path``; each line written to it runs ``device.command``."""

    def __init__(self, path: Path, device: CommandTarget) -> None:
        if path.exists() and not stat.S_ISFIFO(path.stat().st_mode):
            raise SimError(f"--control {path} exists and is not a FIFO; remove it or choose "
                           "another path.")
        try:
            if not path.exists():
                os.mkfifo(path)
            # Opened read-write so the pipe never reports EOF between writers.
            self._fd = os.open(path, os.O_RDWR | os.O_NONBLOCK)
        except OSError as exc:
            raise SimError(f"Cannot create the control FIFO {path} ({exc.strerror}); choose "
                           "a writable --control path.") from None
        self.path = path
        self._device = device
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="mock-adc-control", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        pending = b""
        while not self._stop.is_set():
            ready, _, _ = select.select([self._fd], [], [], 0.1)
            if not ready:
                continue
            try:
                pending += os.read(self._fd, 4096)
            except OSError as exc:
                if exc.errno in (errno.EAGAIN, errno.EINTR):
                    continue
                raise
            *lines, pending = pending.split(b"\n")
            for raw in lines:
                answer = self._device.command(raw.decode("utf-8", "replace"))
                if answer:
                    print(f"mock adc: {answer}", flush=True)

    def close(self) -> None:
        self._stop.set()
        self._thread.join(1.0)
        os.close(self._fd)
        with contextlib.suppress(OSError):
            self.path.unlink()
