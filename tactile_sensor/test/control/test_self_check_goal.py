"""The SelfCheck goal: the slow close it records, where it stops, the fit and the apply."""

from __future__ import annotations

import math
from types import SimpleNamespace as NS

import numpy as np
import pytest

from tactile_sensor.control.actions import GoalSettings
from tactile_sensor.control.errors import InvalidRequest
from tactile_sensor.control.grasp import GraspConfig, Outcome
from tactile_sensor.control.self_check import DriveTrain, SelfCheckError, SkinPrediction
from tactile_sensor.control.self_check_goal import PRESS_M, SelfCheckLinks, accept_self_check
from tactile_sensor.nodes.self_check_links import LatestOutput, corrected_calibration

D = np.linspace(0.0, 0.003, 16)
SKIN = SkinPrediction(tuple(D.tolist()), tuple((1.6e3 * D + 2.6e5 * D**2).tolist()),
                      tuple((150.0 * D + 7e3 * D**2).tolist()))
SETTINGS = GoalSettings(GraspConfig())
GEOMETRY = SETTINGS.config.geometry
R = GEOMETRY.pitch_radius_m


class Close:
    """A 20 mm rod centred between the fingers, a skin at ``stiffness`` and a module at
    ``gain``; the servo follows its goal at the commanded speed, one tick at a time."""

    def __init__(self, gain: float, stiffness: float, rod: bool = True) -> None:
        self.gain, self.stiffness, self.rod = gain, stiffness, rod
        self.position = GEOMETRY.position_rad(0.024)
        self.applied: list[object] = []
        self.links = SelfCheckLinks(self.output, lambda: SKIN,
                                    lambda fit, skin: self.applied.append(fit), DriveTrain())

    def indentation(self) -> float:
        return max(0.0, (0.020 - GEOMETRY.opening_m(self.position)) / 2.0) if self.rod else 0.0

    def output(self) -> float:
        return 0.01 + self.gain * float(SKIN.output(np.array(self.indentation())))

    def servo(self, velocity: float) -> NS:
        d = self.indentation()  # the skin's law, past the table too
        force = 2.0 * self.stiffness * (1.6e3 * d + 2.6e5 * d**2)
        return NS(position_rad=self.position, velocity_rad_s=velocity, moving=True,
                  hardware_error=frozenset(), current_a=0.0188 + force * R / (3.0 / 2.3))

    def run(self, apply: bool) -> tuple[object, object]:
        goal = accept_self_check(NS(closing_speed=0.0, apply=apply), SETTINGS, self.links,
                                 0.001)
        step = goal.start(0.0, self.servo(0.0))
        speed, t = step.command.profile_velocity_rad_s, 0.0
        while not step.finished:
            t += 0.01
            self.position = min(self.position + speed * 0.01, GEOMETRY.closed_position_rad)
            step = goal.tick(t, None, None, self.servo(speed))
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


def test_no_fresh_output_ends_the_close_stale():
    close = Close(1.0, 1.0)
    close.links = SelfCheckLinks(lambda: None, lambda: SKIN, lambda f, s: None, DriveTrain())
    _goal, step = close.run(apply=True)
    assert step.outcome is Outcome.TACTILE_STALE and "driver" in step.message


def test_a_model_that_cannot_predict_refuses_before_anything_moves():
    def not_ready() -> SkinPrediction:
        raise SelfCheckError("model_not_ready", "The model cannot predict the skin yet.")

    close = Close(1.0, 1.0)
    close.links = SelfCheckLinks(close.output, not_ready, lambda f, s: None, DriveTrain())
    goal = accept_self_check(NS(closing_speed=0.0, apply=True), SETTINGS, close.links, 0.001)
    with pytest.raises(SelfCheckError, match="cannot predict"):
        goal.start(0.0, close.servo(0.0))


def test_a_speed_out_of_range_is_refused():
    with pytest.raises(InvalidRequest, match="Self-check closing speed"):
        accept_self_check(NS(closing_speed=-1.0, apply=False), SETTINGS,
                          Close(1.0, 1.0).links, 0.001)


def test_the_latest_output_goes_stale_and_the_correction_is_a_calibration():
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
    calibration = corrected_calibration(goal.fit, SKIN)
    assert calibration.source.startswith("self_check:gain=0.8")
    assert calibration.full_scale_force_n == pytest.approx(goal.fit.stiffness * SKIN.force_n[-1])
