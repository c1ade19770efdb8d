"""The friction margin a slip detector reads: mu Fn - |Ft|, low-passed, against its noise.

Shared by the slip study (analysis/slip/detector.py, which chose it) and the slip-aware
hold (control/slip_hold.py, which runs it): docs/gripper.md, "Can the sensor see slip?".
Why a margin: a sliding contact carries |Ft| = mu_k Fn (Coulomb), so the gap between the
friction limit and the shear closes before the contact breaks away, and it is a slow
quantity, read at a low bandwidth where the fingertip resolves force best.

Threshold: the margin's noise sigma_m = sqrt(sigma_t^2 + mu^2 sigma_n^2) at the cutoff; an
alarm once the filtered margin is below k sigma_m, with k from Rice's crossing rate for the
false-alarm rate (2nd-order Butterworth noise at cutoff B crosses k sigma upward
B exp(-k^2 / 2) times a second). A hold at rest needs a true margin of 2 k sigma_m to keep
that rate.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from tactile_sensor.sensing.errors import SensingError


def threshold_sigmas(false_alarms_per_hour: float, bandwidth_hz: float,
                     two_sided: bool = False) -> float:
    """k such that 2nd-order Butterworth noise at cutoff ``bandwidth_hz`` crosses k sigma
    (either sign when ``two_sided``) ``false_alarms_per_hour`` times an hour (Rice)."""
    if not (false_alarms_per_hour > 0 and bandwidth_hz > 0):
        raise SensingError("A false-alarm rate and a bandwidth must be > 0; give both.")
    per_second = false_alarms_per_hour / 3600.0 / (2.0 if two_sided else 1.0)
    ratio = bandwidth_hz / per_second
    return math.sqrt(2.0 * math.log(ratio)) if ratio > 1.0 else 0.0


def margin_sigma_n(friction: float, shear_sigma_n: float, normal_sigma_n: float) -> float:
    """The noise [N] of mu Fn - |Ft| from the noise of Ft and Fn at the same bandwidth."""
    return math.hypot(shear_sigma_n, friction * normal_sigma_n)


@dataclass(frozen=True)
class MarginNoise:
    """The fingertip's force noise as densities [N / sqrt(Hz)]: white noise through the
    low-pass leaves density x sqrt(B) (docs/gripper.md: 38.9 mN of Ft and 57.0 mN of Fn at
    10 Hz on the shear fingertip)."""

    shear_density: float
    normal_density: float
    false_alarms_per_hour: float = 1.0

    def __post_init__(self) -> None:
        if not (self.shear_density > 0 and self.normal_density > 0
                and self.false_alarms_per_hour > 0):
            raise SensingError("The slip margin's noise densities and false-alarm rate "
                               "must be > 0; fix the slip parameters.")

    def threshold_n(self, friction: float, bandwidth_hz: float) -> float:
        """k sigma_m [N]: the filtered margin below this is an alarm."""
        root = math.sqrt(bandwidth_hz)
        sigma = margin_sigma_n(friction, self.shear_density * root,
                               self.normal_density * root)
        return threshold_sigmas(self.false_alarms_per_hour, bandwidth_hz) * sigma

    def shear_sigma_n(self, bandwidth_hz: float) -> float:
        return self.shear_density * math.sqrt(bandwidth_hz)


class LowPass2:
    """2nd-order Butterworth low-pass (bilinear, pre-warped) on a stream at a fixed rate;
    starts settled on its first input, as a hold that was already running."""

    def __init__(self, cutoff_hz: float, rate_hz: float) -> None:
        if not 0 < cutoff_hz < rate_hz / 2:
            raise SensingError(f"A low-pass at {cutoff_hz!r} Hz needs a rate above twice it "
                               f"(here {rate_hz!r} Hz); lower the cutoff or raise the rate.")
        k = math.tan(math.pi * cutoff_hz / rate_hz)
        norm = 1.0 / (1.0 + math.sqrt(2.0) * k + k * k)
        self._b = (k * k * norm, 2.0 * k * k * norm, k * k * norm)
        self._a = (2.0 * (k * k - 1.0) * norm, (1.0 - math.sqrt(2.0) * k + k * k) * norm)
        self._z: tuple[float, float] | None = None

    def update(self, x: float) -> float:
        (b0, b1, b2), (a1, a2) = self._b, self._a
        if self._z is None:
            z2 = (b2 - a2) * x
            self._z = ((b1 - a1) * x + z2, z2)
        z1, z2 = self._z
        y = b0 * x + z1
        self._z = (b1 * x - a1 * y + z2, b2 * x - a2 * y)
        return y


class MarginFilter:
    """Fn, Fx and Fy each through the low-pass; ``update`` gives the filtered (Fn, |Ft|)."""

    def __init__(self, cutoff_hz: float, rate_hz: float) -> None:
        self._filters = tuple(LowPass2(cutoff_hz, rate_hz) for _ in range(3))

    def update(self, fn_n: float, fx_n: float, fy_n: float) -> tuple[float, float]:
        fn, fx, fy = (f.update(v) for f, v in zip(self._filters, (fn_n, fx_n, fy_n),
                                                   strict=True))
        return fn, math.hypot(fx, fy)
