"""An executor spun in a background thread that stops spinning before it shuts down.

``executor.shutdown()`` while another thread is inside ``executor.spin()`` races on Jazzy's
rclpy 7: the spinning thread can wake on the guard condition shutdown just destroyed and
die with "'NoneType' object has no attribute 'trigger'" (seen once in a test). So
the thread spins in short turns until asked to stop, and the executor is shut down only
after it has returned.
"""

from __future__ import annotations

import threading
import time

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
        settle_callbacks(self.executor, timeout_s)
        self.executor.shutdown(timeout_sec=1.0)

def settle_callbacks(executor: Executor, timeout_s: float) -> None:
    """Wait for the callbacks the executor's pool still runs, and take their outcome.

    rclpy's ``Executor.shutdown`` does not wait for them (7.1.6 and 9.1.2 skip the wait
    they document), so a callback still running when the lifecycle cleanup destroyed its
    timer or publisher failed, and its task printed "The following exception was never
    retrieved: cannot use Destroyable because destruction was requested" at exit. The
    executor keeps the tasks it dispatched in ``_futures`` (both distributions); an
    executor without it has nothing to settle.
    """
    deadline = time.monotonic() + timeout_s
    for task in list(getattr(executor, "_futures", ())):
        while not task.done() and time.monotonic() < deadline:
            time.sleep(0.005)
        if task.done():
            task.exception()  # taken: a task that failed at shutdown is not news
