"""The tactile force as the gripper's goals read it: the newest value, and a running mean.

Grasps and moves act on the newest force and its stamp (staleness is judged from it); the
hold (control/hold.py) acts on the sum and count of all forces since its previous tick,
so it follows the force rather than its noise, and only on forces stamped after its last
correction took effect (``count_after``): a force that arrives late still describes where
the fingers were. The subscription thread adds, the goal's thread reads.

``full_scale_n`` is the sensor's full-scale force as the driver latched it (None until
then): a reading there is saturated, and a goal that ends pressing there backs off
(control/back_off.py) even when it was accepted before the range was known.
"""

from __future__ import annotations

import math
import threading


def stale_detail(age_s: float, stale_after_s: float, heard: bool) -> str:
    """Why a goal stopped for want of a fresh tactile force, in one sentence. A force that
    arrives but is old is a late driver (a starved one keeps every sample and falls behind
    its ADC), which no silence of the sensor explains."""
    if heard:
        return (f"the newest tactile force is {age_s:.3f} s old (tactile_timeout "
                f"{stale_after_s:g} s): the driver runs late (a busy machine: see "
                "frames_backlog in its /diagnostics) or its stream stopped")
    return f"no tactile force for {age_s:.3f} s (tactile_timeout {stale_after_s:g} s)"


def no_first_force_detail(waited_s: float, stale_after_s: float, heard: bool,
                          what: str = "tactile force", topic: str = "tactile_wrench",
                          source: str = "~/wrench") -> str:
    """Why a goal that waited for a fresh tactile force (or another of the driver's
    ``what``, subscribed as ``topic`` onto its ``source``) before moving (readiness) ended
    without one, in one sentence with the fix."""
    kind = f"no fresh {what} (the newest is older than that)" if heard else f"no {what}"
    return (f"{kind} came within {waited_s:.3f} s of the goal (tactile_timeout "
            f"{stale_after_s:g} s), so the fingers did not move: start and activate the "
            f"driver, check that {topic} is remapped onto its {source}, or send the "
            "goal again once its data flow")


class TactileForce:
    def __init__(self) -> None:
        self._lock = threading.Lock()
        #: (force [N], its stamp [s]) of the newest message; None before the first.
        self.latest: tuple[float, float] | None = None
        #: The sensor's full-scale force [N]; None until the driver stated it.
        self.full_scale_n: float | None = None
        self._sum_n, self._count = 0.0, 0
        self._after_s = -math.inf
        self._wrench_sums = (0.0, 0.0, 0.0, 0)

    def add(self, force_n: float, stamp_s: float, sum_n: float | None = None,
            count: int = 1, first_stamp_s: float | None = None) -> None:
        """The newest force, and the ``count`` forces (summing to ``sum_n``, the oldest
        stamped ``first_stamp_s``; default: this one alone) that arrived with it."""
        if count < 1:
            raise ValueError(f"count = {count} must be >= 1: the newest force is one of them")
        self.latest = (force_n, stamp_s)
        with self._lock:
            if stamp_s <= self._after_s:
                return
            if first_stamp_s is not None and first_stamp_s <= self._after_s:
                sum_n, count = None, 1  # the batch straddles the gate: its newest force alone
            self._sum_n += force_n if sum_n is None else sum_n
            self._count += count

    def add_wrench(self, fn_sum_n: float, fx_sum_n: float, fy_sum_n: float,
                   count: int) -> None:
        """Sums of ``count`` forces along z (the grip), x and y (the shear), for the
        adaptive hold (control/slip_hold.py), which reads every force, not the newest."""
        with self._lock:
            n, x, y, c = self._wrench_sums
            self._wrench_sums = (n + fn_sum_n, x + fx_sum_n, y + fy_sum_n, c + count)

    def wrench_means_since_last_call(self) -> tuple[float, float, float] | None:
        """Mean (Fz, Fx, Fy) [N] of the forces added since the previous call; None when
        none came."""
        with self._lock:
            n, x, y, count = self._wrench_sums
            self._wrench_sums = (0.0, 0.0, 0.0, 0)
        return None if count == 0 else (n / count, x / count, y / count)

    def count_after(self, stamp_s: float) -> None:
        """From now on the mean takes only forces stamped after ``stamp_s`` [s]; what it
        held is dropped."""
        with self._lock:
            self._after_s = stamp_s
            self._sum_n, self._count = 0.0, 0

    def sum_since_last_call(self) -> tuple[float, int]:
        """(sum [N], count) of the forces added since the previous call."""
        with self._lock:
            total, count = self._sum_n, self._count
            self._sum_n, self._count = 0.0, 0
        return total, count

    def mean_since_last_call(self) -> float | None:
        """Mean of the forces added since the previous call [N]; None when none came."""
        total, count = self.sum_since_last_call()
        return total / count if count else None

    def stale_refusal(self, now_s: float, stale_after_s: float) -> str | None:
        """Why a grasp cannot start now, in one sentence (None: it may). The driver
        publishes no force while its detector is blind (ambient light at the rail,
        docs/ambient.md) or its stream is down; a grasp would close on nothing it can feel.
        Before the first force none is refused: the goal waits ``stale_after_s`` for it
        before it moves (control/goal_runner.py)."""
        latest = self.latest
        if latest is None:
            return None
        force_n, stamp_s = latest
        age = now_s - stamp_s
        if age > stale_after_s or not math.isfinite(force_n):
            return (f"the tactile force is {age:.2f} s old (tactile_timeout "
                    f"{stale_after_s:g} s): the sensor is blind or its stream stopped; see "
                    "the driver's /diagnostics ('ambient light saturates the detector': shade "
                    "the module).")
        return None
