"""A correction found in the field, applied over whatever calibration the driver has.

The gripper's self-check (control/self_check.py) finds how the module reads now: an
optical gain (the output at an indentation is ``gain`` times the calibration's) and a skin
stiffness (the force there is ``stiffness`` times the calibration's). Over a base curve of
points (output, force) the corrected curve is (gain x output, stiffness x force): the
same indentations, read through the optics and the skin as they are now. A rate-aware
base keeps its relative rate terms; its play's force gap scales with the stiffness and
its direction band with the gain.

A base calibration (the model's latched curve, a file) and a correction (latched by the
gripper) reach a driver in no set order. Their stamps decide, not the order they came in:
a correction applies over a base stamped before it, or loaded from a file; a base stamped
after a correction describes the module as it is then and replaces the correction,
unless the correction says to keep it (``keep_on_new_calibration``). A base or a
correction older than the one in use is ignored; the same one heard twice changes nothing.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from tactile_sensor.sensing.calibration import Calibration
from tactile_sensor.sensing.errors import CalibrationError
from tactile_sensor.sensing.rate_calibration import Play, RateCalibration

BaseCalibration = Calibration | RateCalibration
#: The stamp of a base calibration that has none (a file loaded at configure): older than
#: any correction.
UNSTAMPED = -math.inf


@dataclass(frozen=True)
class CalibrationCorrection:
    """Two factors over the base calibration, where they come from and when [s]."""

    source: str
    optical_gain: float
    stiffness: float
    stamp_s: float
    keep_on_new_calibration: bool = False
    optical_gain_sigma: float = math.nan
    stiffness_sigma: float = math.nan

    def __post_init__(self) -> None:
        for name in ("optical_gain", "stiffness"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise CalibrationError(
                    f"{self.source or 'a calibration correction'}: {name} = {value!r}; a "
                    "correction's factors must be finite and > 0 (run the self-check again).")

    def apply(self, base: BaseCalibration) -> BaseCalibration:
        """The base curve through the optics and the skin as they are now."""
        static = base.static if isinstance(base, RateCalibration) else base
        corrected = Calibration([self.optical_gain * v for v in static.output_v],
                                [self.stiffness * f for f in static.force_n],
                                f"{static.source} corrected by {self.source}")
        if not isinstance(base, RateCalibration):
            return corrected
        play = base.play
        if play is not None:
            play = Play(tuple(self.stiffness * g for g in play.half_gap_n),
                        self.optical_gain * play.band_v, play.smoothing_hz)
        return RateCalibration(corrected, base.terms, play)


def _same(a: BaseCalibration | None, b: BaseCalibration | None) -> bool:
    """The same curve, rate terms and source (a latched curve heard again)."""
    if a is None or b is None or type(a) is not type(b) or a.source != b.source:
        return a is b
    sa = a.static if isinstance(a, RateCalibration) else a
    sb = b.static if isinstance(b, RateCalibration) else b
    same_rate = (not isinstance(a, RateCalibration) or not isinstance(b, RateCalibration)
                 or (a.terms == b.terms and a.play == b.play))
    return sa.output_v == sb.output_v and sa.force_n == sb.force_n and same_rate


class CorrectedCalibration:
    """The driver's base calibration and the correction over it (module docstring)."""

    def __init__(self, base: BaseCalibration | None = None,
                 base_stamp_s: float = UNSTAMPED) -> None:
        self.base, self.base_stamp_s = base, base_stamp_s
        self.correction: CalibrationCorrection | None = None
        self.effective: BaseCalibration | None = base

    def set_base(self, base: BaseCalibration, stamp_s: float) -> tuple[bool, str]:
        """Take a base calibration; (whether the calibration in use changed, what
        happened to it or to the correction: "" when nothing to say)."""
        if _same(base, self.base):
            return False, ""
        if stamp_s < self.base_stamp_s:
            return False, (f"the calibration {base.source} is older than the one in use "
                           f"({self.base.source if self.base else ''}); ignored")
        self.base, self.base_stamp_s = base, stamp_s
        note = ""
        correction = self.correction
        if (correction is not None and stamp_s > correction.stamp_s
                and not correction.keep_on_new_calibration):
            self.correction = None
            note = (f"the correction {correction.source} is older than this calibration "
                    "and was dropped; run the self-check again to correct it")
        self._update()
        return True, note

    def set_correction(self, correction: CalibrationCorrection) -> tuple[bool, str]:
        """Take a correction; (whether the calibration in use changed, why it was not
        applied: "" when it was, or waits for a base)."""
        current = self.correction
        if current == correction:
            return False, ""
        if current is not None and correction.stamp_s < current.stamp_s:
            return False, (f"the correction {correction.source} is older than the one in "
                           f"use ({current.source}); ignored")
        if (self.base is not None and self.base_stamp_s > correction.stamp_s
                and not correction.keep_on_new_calibration):
            return False, (f"the correction {correction.source} is older than the "
                           f"calibration in use ({self.base.source}); ignored: run the "
                           "self-check again to correct it")
        self.correction = correction
        return self._update(), ""

    def _update(self) -> bool:
        before = self.effective
        base, correction = self.base, self.correction
        self.effective = (correction.apply(base) if base is not None and correction is not None
                          else base)
        return self.effective is not before
