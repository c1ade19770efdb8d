"""The SelfCheck goal: the slow close it records, where it stops, the fit and the apply."""

from __future__ import annotations

import math
import threading
from types import SimpleNamespace as NS

import numpy as np
import pytest

from tactile_sensor.control.actions import GoalSettings
from tactile_sensor.control.errors import InvalidRequest
from tactile_sensor.control.grasp import GraspConfig, Outcome
from tactile_sensor.control.self_check import DriveTrain, SelfCheckError, SkinPrediction
from tactile_sensor.control.self_check_goal import PRESS_M, SelfCheckLinks, accept_self_check
from tactile_sensor.nodes.self_check_links import LatestOutput, correction_of
from tactile_sensor.sensing.calibration import Calibration

D = np.linspace(0.0, 0.003, 16)
SKIN = SkinPrediction(tuple(D.tolist()), tuple((1.6e3 * D + 2.6e5 * D**2).tolist()),
                      tuple((150.0 * D + 7e3 * D**2).tolist()))
SETTINGS = GoalSettings(GraspConfig())
GEOMETRY = SETTINGS.config.geometry
R = GEOMETRY.pitch_radius_m
LOAD_FRICTION = DriveTrain().load_friction_ratio
PATIENCE_S = 30.0  # the bound of a wait that ends as soon as its reading came


class Close:
    """A 20 mm rod centred between the fingers, a skin at ``stiffness`` and a module at
    ``gain``; the servo follows its goal at the commanded speed, one tick at a time. The
    driver samples the module at 1 kHz and stamps each reading with its sample's time; the
    readings reach the gripper at once, or (``burst_s``) held back and sent together every
    ``burst_s``, 50 ms late (a driver starved of the CPU)."""

    def __init__(self, gain: float, stiffness: float, rod: bool = True,
                 burst_s: float = 0.0) -> None:
        self.gain, self.stiffness, self.rod, self.burst_s = gain, stiffness, rod, burst_s
        self.position = GEOMETRY.position_rad(0.024)
        self.t = 0.0
        self._heard_until, self._mean = 0.0, 0.0
        self.history = [(self.t, self.position)]  # (time [s], servo position [rad])
        self.keeping: list[bool] = []
        self.applied: list[object] = []
        self.links = self.with_links(self.output)

    def with_links(self, output_v, prediction=lambda: SKIN) -> SelfCheckLinks:
        return SelfCheckLinks(output_v, prediction, lambda fit, skin: self.applied.append(fit),
                              DriveTrain(), lambda servo: self.t, self.keeping.append,
                              self.kept_outputs)

    def indentation(self, position: float | None = None) -> float:
        opening = GEOMETRY.opening_m(self.position if position is None else position)
        return max(0.0, (0.020 - opening) / 2.0) if self.rod else 0.0

    def output_at(self, t):
        """The module's output sampled at ``t`` [s] (a number or an array): where the
        fingers were then."""
        times, positions = zip(*self.history, strict=True)
        opening = GEOMETRY.opening_m(np.interp(t, times, positions))
        d = np.maximum(0.0, (0.020 - opening) / 2.0) * self.rod
        return 0.01 + self.gain * SKIN.output(d)

    def output(self) -> float:
        """The mean of the readings received since the last tick (the last mean if none)."""
        if not self.burst_s:
            return float(self.output_at(self.t))
        stamps = np.arange(0.0, self.t, 0.001)
        came = np.ceil(stamps / self.burst_s) * self.burst_s + 0.05
        new = stamps[(came > self._heard_until) & (came <= self.t)]
        self._heard_until = self.t
        if new.size:
            self._mean = float(np.mean(self.output_at(new)))
        return self._mean

    def kept_outputs(self, until_s: float) -> tuple[list[float], list[float]]:
        stamps = np.arange(0.0, until_s + 1e-9, 0.001)
        return stamps.tolist(), self.output_at(stamps).tolist()

    def servo(self, velocity: float) -> NS:
        d = self.indentation()  # the skin's law, past the table too
        force = 2.0 * self.stiffness * (1.6e3 * d + 2.6e5 * d**2)
        return NS(position_rad=self.position, velocity_rad_s=velocity, moving=True,
                  hardware_error=frozenset(),
                  # the XM430's load-dependent friction on the motor's torque
                  current_a=0.0188 + force * R / (3.0 / 2.3 * (1.0 - LOAD_FRICTION)))

    def run(self, apply: bool) -> tuple[object, object]:
        goal = accept_self_check(NS(closing_speed=0.0, apply=apply), SETTINGS, self.links,
                                 0.001)
        step = goal.start(0.0, self.servo(0.0))
        speed = step.command.profile_velocity_rad_s
        while not step.finished:
            self.t += 0.01
            self.position = min(self.position + speed * 0.01, GEOMETRY.closed_position_rad)
            self.history.append((self.t, self.position))
            step = goal.tick(self.t, None, None, self.servo(speed))
        return goal, step


def test_a_close_on_a_rod_stops_past_contact_fits_and_applies():
    close = Close(0.8, 1.15)
    goal, step = close.run(apply=True)
    assert step.outcome is Outcome.CONTACT
    assert PRESS_M < close.indentation() < 0.003  # inside the prediction's range
    assert goal.failure(step) is None and goal.applied and len(close.applied) == 1
    result = goal.result(NS(step=step, opening_m=0.02), "fitted")
    assert result["outcome"] == "fitted"
    assert result["optical_gain"] == pytest.approx(0.8, abs=0.01)
    assert result["stiffness"] == pytest.approx(1.15, abs=0.01)


def test_outputs_that_reach_the_gripper_late_pair_with_where_the_fingers_were():
    """Readings held back and sent every 0.3 s (a busy machine): paired by arrival, the
    output seems to rise after the touch (stiffness 1.186); paired by their stamps, both
    factors come back."""
    close = Close(0.8, 1.15, burst_s=0.3)
    goal, step = close.run(apply=True)
    assert step.outcome is Outcome.CONTACT
    assert goal.failure(step) is None, goal.outcome
    assert goal.fit.optical_gain == pytest.approx(0.8, abs=0.01)
    assert goal.fit.stiffness == pytest.approx(1.15, abs=0.01)
    assert close.keeping == [True, False]  # kept for the close only


def test_a_fit_not_asked_to_apply_leaves_the_calibration():
    close = Close(1.0, 1.0)
    goal, step = close.run(apply=False)
    assert goal.failure(step) is None and not goal.applied and close.applied == []


def test_no_object_ends_at_the_closed_limit_and_applies_nothing():
    close = Close(1.0, 1.0, rod=False)
    goal, step = close.run(apply=True)
    assert step.outcome is Outcome.CLOSED_LIMIT_WITHOUT_CONTACT
    assert goal.failure(step).startswith("closed_limit_without_contact: ")
    assert close.applied == [] and math.isnan(goal.result(
        NS(step=step, opening_m=0.002), "")["stiffness"])


def test_a_refused_fit_applies_nothing():
    close = Close(1.0, 1.0)
    goal, step = close.run(apply=True)
    goal.closer.rows = goal.closer.rows[:8]  # as if the close were cut short
    assert goal.failure(step).startswith("too_few_samples: ")
    assert close.applied == [] and goal.outcome == "too_few_samples"


def test_a_close_whose_output_never_rises_stops_at_the_force_limit():
    close = Close(1.0, 1.0)
    close.gain = 0.0  # a module that reads nothing
    goal, step = close.run(apply=True)
    assert step.outcome is Outcome.FORCE_LIMIT and "without the module's output" in \
        step.message
    assert goal.failure(step).startswith("force_limit: ") and close.applied == []


def test_a_close_begun_while_the_servo_settles_from_a_release_still_fits():
    """The first ticks after a release see the servo still easing off its opening: an
    opening current, not the free close's. Taken as the free current it put the rack force
    tens of newtons high and stopped every retried close at the force limit."""

    class AfterRelease(Close):
        ticks = 0

        def servo(self, velocity: float) -> NS:
            reading = super().servo(velocity)
            self.ticks += 1
            if self.ticks <= 3:  # the start and two ticks: still opening, at -0.6 A
                return NS(**{**vars(reading), "velocity_rad_s": -0.05, "current_a": -0.6})
            return reading

    close = AfterRelease(0.8, 1.15)
    goal, step = close.run(apply=True)
    assert step.outcome is Outcome.CONTACT, step.message
    assert goal.failure(step) is None and goal.applied
    result = goal.result(NS(step=step, opening_m=0.02), "fitted")
    assert result["stiffness"] == pytest.approx(1.15, abs=0.03)


def test_no_fresh_output_ends_the_close_stale():
    close = Close(1.0, 1.0)
    close.links = close.with_links(lambda: None)
    _goal, step = close.run(apply=True)
    assert step.outcome is Outcome.TACTILE_STALE and "driver" in step.message


def test_an_output_the_driver_cannot_give_ends_the_close_stale_not_at_the_force_limit():
    """NaN (an untared or blind driver) never rises past the free level: taken as an
    output, the close pressed on until the rack force stopped it (27 N); taken as none
    came, it ends stale within half a millimetre of travel."""
    close = Close(1.0, 1.0)
    start = close.position
    close.links = close.with_links(lambda: math.nan)
    _goal, step = close.run(apply=True)
    assert step.outcome is Outcome.TACTILE_STALE and "driver" in step.message
    travel_m = (close.position - start) * R
    assert travel_m <= 0.0005 + 0.00002, travel_m


def gappy(close: Close, gap: tuple[float, float]):
    """The close's outputs, none fresh between ``gap`` [s] (a driver starved of the CPU)."""
    def output():
        return None if gap[0] <= close.t < gap[1] else close.output()
    return output


def test_outputs_late_for_less_than_half_a_millimetre_of_travel_leave_the_fit_whole():
    """0.4 s without a fresh output at 1 mm/s (0.4 mm of travel, under LATE_TRAVEL_M): the
    close goes on and the stamps still pair every reading; 0.6 s ends it stale."""
    close = Close(0.8, 1.15)
    close.links = close.with_links(gappy(close, (3.0, 3.4)))
    goal, step = close.run(apply=True)
    assert step.outcome is Outcome.CONTACT and goal.failure(step) is None, goal.outcome
    assert goal.fit.optical_gain == pytest.approx(0.8, abs=0.01)
    close = Close(0.8, 1.15)
    close.links = close.with_links(gappy(close, (3.0, 3.6)))
    _goal, step = close.run(apply=True)
    assert step.outcome is Outcome.TACTILE_STALE


def test_a_model_that_cannot_predict_refuses_before_anything_moves():
    def not_ready() -> SkinPrediction:
        raise SelfCheckError("model_not_ready", "The model cannot predict the skin yet.")

    close = Close(1.0, 1.0)
    close.links = close.with_links(close.output, not_ready)
    goal = accept_self_check(NS(closing_speed=0.0, apply=True), SETTINGS, close.links, 0.001)
    with pytest.raises(SelfCheckError, match="cannot predict"):
        goal.start(0.0, close.servo(0.0))


def test_a_speed_out_of_range_is_refused():
    with pytest.raises(InvalidRequest, match="Self-check closing speed"):
        accept_self_check(NS(closing_speed=-1.0, apply=False), SETTINGS,
                          Close(1.0, 1.0).links, 0.001)


def test_the_latest_output_goes_stale_and_the_fit_is_a_correction_of_the_fem_curve():
    latest = LatestOutput()
    assert latest.fresh(0.0, 0.1) is None
    latest.add(0.2, 1.0)
    latest.add(0.4, 1.01)
    assert latest.fresh(1.05, 0.1) == pytest.approx(0.3)  # the mean since the last tick
    assert latest.fresh(1.06, 0.1) == pytest.approx(0.3)  # none new: the last mean
    assert latest.fresh(1.2, 0.1) is None
    close = Close(0.8, 1.15)
    goal, step = close.run(apply=False)
    goal.failure(step)
    correction = correction_of(goal.fit, 123.0)
    assert correction.source == (f"self_check:gain={goal.fit.optical_gain:.4f}+-"
                                 f"{goal.fit.optical_gain_sigma:.4f},stiffness="
                                 f"{goal.fit.stiffness:.4f}+-{goal.fit.stiffness_sigma:.4f}")
    assert correction.optical_gain == pytest.approx(0.8, abs=0.001)
    assert correction.stamp_s == 123.0 and not correction.keep_on_new_calibration
    fem = Calibration.from_curve(list(SKIN.output_v[1:]), list(SKIN.force_n[1:]), "fem")
    output, force = goal.fit.corrected_curve(SKIN)
    corrected = correction.apply(fem)
    assert corrected.output_v == pytest.approx(output[1:].tolist())
    assert corrected.force_n == pytest.approx(force[1:].tolist())


def test_outputs_are_kept_with_their_stamps_only_while_asked_and_waited_for():
    latest = LatestOutput()
    latest.add(0.1, 0.0, 10.0)
    latest.keep(True)
    latest.add(0.2, 0.01, 10.001)
    adder = threading.Timer(0.05, lambda: latest.add(0.3, 0.02, 10.002))
    adder.start()
    assert latest.kept(10.002, timeout_s=PATIENCE_S) == ([10.001, 10.002], [0.2, 0.3])
    adder.join()
    assert latest.kept(11.0, timeout_s=0.0) == ([10.001, 10.002], [0.2, 0.3])  # none later
    latest.keep(False)
    latest.add(0.4, 0.03, 10.003)
    assert latest.kept(0.0) == ([], [])
