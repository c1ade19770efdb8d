"""Following the module while nothing touches it: the baseline, and a modulated module's
optical gain against its calibration's.

Outside the dark room the level at rest moves: daylight changes, the emitter dims as it
warms and as it ages. Only at rest can the driver see it, and only when it is sure nothing
touches the skin: a whole tare window with no contact, the force under the contact's
release threshold, the detector not blind and the level steady (the tare's own test).

- **Re-tare at rest** (``RestRetare``): the baseline follows the window's mean with a time
  constant, so a slow change is followed while a press (faster than the follow) is not
  taken for light. A change that raises the force past the release threshold before the
  baseline catches it (a lamp switched on, a light step during a press) is read as force:
  a stock module has no reading without its emitter to tell the two apart.
- **A level that fell** on a stock module (less light: a lamp switched off, a shadow) is
  taken at once: a press only lowers the detector's voltage (the output rises), so a quiet
  window whose level stands above the baseline by more than the window's own spread can
  only be the module's level, never a touch. Followed with the time constant instead, a
  lamp switched off between presses left the next presses reading low for tens of seconds.
  A modulated module rejects the room's light; its level falls only as the emitter dims,
  slowly, and keeps the time constant, which averages its noisier signal into the gain.
- **The optical gain** (``RestGain``): a modulated module's signal is the emitter's light
  alone, so its drop at rest below the supply is proportional to emitter x detector x skin
  reflectance. Against the drop when the calibration was taken it is the gain the
  calibration's outputs must be scaled by for the sensitivity to hold; past a bound the
  driver asks for a recalibration. A stock module's drop at rest also holds the room's
  light: its gain cannot be measured.
"""

from __future__ import annotations

import math

from tactile_sensor.sensing.errors import SensingError

#: The relative change of the optical gain past which the driver asks for a recalibration.
DEFAULT_GAIN_BOUND = 0.15
#: The baseline's time constant at rest [s]: a press that keeps the force under the contact's
#: release threshold for this long is taken for light; a slower change of light is followed.
DEFAULT_RETARE_TIME_CONSTANT_S = 10.0
#: The longest time constant accepted [s]: an hour.
MAX_RETARE_TIME_CONSTANT_S = 3600.0


def _number(value: object) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) \
        and math.isfinite(value)


class RestRetare:
    """The baseline's first-order follow of the level at rest: one step per quiet window
    (``window_samples`` at ``rate_hz``); a time constant of 0 switches it off."""

    def __init__(self, time_constant_s: float, rate_hz: float, window_samples: int) -> None:
        if not _number(time_constant_s) or not 0.0 <= time_constant_s \
                <= MAX_RETARE_TIME_CONSTANT_S:
            raise SensingError(f"rest_retare_time_constant must be 0 (off) or a time in (0, "
                               f"{MAX_RETARE_TIME_CONSTANT_S:g}] s, got {time_constant_s!r}.")
        self.time_constant_s = float(time_constant_s)
        self.window_samples = window_samples
        self.enabled = time_constant_s > 0
        self.alpha = (-math.expm1(-window_samples / (rate_hz * time_constant_s))
                      if self.enabled else 0.0)
        self.retares = 0  # how many steps the baseline took at rest since start

    def follow(self, baseline_v: float, rest_mean_v: float, spread_v: float = math.inf) -> float:
        """The baseline after one quiet window whose mean was ``rest_mean_v`` and whose
        block means spread ``spread_v`` [V]: the window's mean at once if the level stands
        above the baseline by more than that spread (less light; no press raises the
        voltage), else one step of the first-order follow. Without a spread (an array's
        baselines, as arrays) every step is the follow's."""
        self.retares += 1
        if spread_v < math.inf and rest_mean_v - baseline_v > spread_v:
            return rest_mean_v
        return baseline_v + self.alpha * (rest_mean_v - baseline_v)


class RestGain:
    """A modulated module's optical gain: its emitter's drop at rest against the drop when
    the calibration was taken (the first baseline known after the calibration arrived)."""

    def __init__(self, bound: float = DEFAULT_GAIN_BOUND) -> None:
        if not _number(bound) or not 0.0 < bound < 1.0:
            raise SensingError(f"gain_warn_bound must be a fraction in (0, 1) (0.15 = warn "
                               f"past +-15 %), got {bound!r}.")
        self.bound = float(bound)
        self.reference_drop_v: float | None = None
        self.gain = 1.0

    def forget(self) -> None:
        """A new calibration (or a new kind of signal): the next drop is its reference."""
        self.reference_drop_v, self.gain = None, 1.0

    def observe(self, rest_drop_v: float) -> float:
        """The gain for the emitter's drop at rest ``rest_drop_v`` [V] (the supply less the
        baseline); the first positive drop after ``forget`` is the reference. A drop that
        is not positive (no emitter light) leaves the gain as it was."""
        if not rest_drop_v > 0:
            return self.gain
        if self.reference_drop_v is None:
            self.reference_drop_v = float(rest_drop_v)
        self.gain = rest_drop_v / self.reference_drop_v
        return self.gain

    @property
    def beyond_bound(self) -> bool:
        return abs(self.gain - 1.0) > self.bound

    def warning(self) -> str | None:
        """One sentence asking for a recalibration once the gain left its bound, else None."""
        if not self.beyond_bound:
            return None
        return (f"the module's optical gain is {self.gain:.2f} of its calibration's, past "
                f"the +-{self.bound * 100:.0f} % bound: recalibrate (the gripper's "
                "~/self_check, or a new calibration fit)")
