"""Where to stop a moving servo with ONE write: the last sample, carried forward in time.

Stopping a position-controlled XM430 means writing a Goal Position where the output is.
Reading Present Position first costs a second bus transaction (and, in the node, a wait for
the control loop's read to finish). The control loop samples the servo every period anyway,
so the output's position now is the sample plus its velocity times the sample's age: exact
while the fingers close at the profile speed, and never past the goal the servo was heading
for (the profile cannot overshoot it). A sample older than ``max_age_s`` is not trusted (the
fingers may have met the object since): the caller reads the servo instead.

The error is |velocity change since the sample| x age; at 10 mm/s finger speed (0.71 rad/s)
a 2 ms timing error is 1.4 mrad, one encoder pulse (1.5 mrad).
"""

from __future__ import annotations

import math

from tactile_sensor.control.errors import InvalidRequest


def stop_position_rad(position_rad: float, velocity_rad_s: float, age_s: float,
                      max_age_s: float, heading_to_rad: float | None = None
                      ) -> float | None:
    """Goal Position [rad] that stops the output where it is now, or None when the sample
    (``position_rad``, ``velocity_rad_s``, taken ``age_s`` ago) is too old to trust."""
    for name, value in (("position_rad", position_rad), ("velocity_rad_s", velocity_rad_s),
                        ("age_s", age_s), ("max_age_s", max_age_s)):
        if not math.isfinite(value):
            raise InvalidRequest(f"stop_position_rad: {name} = {value} is not finite; pass "
                                 "a real servo sample and its age.")
    if max_age_s < 0:
        raise InvalidRequest(f"stop_position_rad: max_age_s = {max_age_s} is negative; pass "
                             "how old a sample may be, e.g. three control periods.")
    if age_s > max_age_s:
        return None
    estimate = position_rad + velocity_rad_s * max(age_s, 0.0)
    if heading_to_rad is not None and math.isfinite(heading_to_rad):
        ahead = heading_to_rad - position_rad
        if ahead == 0.0:
            return position_rad  # at its goal the servo holds; a velocity there is noise
        # carried past the goal (signs compared, not multiplied: a product of two tiny
        # distances underflows to 0)
        if (ahead > 0) == (estimate > heading_to_rad) and estimate != heading_to_rad:
            return heading_to_rad
    return estimate
