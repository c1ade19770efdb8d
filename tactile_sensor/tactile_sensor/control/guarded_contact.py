"""Where the fingers were when a tactile force was sampled, and where to stop them.

A tactile force reaches the gripper late: the driver's sample, its filter and the topic
(about 5 ms), then up to one control period before a tick reads it (docs/gripper.md,
"Latency budget"). While it travels the fingers close on, so a grasp that stops where the
fingers are when it sees the target has already pressed past it. The stop is counted from
the force's own instant instead: the position the fingers had then (``PositionTrace``),
plus the travel the missing force needs at the skin's stiffness. The servo's own position
loop then stops the fingers there, whatever the latency of the command.
"""

from __future__ import annotations

import bisect
from collections import deque


class PositionTrace:
    """Recent (time, servo position) samples of one grasp; time in the goal's clock [s]."""

    def __init__(self, span_s: float = 0.5) -> None:
        self.span_s = span_s
        self._times: deque[float] = deque()
        self._positions: deque[float] = deque()

    def add(self, t_s: float, position_rad: float) -> None:
        if self._times and t_s <= self._times[-1]:
            return  # a sample no newer than the last tells nothing more
        self._times.append(t_s)
        self._positions.append(position_rad)
        while self._times[0] < t_s - self.span_s:
            self._times.popleft()
            self._positions.popleft()

    def at(self, t_s: float) -> float:
        """The position at ``t_s``, interpolated; the oldest / newest one outside the span.
        Raises LookupError before the first sample."""
        if not self._times:
            raise LookupError("no position sampled yet")
        times, positions = self._times, self._positions
        i = bisect.bisect_left(times, t_s)
        if i == 0:
            return positions[0]
        if i == len(times):
            return positions[-1]
        t0, t1 = times[i - 1], times[i]
        w = (t_s - t0) / (t1 - t0)
        return positions[i - 1] + w * (positions[i] - positions[i - 1])


def stop_goal_rad(force_n: float, position_at_force_rad: float, target_force_n: float,
                  newton_per_rad: float) -> float:
    """The position where the force reaches the target, from a force and where the fingers
    were when it was sampled (positive rotation closes)."""
    return position_at_force_rad + (target_force_n - force_n) / newton_per_rad


def force_ahead_n(force_n: float, position_at_force_rad: float, position_now_rad: float,
                  speed_rad_s: float, newton_per_rad: float, command_latency_s: float) -> float:
    """The force the fingers will press with once a stop sent now takes effect: the sampled
    force, plus the travel since it was sampled, plus the travel until the command lands."""
    travel_rad = max(0.0, position_now_rad - position_at_force_rad)
    return force_n + newton_per_rad * (travel_rad + speed_rad_s * command_latency_s)
