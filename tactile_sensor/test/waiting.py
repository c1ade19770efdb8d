"""The tests' one wait on a condition (conftest.py puts this folder on ``sys.path``).

A wait ends as soon as its condition holds; the bound is only for a condition that never
comes, so it is generous: a busy machine may be slow to get there, and a test never waits
for a fixed time instead.
"""

from __future__ import annotations

import time
from collections.abc import Callable

#: Upper bound [s] of a wait on a condition that a process or a device brings about.
PATIENCE_S = 60.0


def wait_until(predicate: Callable[[], object], timeout_s: float = PATIENCE_S,
               poll_s: float = 0.01) -> bool:
    """True as soon as ``predicate()`` is; False if it is not by ``timeout_s`` [s]."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(poll_s)
    return bool(predicate())


def wait_while_advancing(predicate: Callable[[], object], progress: Callable[[], object],
                         stall_s: float = PATIENCE_S, poll_s: float = 0.01) -> bool:
    """True as soon as ``predicate()`` is; False once ``progress()`` (a stream's length,
    its newest stamp) has not changed for ``stall_s`` [s]. For a stream a starved listener
    takes in slower than real time: it gets there late, but it keeps getting nearer."""
    last, moved = progress(), time.monotonic()
    while not predicate():
        now = progress()
        if now != last:
            last, moved = now, time.monotonic()
        elif time.monotonic() - moved > stall_s:
            return bool(predicate())
        time.sleep(poll_s)
    return True
