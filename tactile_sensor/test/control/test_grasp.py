"""Grasp and release state machines, fed synthetic inputs (pure, no I/O)."""

from __future__ import annotations

from dataclasses import dataclass

import pytest
from hypothesis import given
from hypothesis import strategies as st

from tactile_sensor.control.errors import InvalidRequest
from tactile_sensor.control.geometry import GripperGeometry
from tactile_sensor.control.grasp import (
    GraspConfig,
    GraspController,
    GraspRequest,
    Outcome,
    Phase,
    ReleaseController,
)

G = GripperGeometry()


@dataclass(frozen=True)
class Servo:
    position_rad: float = G.open_position_rad
    moving: bool = True
    hardware_error: frozenset[str] = frozenset()


def at(opening_m: float, **kw) -> Servo:
    return Servo(G.position_rad(opening_m), **kw)


def started(target=2.0, speed=0.01, timeout=5.0, config=None) -> GraspController:
    controller = GraspController(config)
    step = controller.start(GraspRequest(target, speed, timeout), 0.0, Servo())
    assert step.phase is Phase.CLOSING and not step.finished
    return controller


@given(st.floats(0.001, 0.1), st.floats(0.1, 20.0))
def test_start_closes_on_a_leash_at_the_requested_finger_speed(speed, target):
    step = GraspController().start(GraspRequest(target, speed, 5.0), 0.0, Servo())
    leash_m = speed * GraspConfig().leash_s
    assert G.opening_m(step.command.goal_position_rad) == pytest.approx(
        max(G.closed_opening_m, G.open_opening_m - 2.0 * leash_m))
    assert step.command.profile_velocity_rad_s * G.pitch_radius_m == pytest.approx(speed)
    assert step.command.goal_current_a == GraspConfig().closing_current_a


def test_contact_past_the_target_backs_off_the_excess():
    controller = started(target=2.0)
    step = controller.tick(0.5, 2.1, 0.49, at(0.018))
    assert step.outcome is Outcome.CONTACT and step.phase is Phase.DONE
    assert step.message == "contact at 2.10 N"
    back_rad = 0.1 / controller.newton_per_rad
    assert step.command.goal_position_rad == pytest.approx(G.position_rad(0.018) - back_rad)
    assert step.command.goal_current_a == GraspConfig().hold_current_a
    assert not step.command.hold_present  # aimed at the target's position
    assert controller.tick(0.6, 2.1, 0.59, at(0.018)).command is None   # finished


def test_contact_stops_ahead_when_the_force_in_flight_will_reach_the_target():
    """The force was sampled 20 ms ago; the fingers closed on since: the stop is sent
    before the force reads the target, aimed where the missing force will be."""
    controller = started(target=2.0)
    k_rad, speed = controller.newton_per_rad, controller._speed_rad_s
    before = G.position_rad(0.0185)
    assert controller.tick(0.48, 1.2, 0.47, Servo(before)).outcome is None
    now = before + speed * 0.02
    step = controller.tick(0.50, 1.9, 0.48, Servo(now))
    assert step.outcome is Outcome.CONTACT
    # aimed from where the fingers were when the force was sampled (0.48 s)
    assert step.command.goal_position_rad == pytest.approx(before + 0.1 / k_rad)


def test_no_stop_ahead_in_free_air():
    """Below the slow-down the travel since a force was sampled adds no force."""
    controller = started(target=2.0)
    controller.tick(0.40, 0.0, 0.39, at(0.03))
    assert controller.tick(0.45, 0.9, 0.40, at(0.025)).outcome is None


def test_noise_in_free_air_does_not_stop_the_fingers():
    """At full speed the travel since a force's stamp predicts 0.6 N more, in contact; a
    3 σ noise reading in free air must not stop the grasp on it."""
    controller = started(target=1.0)
    controller.tick(0.40, 0.0, 0.39, at(0.03))
    assert controller.tick(0.41, 0.56, 0.395, at(0.0298)).outcome is None


def test_closing_pauses_while_the_force_is_late_and_resumes_on_a_fresh_one():
    controller = started(target=2.0)
    controller.tick(0.10, 0.0, 0.10, at(0.03))
    paused = controller.tick(0.18, 0.0, 0.10, at(0.029))
    assert paused.outcome is None and paused.message.startswith("paused")
    assert paused.command.goal_position_rad == pytest.approx(G.position_rad(0.029))
    # where the fingers are when it lands: the sample may be old by then
    assert paused.command.hold_present
    assert controller.tick(0.19, 0.0, 0.10, at(0.029)).command is None  # once
    resumed = controller.tick(0.20, 0.0, 0.195, at(0.029))
    assert resumed.command.goal_position_rad > G.position_rad(0.029)  # closing on


@given(st.floats(0.0, 2.5), st.floats(0.0, 0.03), st.floats(0.1, 5.0))
def test_contact_stop_never_closes_past_the_target_position(force, lag_s, target):
    """Wherever the stop lands, the skin model the controller assumes reads at most the
    target there."""
    controller = started(target=target)
    k_rad, speed = controller.newton_per_rad, controller._speed_rad_s
    start = G.position_rad(0.022)
    controller.tick(0.5 - lag_s, force, 0.5 - lag_s, Servo(start))
    now = start + speed * lag_s
    step = controller.tick(0.5, force, 0.5 - lag_s, Servo(now))
    if step.outcome is Outcome.CONTACT:
        assert force + k_rad * (step.command.goal_position_rad - start) <= target + 1e-9


@given(st.floats(0.0, 1.0), st.floats(0.0, 1.0))
def test_slowdown_never_speeds_up_with_more_force(f1, f2):
    controller = started(target=2.0, config=GraspConfig(resend_speed_change=0.0))
    low, high = sorted((f1, f2))
    s_low = controller._scheduled_speed(low * 2.0)
    s_high = controller._scheduled_speed(high * 2.0)
    assert s_high <= s_low + 1e-12
    assert s_high >= GraspConfig().min_speed_fraction * 0.01 / G.pitch_radius_m - 1e-12


def test_each_tick_moves_the_leash_on_and_slows_down_in_contact():
    controller = started(target=2.0)
    free = controller.tick(0.1, 0.0, 0.1, at(0.03)).command
    assert free.profile_velocity_rad_s == pytest.approx(0.01 / G.pitch_radius_m)
    assert G.opening_m(free.goal_position_rad) == pytest.approx(0.03 - 2 * 0.01 * 0.05)
    step = controller.tick(0.2, 1.6, 0.2, at(0.019))
    # 0.4 N missing in 50 ms on 2500 N/m: 3.2 mm/s
    assert step.command.profile_velocity_rad_s * G.pitch_radius_m == pytest.approx(0.0032)


@pytest.mark.parametrize(("tick", "outcome"), [
    ((6.0, 0.0, 6.0, at(0.03)), Outcome.TIMEOUT),
    ((0.5, 0.0, 0.3, at(0.03)), Outcome.TACTILE_STALE),
    ((0.5, None, None, at(0.03)), Outcome.TACTILE_STALE),
    ((0.5, 0.0, 0.5, at(G.closed_opening_m)), Outcome.CLOSED_LIMIT_WITHOUT_CONTACT),
    ((0.5, 0.0, 0.5, at(0.03, hardware_error=frozenset({"overload"}))),
     Outcome.HARDWARE_ERROR),
])
def test_aborts_with_a_reason(tick, outcome):
    step = started().tick(*tick)
    assert step.outcome is outcome and step.phase is Phase.ABORTED
    assert not outcome.succeeded
    if outcome is Outcome.HARDWARE_ERROR:
        assert step.command is None and "overload" in step.message
    else:
        assert step.command.goal_position_rad == pytest.approx(tick[3].position_rad)
        assert step.command.hold_present  # stop where the fingers are, not go back


def test_a_stale_abort_tells_a_late_force_from_none():
    """A starved driver keeps publishing, only late: its user should look at the machine,
    not at the sensor."""
    late = started().tick(0.5, 0.0, 0.3, at(0.03)).message
    assert late.startswith("the newest tactile force is 0.200 s old (tactile_timeout ")
    assert "frames_backlog" in late
    silent = started().tick(0.5, None, None, at(0.03)).message
    assert silent.startswith("no tactile force for 0.500 s (tactile_timeout ")


def test_waits_briefly_for_the_first_tactile_reading():
    step = started().tick(0.05, None, None, at(0.05))
    assert step.outcome is None and step.message == "waiting for tactile force"


def test_cancel_stops_at_once_and_only_while_moving():
    controller = started()
    step = controller.cancel(0.3, at(0.04))
    assert step.outcome is Outcome.CANCELED
    assert step.command.goal_position_rad == pytest.approx(G.position_rad(0.04))
    assert controller.cancel(0.4, at(0.04)).outcome is None


def test_start_with_a_latched_error_aborts():
    step = GraspController().start(GraspRequest(2.0, 0.01, 5.0), 0.0,
                                   Servo(hardware_error=frozenset({"overheating"})))
    assert step.outcome is Outcome.HARDWARE_ERROR


@pytest.mark.parametrize("request_", [
    GraspRequest(0.0, 0.01, 5.0), GraspRequest(2.0, 0.0, 5.0), GraspRequest(2.0, 1.0, 5.0),
    GraspRequest(2.0, 0.01, 0.0), GraspRequest(float("nan"), 0.01, 5.0),
])
def test_invalid_grasp_requests(request_):
    with pytest.raises(InvalidRequest):
        GraspController().start(request_, 0.0, Servo())


def test_invalid_config():
    with pytest.raises(InvalidRequest, match="slowdown_from_fraction"):
        GraspConfig(slowdown_from_fraction=0.0)
    with pytest.raises(InvalidRequest, match="hold_current_a"):
        GraspConfig(hold_current_a=-1.0)
    with pytest.raises(InvalidRequest, match="skin_stiffness"):
        GraspConfig(skin_stiffness_n_per_m=0.0)
    for bad in (dict(command_latency_s=-0.001), dict(contact_noise_margin_n=-1.0),
                dict(pause_after_s=0.0), dict(leash_s=0.0), dict(approach_time_s=0.0)):
        with pytest.raises(InvalidRequest, match="command_latency_s"):
            GraspConfig(**bad)


def test_release_opens_and_finishes_when_still_there():
    release = ReleaseController()
    step = release.start(0.05, 0.02, 3.0, 0.0, at(0.018))
    assert step.command.goal_position_rad == pytest.approx(G.position_rad(0.05))
    assert release.tick(0.5, at(0.03)).outcome is None
    assert release.tick(0.9, at(0.05, moving=True)).outcome is None
    assert release.tick(1.0, at(0.05, moving=False)).outcome is Outcome.OPENED


def test_release_aborts_and_rejects_bad_requests():
    release = ReleaseController()
    release.start(0.05, 0.02, 1.0, 0.0, at(0.018))
    assert release.tick(1.5, at(0.02)).outcome is Outcome.TIMEOUT
    with pytest.raises(InvalidRequest, match="outside the travel"):
        ReleaseController().start(0.1, 0.02, 1.0, 0.0, at(0.02))
    with pytest.raises(InvalidRequest, match="speed"):
        ReleaseController().start(0.05, -1.0, 1.0, 0.0, at(0.02))
    with pytest.raises(InvalidRequest, match="timeout"):
        ReleaseController().start(0.05, 0.02, 0.0, 0.0, at(0.02))



@dataclass(frozen=True)
class GearedServo:
    """A sample of a servo whose friction makes its profile lead the output."""

    position_rad: float
    trajectory_position_rad: float
    current_a: float = 0.2
    moving: bool = True
    hardware_error: frozenset[str] = frozenset()


def test_the_loops_lead_in_free_air_goes_on_the_leash_the_stop_and_the_closed_limit():
    controller = started(target=2.0)
    lead = 17 * 2 * 3.141592653589793 / 4096  # the sources' drivetrain at 10 mm/s
    free = G.position_rad(0.030)
    step = controller.tick(0.1, 0.0, 0.095, GearedServo(free, free + lead))
    leash = controller._speed_rad_s * GraspConfig().leash_s
    assert step.command.goal_position_rad == pytest.approx(free + lead + leash)
    assert controller.free_loop is not None
    assert controller.free_loop.current_a / controller.free_loop.lead_rad == pytest.approx(
        0.2 / lead)
    # past the target: the stop holds the output where it is, its goal the closing edge
    # at the target's force ahead of it (a goal behind it would throw it past the band)
    touch = G.position_rad(0.018)
    step = controller.tick(0.5, 2.1, 0.49, GearedServo(touch, touch + lead))
    assert step.outcome is Outcome.CONTACT
    edge = controller.free_loop.closing_edge_rad(2.0 * 2.0, G.pitch_radius_m)
    assert edge > lead  # the force's lead on top of the free one
    assert step.command.goal_position_rad == pytest.approx(touch + edge)


def test_an_output_at_rest_its_lead_short_of_the_closed_limit_has_reached_it():
    controller = started(target=2.0)
    limit = G.closed_position_rad
    short = GearedServo(limit - 0.03, limit, moving=False)
    step = controller.tick(1.0, 0.0, 0.99, short)
    assert step.outcome is Outcome.CLOSED_LIMIT_WITHOUT_CONTACT
    moving = started(target=2.0).tick(1.0, 0.0, 0.99, GearedServo(limit - 0.03, limit))
    assert moving.outcome is None
    # stalled on an object the sensor cannot read (saturated, blind): the limit's current
    pressed = GearedServo(limit - 0.3, limit, current_a=0.6, moving=False)
    assert started(target=2.0).tick(1.0, 0.0, 0.99, pressed).outcome is None


def test_a_release_resting_its_lead_short_of_the_opening_has_opened_unless_stalled():
    """Through the friction the output rests its loop's lead short of the goal, drawing
    the friction's current; one pressed on something draws the limit and has not."""
    release = ReleaseController()
    goal = G.position_rad(0.030)
    release.start(0.030, 0.01, 5.0, 0.0, Servo(G.position_rad(0.020)))
    short = goal + 0.03  # 0.8 mm of opening short: more than the tolerance
    friction = GearedServo(short, goal, current_a=-0.2, moving=False)
    assert release.tick(1.0, friction).outcome is Outcome.OPENED
    release = ReleaseController()
    release.start(0.030, 0.01, 5.0, 0.0, Servo(G.position_rad(0.020)))
    stalled = GearedServo(short, goal, current_a=-0.6, moving=False)
    assert release.tick(1.0, stalled).outcome is None
