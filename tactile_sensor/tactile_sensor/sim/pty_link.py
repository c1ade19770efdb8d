"""A pseudo-terminal that looks like a USB serial device at a stable path.

The mock devices own the master side; the driver opens the slave through a symlink, just
as it opens /dev/ttyUSB0 on a robot. Closing the link removes the symlink, which is how
the mocks simulate an unplugged cable.
"""

from __future__ import annotations

import contextlib
import errno
import os
import select
import termios
import time
import tty
from pathlib import Path
from types import TracebackType

from tactile_sensor.sim.errors import SimError


class PtyLink:
    """Master side of a raw pseudo-terminal published at ``link_path``."""

    def __init__(self, link_path: Path | str) -> None:
        self.link_path = Path(link_path)
        self._master: int | None = None
        self._slave: int | None = None
        self.slave_name: str | None = None

    @property
    def is_open(self) -> bool:
        return self._master is not None

    def open(self) -> int:
        """Create the terminal and the symlink; returns the master fd."""
        if self._master is not None:
            return self._master
        parent = self.link_path.parent
        if not parent.is_dir():
            raise SimError(
                f"Cannot create the device link {self.link_path}: folder {parent} does not "
                "exist; create it or choose another --link path."
            )
        if self.link_path.exists() and not self.link_path.is_symlink():
            raise SimError(
                f"Cannot create the device link {self.link_path}: a regular file is in the "
                "way; remove it or choose another --link path."
            )
        master, slave = os.openpty()
        # Raw mode on the slave: binary frames must pass untouched (no echo, no CR/LF
        # translation). Keeping our own slave fd open also stops the master from seeing
        # EIO whenever the client closes and reopens the port.
        tty.setraw(slave, termios.TCSANOW)
        os.set_blocking(master, False)
        self._master, self._slave = master, slave
        self.slave_name = os.ttyname(slave)
        tmp = self.link_path.with_name(f".{self.link_path.name}.{os.getpid()}.tmp")
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()
        os.symlink(self.slave_name, tmp)
        os.replace(tmp, self.link_path)
        return master

    def close(self) -> None:
        """Remove the symlink and close the terminal (the 'cable' is pulled)."""
        if self.link_path.is_symlink() and self.slave_name is not None:
            with contextlib.suppress(OSError):
                if os.readlink(self.link_path) == self.slave_name:
                    self.link_path.unlink()
        for fd in (self._master, self._slave):
            if fd is not None:
                with contextlib.suppress(OSError):
                    os.close(fd)
        self._master = self._slave = None
        self.slave_name = None

    def wait_released(self, timeout_s: float) -> bool:
        """Wait until no program has the port open, at most ``timeout_s``; True if none has.

        For shutting down: a mock that exits while its client still reads looks like a
        pulled cable to the client. Our own slave fd (which keeps the master from seeing a
        hang-up) is closed first, so the master reports POLLHUP once the last client has
        closed the port.
        """
        if self._master is None:
            return True
        if self._slave is not None:
            with contextlib.suppress(OSError):
                os.close(self._slave)
            self._slave = None
        poller = select.poll()
        poller.register(self._master, 0)  # POLLHUP and POLLERR are always reported
        deadline = time.monotonic() + timeout_s
        while True:
            remaining = deadline - time.monotonic()
            events = poller.poll(max(0, int(remaining * 1000)))
            if any(event & (select.POLLHUP | select.POLLERR) for _, event in events):
                return True
            if remaining <= 0:
                return False

    def fileno(self) -> int:
        if self._master is None:
            raise SimError(f"The device link {self.link_path} is not open; call open() first.")
        return self._master

    def write(self, data: bytes) -> int:
        """Write without blocking; bytes the host has no room for are dropped, like USB."""
        if self._master is None or not data:
            return 0
        try:
            return os.write(self._master, data)
        except BlockingIOError:
            return 0
        except OSError as exc:
            if exc.errno in (errno.EAGAIN, errno.EIO):
                return 0
            raise

    def write_all(self, data: bytes, timeout_s: float = 1.0) -> bool:
        """Write every byte unless the host stalls for ``timeout_s``; True when all went."""
        view = memoryview(data)
        while view:
            n = self.write(bytes(view))
            if n:
                view = view[n:]
                continue
            if self._master is None:
                return False
            _, ready, _ = select.select([], [self._master], [], timeout_s)
            if not ready:
                return False
        return True

    def read(self, max_bytes: int = 4096, timeout_s: float = 0.1) -> bytes:
        """Bytes the host sent, or b'' after ``timeout_s`` with nothing to read."""
        if self._master is None:
            return b""
        ready, _, _ = select.select([self._master], [], [], timeout_s)
        if not ready:
            return b""
        try:
            return os.read(self._master, max_bytes)
        except (BlockingIOError, InterruptedError):
            return b""
        except OSError as exc:
            if exc.errno == errno.EIO:
                return b""
            raise

    def __enter__(self) -> PtyLink:
        self.open()
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()
