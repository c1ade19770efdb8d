"""When a gripper's fingers came to rest, from its ``~/joint_states`` openings.

One definition for every measurement of a stop (a cancel, a goal's end): the first sample
from which the opening stays within a tolerance of where it ends. A finger that passes that
point and comes back, or closes again after the stop, counts as still moving.
"""

from __future__ import annotations

from collections.abc import Sequence

#: How far [m] the opening may move and still count as at rest: just over one servo position
#: count at the opening (2 × the 14 mm pinion × 2π/4096 = 0.043 mm), by which a servo holding
#: its position dithers.
REST_TOLERANCE_M = 5e-5


def rest_onset(opening: Sequence[tuple[float, float]], since: float,
               until: float = float("inf"), *, tolerance_m: float = REST_TOLERANCE_M,
               hold_s: float = 0.0) -> float | None:
    """Stamp [s] of the first (stamp, opening [m]) sample in [since, until] from which the
    opening stays within ``tolerance_m`` of its last value there; None when there is no
    sample, or when it has not stayed there for ``hold_s`` of samples yet (a stop still in
    progress cannot be told from one that ended)."""
    window = [(t, o) for t, o in list(opening) if since <= t <= until]
    if not window:
        return None
    final = window[-1][1]
    moving = [i for i, (_, o) in enumerate(window) if abs(o - final) >= tolerance_m]
    rest = window[moving[-1] + 1 if moving else 0][0]
    return rest if window[-1][0] - rest >= hold_s else None
