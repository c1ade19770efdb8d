"""When an aborted goal backs off, where to, and when it stops (control/back_off.py)."""

from __future__ import annotations

import math
from types import SimpleNamespace as NS

import pytest
from hypothesis import given
from hypothesis import strategies as st

from tactile_sensor.control.back_off import SATURATION_BAND, BackOff
from tactile_sensor.control.errors import InvalidRequest
from tactile_sensor.control.geometry import GripperGeometry

G = GripperGeometry()


def back_off(target: float = 2.0, full_scale: float | None = 6.77) -> BackOff:
    return BackOff(G, target, full_scale, speed_rad_s=0.7, current_a=0.6,
                   stop_velocity_rad_s=6.0)


def at(opening_m: float) -> NS:
    return NS(position_rad=G.position_rad(opening_m), moving=True, hardware_error=frozenset())


@given(st.floats(0.0, 6.0))
def test_below_the_full_scale_it_backs_off_exactly_above_the_target(force):
    assert back_off().needed(force) is (force > 2.0)


def test_a_reading_at_the_full_scale_backs_off_whatever_the_target():
    saturated = (1 - SATURATION_BAND) * 6.77  # the tare's offset keeps it a little below
    assert back_off(target=10.0).needed(6.77) and back_off(target=10.0).needed(saturated)
    assert not back_off(target=10.0).needed(saturated - 1e-9)
    assert not back_off(target=10.0, full_scale=None).needed(6.77)  # range not known


@pytest.mark.parametrize("force", [None, math.nan])
def test_without_a_force_it_holds(force):
    assert not back_off().needed(force)


def test_it_opens_toward_the_open_limit_and_holds_where_the_force_is_safe():
    b = back_off()
    command = b.opening_command()
    assert command.goal_position_rad == G.open_position_rad
    assert (command.profile_velocity_rad_s, command.goal_current_a) == (0.7, 0.6)
    servo = at(0.015)
    assert b.tick(2.5, servo) is None and b.tick(6.77, servo) is None
    assert b.tick(2.0, servo) is None and b.tick(1.9, servo) is None  # safe twice ...
    assert b.tick(2.1, servo) is None  # ... then not: a noisy dip does not count
    assert b.tick(2.0, servo) is None and b.tick(1.9, servo) is None
    hold = b.tick(1.8, servo)  # safe three periods in a row: hold here
    assert hold.goal_position_rad == servo.position_rad
    assert hold.profile_velocity_rad_s == 6.0
    assert hold.hold_present  # where the opening fingers are when it lands, not behind
    assert b.time_bound_s(servo) == pytest.approx(
        (servo.position_rad - G.open_position_rad) / 0.7)


@pytest.mark.parametrize("change, words", [
    ({"target_force_n": 0.0}, "nothing to back off to"),
    ({"target_force_n": math.nan}, "nothing to back off to"),
    ({"speed_rad_s": 0.0}, "speed_rad_s must be positive"),
    ({"current_a": -1.0}, "current_a must be positive"),
])
def test_a_back_off_that_cannot_work_is_refused(change, words):
    values = {"geometry": G, "target_force_n": 2.0, "full_scale_force_n": None,
              "speed_rad_s": 0.7, "current_a": 0.6, "stop_velocity_rad_s": 6.0, **change}
    with pytest.raises(InvalidRequest, match=words):
        BackOff(**values)
