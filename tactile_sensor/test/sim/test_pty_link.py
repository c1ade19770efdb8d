"""PtyLink.wait_released: a mock shutting down keeps its device until the client let go."""

from __future__ import annotations

import os
import threading
import time

from tactile_sensor.sim.pty_link import PtyLink

PATIENCE_S = 30.0  # upper bound of a wait that ends as soon as its condition holds


def test_wait_released_returns_once_the_last_client_closed_the_port(tmp_path):
    with PtyLink(tmp_path / "dev") as link:
        client = os.open(tmp_path / "dev", os.O_RDWR | os.O_NOCTTY)
        assert link.wait_released(0.2) is False  # the client still has it open
        threading.Timer(0.3, os.close, args=(client,)).start()
        start = time.monotonic()
        # True, not the timeout's False: it woke because the client closed (a bound, not a
        # time: a busy machine may take longer to get there)
        assert link.wait_released(PATIENCE_S) is True
        assert time.monotonic() - start > 0.25  # not before the client closed
    assert not (tmp_path / "dev").exists()


def test_wait_released_without_clients_or_when_closed_returns_at_once(tmp_path):
    link = PtyLink(tmp_path / "dev")
    assert link.wait_released(5.0) is True  # never opened
    link.open()
    start = time.monotonic()
    assert link.wait_released(PATIENCE_S) is True  # nobody opened the port
    assert time.monotonic() - start < PATIENCE_S / 2  # at once, not at the timeout
    link.close()
