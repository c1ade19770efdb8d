"""The position move with a tactile force limit (control/move.py), fed synthetic inputs."""

from __future__ import annotations

import math
from types import SimpleNamespace as NS

import pytest
from hypothesis import given
from hypothesis import strategies as st

from tactile_sensor.control.errors import InvalidRequest
from tactile_sensor.control.geometry import GripperGeometry
from tactile_sensor.control.grasp import GraspConfig, Outcome, Phase
from tactile_sensor.control.move import MoveController, MoveRequest

G = GripperGeometry()
CONFIG = GraspConfig()


def at(opening_m: float, moving: bool = True,
       hardware_error: frozenset[str] = frozenset()) -> NS:
    """A servo sample at this opening, as the controllers read it (ServoReading)."""
    return NS(position_rad=G.position_rad(opening_m), moving=moving,
              hardware_error=hardware_error)


def request(opening=0.002, effort=2.0, speed=0.01, **kw) -> MoveRequest:
    return MoveRequest(opening, effort, speed, 2 * speed, kw.pop("timeout", 5.0), **kw)


def started(req: MoveRequest, servo: NS | None = None) -> MoveController:
    controller = MoveController(CONFIG)
    step = controller.start(req, 0.0, servo or at(G.open_opening_m))
    assert not step.finished
    return controller


@given(st.floats(0.002, 0.06), st.floats(0.001, 0.05))
def test_start_commands_the_target_opening_at_the_direction_s_speed(opening, speed):
    servo = at(0.03)
    step = MoveController(CONFIG).start(request(opening, 1.0, speed), 0.0, servo)
    assert step.command.goal_position_rad == pytest.approx(G.position_rad(opening))
    # The direction is decided against the opening the servo reports (0.03 m after a round
    # trip through radians, which may differ from 0.03 in the last bit).
    closing = opening < G.opening_m(servo.position_rad)
    expected = speed if closing else 2 * speed
    assert step.command.profile_velocity_rad_s * G.pitch_radius_m == pytest.approx(expected)
    assert step.phase is (Phase.CLOSING if closing else Phase.OPENING)


@given(st.floats(0.1, 20.0), st.floats(0.0, 3.0))
def test_closing_stops_at_the_tactile_limit_and_holds_there(limit, excess):
    controller = started(request(0.002, limit))
    step = controller.tick(0.5, limit + excess, 0.49, at(0.02))
    assert step.outcome is Outcome.FORCE_LIMIT
    assert step.command.goal_position_rad == pytest.approx(G.position_rad(0.02))
    assert step.command.goal_current_a == CONFIG.hold_current_a


@given(st.floats(0.1, 20.0), st.floats(0.0, 0.999))
def test_below_the_limit_the_move_goes_on_and_slows_near_it(limit, fraction):
    controller = started(request(0.002, limit))
    step = controller.tick(0.5, limit * fraction, 0.49, at(0.02))
    assert not step.finished
    if step.command is not None:  # re-commanded slower, never faster, toward the same goal
        assert step.command.goal_position_rad == pytest.approx(G.closed_position_rad)
        assert step.command.profile_velocity_rad_s < 0.01 / G.pitch_radius_m


def test_no_limit_means_position_only_whatever_the_force():
    controller = started(request(0.002, 0.0))
    step = controller.tick(0.5, 50.0, 0.49, at(0.02))
    assert not step.finished and step.command is None
    # ... and without any tactile force at all
    assert not controller.tick(1.0, None, None, at(0.015)).finished


def test_an_opening_move_ignores_the_force_limit():
    controller = started(request(0.05, 1.0), at(0.02))
    assert not controller.tick(0.5, 5.0, 0.49, at(0.03)).finished


@given(st.floats(0.002, 0.06), st.floats(-0.00049, 0.00049))
def test_arriving_within_tolerance_at_rest_reaches_the_goal(opening, error):
    controller = started(request(opening, 0.0), at(0.031))
    at_goal = min(max(opening + error, 0.002), 0.06)
    assert not controller.tick(0.5, None, None, at(at_goal, moving=True)).finished
    step = controller.tick(0.6, None, None, at(at_goal, moving=False))
    assert step.outcome is Outcome.REACHED and step.outcome.succeeded
    assert step.command is None  # the servo holds at its goal


def test_at_rest_short_of_the_goal_for_the_stall_time_is_a_stall():
    controller = started(request(0.002, 0.0, stall_time_s=0.2))
    assert not controller.tick(0.5, None, None, at(0.02, moving=False)).finished
    assert not controller.tick(0.65, None, None, at(0.02, moving=False)).finished
    assert not controller.tick(0.7, None, None, at(0.0199, moving=True)).finished  # moved
    assert not controller.tick(0.8, None, None, at(0.0199, moving=False)).finished
    step = controller.tick(1.01, None, None, at(0.0199, moving=False))
    assert step.outcome is Outcome.STALLED and "short of the goal" in step.message
    assert step.command.goal_position_rad == pytest.approx(G.position_rad(0.0199))


def test_a_stall_is_judged_on_a_new_sample_not_on_the_one_already_judged():
    """A control loop starved of its turn leaves the goal ticking on the sample it had,
    taken at rest before its command moved the fingers: 0.2 s of ticks on it is no stall
    (seen beside a busy core: an opening from the rod "stalled" where it began)."""
    controller = started(request(0.03, 0.0, stall_time_s=0.2), at(0.018))
    before = at(0.018, moving=False)
    for now in (0.5, 0.6, 0.75, 0.9):
        assert not controller.tick(now, None, None, before).finished
    assert not controller.tick(0.95, None, None, at(0.0185, moving=True)).finished
    assert controller.tick(1.3, None, None, at(0.03 - 0.005, moving=False)).outcome is None
    assert controller.tick(1.55, None, None, at(0.03 - 0.005, moving=False)).outcome \
        is Outcome.STALLED


def test_a_stale_force_aborts_a_limited_close_but_not_a_position_only_one():
    limited = started(request(0.002, 2.0))
    step = limited.tick(0.5, 0.1, 0.5 - CONFIG.stale_after_s - 0.01, at(0.03))
    assert step.outcome is Outcome.TACTILE_STALE
    assert step.message.startswith("the newest tactile force is ")
    assert started(request(0.002, 2.0)).tick(0.5, None, None, at(0.03)).outcome \
        is Outcome.TACTILE_STALE
    assert not started(request(0.002, 0.0)).tick(0.5, None, None, at(0.03)).finished


def test_timeout_hardware_error_and_cancel():
    controller = started(request(timeout=1.0))
    assert controller.tick(1.5, 0.0, 1.49, at(0.03)).outcome is Outcome.TIMEOUT
    controller = started(request())
    step = controller.tick(0.1, 0.0, 0.09, at(0.03, hardware_error=frozenset({"overload"})))
    assert step.outcome is Outcome.HARDWARE_ERROR and "overload" in step.message
    assert step.command is None  # torque may be off: nothing is written
    controller = started(request())
    step = controller.cancel(0.2, at(0.04))
    assert step.outcome is Outcome.CANCELED
    assert step.command.goal_position_rad == pytest.approx(G.position_rad(0.04))
    assert controller.tick(0.3, 0.0, 0.29, at(0.04)).command is None


@pytest.mark.parametrize("field, value, words", [
    ("opening", math.nan, "not a number"),
    ("opening", 0.0019, "outside the travel"),
    ("opening", 0.0601, "outside the travel"),
    ("effort", math.nan, "not a number"),
    ("effort", -0.5, "negative"),
    ("speed", 0.0, "must be in"),
    ("speed", 5.0, "slower"),
])
def test_invalid_requests_name_the_field_and_the_fix(field, value, words):
    values = {"opening": 0.01, "effort": 1.0, "speed": 0.01}
    values[field] = value
    with pytest.raises(InvalidRequest, match=words):
        MoveController(CONFIG).start(request(*values.values()), 0.0, at(G.open_opening_m))


@given(st.floats(2.5, 4.5), st.floats(-8.0, 8.0))
def test_the_opening_rate_is_the_derivative_of_the_opening(position_rad, velocity_rad_s):
    dt = 1e-3
    expected = (G.opening_m(position_rad + velocity_rad_s * dt) - G.opening_m(position_rad)) / dt
    assert G.opening_rate_m_s(velocity_rad_s) == pytest.approx(expected, rel=1e-6, abs=1e-12)
