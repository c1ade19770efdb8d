"""The gripper's control loop on its own thread: fast while a goal runs, slow while idle.

An idle gripper needs its joint state for robot_state_publisher users, its servo's health
for /diagnostics and the newest tactile force, all at a few hertz; a goal needs the servo
every control period. Run as an rclpy timer at the control rate whatever the gripper was
doing, the loop, and the executor round each of its ticks costs, took about a fifth of the
0.5 core an idle gripper node used (100 wakes a second of the 800 the executor had; the rest
were the tactile subscriptions). Here one thread sleeps between samples: every
``servo.period_s`` while a goal is ``busy`` or the fingers still move after it (a cancel's
stop, whose rest a client times by ``~/joint_states``), every ``idle_period_s`` once they
rest; a goal that starts wakes it at once, so its first tick waits for no idle period.

``before`` runs ahead of each sample (the node takes the tactile messages waiting for it,
so a goal's tick that follows the sample sees the newest force), ``after`` gets what the
sample found (joint states, diagnostics). Neither may raise: the thread has nobody to tell.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager

from tactile_sensor.control.servo_link import Poll, ServoLink


class ServoSampler:
    def __init__(self, servo: ServoLink, *, idle_period_s: float,
                 before: Callable[[], None], after: Callable[[Poll], None],
                 clock: Callable[[], float] = time.monotonic) -> None:
        if not idle_period_s >= servo.period_s:
            raise ValueError(
                f"idle_rate {1.0 / idle_period_s:g} Hz is above control_rate "
                f"{1.0 / servo.period_s:g} Hz: an idle gripper samples at most as often as "
                "a running goal; lower idle_rate (e.g. 10).")
        self.servo, self.idle_period_s = servo, idle_period_s
        self._before, self._after, self._clock = before, after, clock
        self._busy = 0
        self._lock = threading.Lock()
        self._wake = threading.Event()
        self._stopping = False
        self._moving = False
        self._thread: threading.Thread | None = None

    @property
    def running(self) -> bool:
        return self._thread is not None

    @property
    def goal_running(self) -> bool:
        """Whether a goal holds the loop ``busy`` now."""
        return self._busy > 0

    @property
    def period_s(self) -> float:
        """The period the loop samples at now [s]."""
        return self.servo.period_s if self._busy or self._moving else self.idle_period_s

    def start(self) -> None:
        if self._thread is not None:
            return
        self._stopping = False
        self._thread = threading.Thread(target=self._run, name="servo_sampler", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        """Stop sampling; returns once the thread's last sample is done."""
        thread, self._thread = self._thread, None
        if thread is None:
            return
        self._stopping = True
        self._wake.set()
        thread.join()

    @contextmanager
    def busy(self) -> Iterator[None]:
        """Sample at the control rate for as long as the block runs (a goal)."""
        with self._lock:
            self._busy += 1
        self._wake.set()
        try:
            yield
        finally:
            with self._lock:
                self._busy -= 1

    def sample(self) -> Poll:
        """One sample now: ``before``, the servo's read, ``after``."""
        self._before()
        poll = self.servo.poll()
        self._moving = poll.state is not None and poll.state.moving
        self._after(poll)
        return poll

    def _run(self) -> None:
        next_at = self._clock()
        while not self._stopping:
            self.sample()
            now = self._clock()
            # a late sample is not made up for by a burst: the next one is a period on
            next_at = max(next_at + self.period_s, now)
            if self._wake.wait(next_at - now):
                self._wake.clear()
                next_at = self._clock()  # a goal started (or stop): sample at once
