"""The ``SelfCheck`` action's goal: one slow close recorded for the fit (control/self_check.py).

The fingers close at the self-check's speed towards the closed limit. Every control tick
records the servo's position, velocity and Present Current and the host time the servo
took them; the module's outputs are kept with their stamps beside. Once the output (the
mean of those received since the last tick) has risen ``CONTACT_RISE_V`` over its level at
the start, the fingers close on for ``PRESS_M`` more and stop: about 2.4 mm into finger A's
skin, inside the FEM prediction's 3 mm. Reaching the closed limit first ends
``closed_limit_without_contact``. When the close ends, each servo sample takes the outputs
stamped around it (control/stamp_pairing.py: a reading that came late still pairs with
the position it was sampled at) and the fit runs; a certain fit is applied through
``apply`` when the goal asks.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from tactile_sensor.control.actions import ActiveGoal, Fields, GoalSettings, Snapshot
from tactile_sensor.control.errors import InvalidRequest
from tactile_sensor.control.grasp import (
    BaseController,
    Outcome,
    Phase,
    ServoCommand,
    ServoReading,
    Step,
)
from tactile_sensor.control.self_check import (
    ClosingRecord,
    DriveTrain,
    SelfCheckError,
    SelfCheckFit,
    SkinPrediction,
    fit_self_check,
)
from tactile_sensor.control.stamp_pairing import outputs_at

#: Output rise over the starting level that starts the press [V] (about 0.35 mm).
CONTACT_RISE_V = 0.05
#: Finger travel past that rise [m].
PRESS_M = 0.002
#: Finger travel a close may make while the module's outputs come late [m]: the pairing
#: takes them by their stamps afterwards, so only the stop waits for them; a quarter of
#: ``PRESS_M`` (0.5 s at the default 1 mm/s, a busy machine's gap), and the rack-force
#: stop needs no output.
LATE_TRAVEL_M = 0.0005
#: Seconds a close may take beyond its travel at speed.
TIMEOUT_MARGIN_S = 5.0
#: Rack force [N] (from the servo's current) at which a close whose output never rose
#: stops: twice the FEM skin's force at 3 mm on both fingers.
MAX_RACK_FORCE_N = 4.0 * 6.77


@dataclass(frozen=True)
class SelfCheckLinks:
    """What the goal needs from the node: the newest module output [V] (None: none
    fresh), the FEM prediction for the skin (raises ``SelfCheckError`` when the model
    cannot give it), how to apply a corrected calibration, the drive train, the host time
    [s] a servo sample was taken (None: not known; the tick's time then), and the module
    outputs kept with their stamps: ``keep_outputs(True)`` starts keeping them (False
    stops), ``kept_outputs(until_s)`` gives (stamps [s], outputs [V]) once one stamped at
    or after ``until_s`` came (or the node gives up waiting)."""

    output_v: Callable[[], float | None]
    prediction: Callable[[], SkinPrediction]
    apply: Callable[[SelfCheckFit, SkinPrediction], None]
    train: DriveTrain
    sampled_at: Callable[[ServoReading], float | None]
    keep_outputs: Callable[[bool], None]
    kept_outputs: Callable[[float], tuple[Sequence[float], Sequence[float]]]


class SelfCheckController(BaseController):
    """Close slowly, record, stop ``PRESS_M`` past the output's rise."""

    def start(self, speed_m_s: float, now_s: float, servo: ServoReading,
              train: DriveTrain) -> Step:
        g = self.config.geometry
        self._started_s = now_s
        self._late_s = LATE_TRAVEL_M / speed_m_s
        self._fresh_s, self._last_output_v = now_s, None
        self._timeout_s = (g.opening_m(servo.position_rad) - g.closed_opening_m) / (
            2.0 * speed_m_s) + TIMEOUT_MARGIN_S
        self.phase = Phase.CLOSING
        #: Per servo sample: host time [s], position [rad], velocity [rad/s], current [A].
        self.rows: list[tuple[float, float, float, float]] = []
        self._level: float | None = None
        self._rise_at: float | None = None
        self._free_a: float | None = None
        self._train = train
        command = ServoCommand(g.closed_position_rad, g.finger_speed_to_rad_s(speed_m_s),
                               self.config.closing_current_a)
        return Step(self.phase, command, None, "closing", self._opening(servo))

    def tick(self, now_s: float, servo: ServoReading, output_v: float | None,
             sampled_at_s: float | None = None) -> Step:
        """One servo sample (taken at ``sampled_at_s``, host time [s]; the tick's time when
        not known) beside the mean output received since the last tick."""
        if (common := self._check_common(now_s, servo, None)) is not None:
            return common
        if output_v is not None and not math.isfinite(output_v):
            # an output the driver cannot give (untared, blind: NaN) shows no rise: the
            # close would press on to the force limit, so it counts as none came
            output_v = None
        if output_v is None:  # late: the close goes on at the last level a while
            output_v = self._last_output_v
            if output_v is None or now_s - self._fresh_s > self._late_s:
                return self._finish(Outcome.TACTILE_STALE, "no fresh module output; check "
                                    "that the driver runs and publishes its reading", servo)
        else:
            self._fresh_s, self._last_output_v = now_s, output_v
        position = servo.position_rad
        self.rows.append((now_s if sampled_at_s is None else sampled_at_s, position,
                          getattr(servo, "velocity_rad_s", math.nan),
                          getattr(servo, "current_a", math.nan)))
        current = getattr(servo, "current_a", 0.0)
        if self._level is None:
            self._level = output_v
        if self._free_a is None and getattr(servo, "velocity_rad_s", 0.0) > 0.0:
            # the free close's current, once it closes: a first tick after a release still
            # sees the servo settling from the opening, and its current would put the rack
            # force tens of newtons high before any contact
            self._free_a = current
        if self._rise_at is None and output_v > self._level + CONTACT_RISE_V:
            self._rise_at = position
        if self._rise_at is None and self._free_a is not None and float(
                self._train.rack_force_n(current, self._free_a)) > MAX_RACK_FORCE_N:
            return self._finish(Outcome.FORCE_LIMIT, (
                f"the fingers pressed {MAX_RACK_FORCE_N:.3g} N without the module's output "
                f"rising {CONTACT_RISE_V} V; check the module and the driver"), servo)
        g = self.config.geometry
        if self._rise_at is not None and (
                position - self._rise_at) * g.pitch_radius_m >= PRESS_M:
            return self._finish(Outcome.CONTACT, "pressed", servo)
        if self._opening(servo) <= g.closed_opening_m + self.config.limit_tolerance_m:
            return self._finish(Outcome.CLOSED_LIMIT_WITHOUT_CONTACT, (
                "the fingers reached their closed limit without touching anything; put a "
                "rigid object between the fingers and run the self-check again"), servo)
        return Step(self.phase, None, None, "closing", self._opening(servo))

    @property
    def last_sample_s(self) -> float | None:
        """Host time of the newest servo sample [s] (None before any)."""
        return self.rows[-1][0] if self.rows else None

    def record(self, stamps_s: Sequence[float], outputs_v: Sequence[float]) -> ClosingRecord:
        """The close: each servo sample beside the mean of the outputs stamped around it
        (samples without one are left out)."""
        if not self.rows:
            return ClosingRecord.of([], [], [], [])
        times, position, velocity, current = (np.asarray(c, dtype=float)
                                              for c in zip(*self.rows, strict=True))
        kept, output = outputs_at(times, stamps_s, outputs_v)
        return ClosingRecord.of(position[kept], velocity[kept], current[kept], output)


class SelfCheckGoal(ActiveGoal):
    """One self-check: the close, then the fit, then (asked and certain) the correction."""

    def __init__(self, settings: GoalSettings, speed_m_s: float, apply: bool,
                 links: SelfCheckLinks) -> None:
        self.closer = SelfCheckController(settings.config)
        super().__init__(settings, self.closer)
        self.speed_m_s, self.apply, self.links = speed_m_s, apply, links
        self.fit: SelfCheckFit | None = None
        self.outcome = ""
        self.applied = False
        self._prediction: SkinPrediction | None = None

    def start(self, now_s: float, servo: ServoReading) -> Step:
        # before anything moves: a model that cannot predict refuses the goal
        self._prediction = self.links.prediction()
        self.links.output_v()  # outputs from before the goal are not the close's
        self.links.keep_outputs(True)
        return self.closer.start(self.speed_m_s, now_s, servo, self.links.train)

    def tick(self, now_s: float, force_n: float | None, force_stamp_s: float | None,
             servo: ServoReading) -> Step:
        return self.closer.tick(now_s, servo, self.links.output_v(),
                                self.links.sampled_at(servo))

    def failure(self, step: Step) -> str | None:
        """The fit, on a close that pressed; why there is none otherwise."""
        if step.outcome is not Outcome.CONTACT or self._prediction is None:
            self.outcome = str(step.outcome)
            return f"{step.outcome}: {step.message}"
        last = self.closer.last_sample_s
        stamps, outputs = self.links.kept_outputs(last) if last is not None else ((), ())
        self.links.keep_outputs(False)
        try:
            self.fit = fit_self_check(self.closer.record(stamps, outputs), self._prediction,
                                      self.links.train)
        except SelfCheckError as exc:
            self.outcome = exc.outcome
            return f"{exc.outcome}: {exc}"
        self.outcome = "fitted"
        if self.apply:
            self.links.apply(self.fit, self._prediction)
            self.applied = True
        return None

    def feedback(self, snap: Snapshot) -> Fields:
        return {"opening": snap.opening_m}

    def result(self, snap: Snapshot, message: str) -> Fields:
        self.links.keep_outputs(False)  # however the goal ended
        fit = self.fit
        return {"outcome": self.outcome or str(snap.step.outcome),
                "optical_gain": fit.optical_gain if fit else math.nan,
                "optical_gain_sigma": fit.optical_gain_sigma if fit else math.nan,
                "stiffness": fit.stiffness if fit else math.nan,
                "stiffness_sigma": fit.stiffness_sigma if fit else math.nan,
                "applied": self.applied, "message": message}


def accept_self_check(goal: object, settings: GoalSettings, links: SelfCheckLinks,
                      default_speed_m_s: float) -> SelfCheckGoal:
    """``SelfCheck``: 0 speed means the gripper's self-check speed."""
    speed = float(getattr(goal, "closing_speed", 0.0)) or default_speed_m_s
    top = SelfCheckController(settings.config).max_speed_m_s
    if not (math.isfinite(speed) and 0.0 < speed <= top):
        raise InvalidRequest(f"Self-check closing speed {speed} m/s must be in (0, {top:.3g}]"
                             " m/s; give 0 for the gripper's self-check speed.")
    return SelfCheckGoal(settings, speed, bool(getattr(goal, "apply", False)), links)
