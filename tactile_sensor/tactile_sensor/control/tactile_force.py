"""The tactile force as the gripper's goals read it: the newest value, and a running mean.

Grasps and moves act on the newest force and its stamp (staleness is judged from it); the
force settler acts on the mean of all forces since its previous tick, so it follows the
force rather than its noise. The subscription thread adds, the goal's thread reads.
"""

from __future__ import annotations

import threading


class TactileForce:
    def __init__(self) -> None:
        self._lock = threading.Lock()
        #: (force [N], its stamp [s]) of the newest message; None before the first.
        self.latest: tuple[float, float] | None = None
        self._sum_n, self._count = 0.0, 0

    def add(self, force_n: float, stamp_s: float, sum_n: float | None = None,
            count: int = 1) -> None:
        """The newest force, and the ``count`` forces (summing to ``sum_n``; default: this
        one alone) that arrived with it."""
        if count < 1:
            raise ValueError(f"count = {count} must be >= 1: the newest force is one of them")
        self.latest = (force_n, stamp_s)
        with self._lock:
            self._sum_n += force_n if sum_n is None else sum_n
            self._count += count

    def mean_since_last_call(self) -> float | None:
        """Mean of the forces added since the previous call [N]; None when none came."""
        with self._lock:
            total, count = self._sum_n, self._count
            self._sum_n, self._count = 0.0, 0
        return total / count if count else None
