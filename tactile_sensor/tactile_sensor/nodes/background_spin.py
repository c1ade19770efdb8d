"""An executor spun in a background thread that stops spinning before it shuts down.

``executor.shutdown()`` while another thread is inside ``executor.spin()`` races on Jazzy's
rclpy 7: the spinning thread can wake on the guard condition shutdown just destroyed and
die with "'NoneType' object has no attribute 'trigger'" (seen once in a test). So
the thread spins in short turns until asked to stop, and the executor is shut down only
after it has returned.
"""

from __future__ import annotations

import threading

from rclpy.executors import Executor

TURN_S = 0.05  # one spin_once's wait: how long stop() may take to be noticed


class BackgroundSpin:
    def __init__(self, executor: Executor) -> None:
        self.executor = executor
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._spin, name="test-spin", daemon=True)
        self._thread.start()

    def _spin(self) -> None:
        while not self._stop.is_set():
            self.executor.spin_once(timeout_sec=TURN_S)

    def stop(self, timeout_s: float = 10.0) -> None:
        """Stop spinning (a callback under way finishes first), then shut the executor down."""
        self._stop.set()
        self._thread.join(timeout_s)
        self.executor.shutdown(timeout_sec=1.0)
