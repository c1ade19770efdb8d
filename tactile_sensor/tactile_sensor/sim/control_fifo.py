"""A line-based control FIFO: another process writes commands to it (``echo "fault
overload" > PATH``) and the device applies them between its own work, without a thread."""

from __future__ import annotations

import contextlib
import errno
import os
import stat
import sys
from collections.abc import Callable
from pathlib import Path

from tactile_sensor.sim.errors import SimError


class ControlFifo:
    """The FIFO at ``path`` (created on :meth:`open`, removed on :meth:`close`); each line
    goes to ``apply``, and what it did, or its ``SimError``, to stderr after ``name``."""

    def __init__(self, path: Path, name: str) -> None:
        self.path = path
        self.name = name
        self._fd: int | None = None
        self._buffer = b""

    def open(self) -> None:
        path = self.path
        if path.exists() and not stat.S_ISFIFO(path.stat().st_mode):
            raise SimError(f"Cannot create the control FIFO {path}: a file is in the way; "
                           "remove it or choose another --control path.")
        if not path.exists():
            try:
                os.mkfifo(path)
            except OSError as exc:
                raise SimError(f"Cannot create the control FIFO {path}: {exc.strerror}; "
                               "choose another --control path.") from None
        # O_RDWR keeps the FIFO open between writers, so no EOF storms.
        self._fd = os.open(path, os.O_RDWR | os.O_NONBLOCK)

    def close(self) -> None:
        if self._fd is None:
            return
        with contextlib.suppress(OSError):
            os.close(self._fd)
        self._fd = None
        with contextlib.suppress(OSError):
            self.path.unlink()

    def poll(self, apply: Callable[[str], str]) -> None:
        """Apply every complete line written since the last poll (none when closed)."""
        if self._fd is None:
            return
        try:
            chunk = os.read(self._fd, 4096)
        except OSError as exc:
            if exc.errno in (errno.EAGAIN, errno.EWOULDBLOCK):
                return
            raise
        self._buffer += chunk
        while b"\n" in self._buffer:
            line, self._buffer = self._buffer.split(b"\n", 1)
            text = line.decode("utf-8", "replace").strip()
            if not text:
                continue
            try:
                print(f"{self.name}: {apply(text)}", file=sys.stderr, flush=True)
            except SimError as exc:
                print(f"{self.name}: {exc}", file=sys.stderr, flush=True)
