"""The slip detector the study chose: the friction margin, low-passed at a reflex's
bandwidth, against a threshold the false-alarm rate sets.

Why this signature (docs/gripper.md, "Can the sensor see slip?"): in the object model, and
in Coulomb friction generally, a sliding contact carries |Ft| = mu_k Fn: the shear stops
growing at the friction limit. The margin m = mu Fn - |Ft| is a slow quantity, so it is
read at a low bandwidth where the layout resolves the tangential force best, and it warns
while the load still rises, before the contact breaks away. The other two signatures are
below the noise at every reflex bandwidth (the normal force's dip, by the FEM's shear
coupling) or absent from the model (vibration above the object's own ring).
mu is the friction the hold has learned (from the level at which the shear stopped
growing at an earlier slip, or from a probe); the detector needs it.

Threshold: the margin's noise sigma_m = sqrt(sigma_t^2 + mu^2 sigma_n^2) at the cutoff;
the detector fires once the filtered margin is below k sigma_m, k from Rice's crossing
rate for the false-alarm rate (``resolution.threshold_sigmas``). A hold at rest then needs
a true margin of 2 k sigma_m to keep that rate (``least_margin_n``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from tactile_sensor.analysis.errors import AnalysisError
from tactile_sensor.analysis.slip.resolution import Resolution
from tactile_sensor.analysis.slip.signature import SAMPLE_RATE_HZ
from tactile_sensor.sensing.slip_margin import margin_sigma_n


@dataclass(frozen=True)
class MarginDetector:
    """Fires when the margin mu Fn - |Ft|, both through a 2nd-order Butterworth low-pass at
    ``bandwidth_hz``, falls below ``threshold_n``."""

    friction: float
    bandwidth_hz: float
    threshold_n: float

    def __post_init__(self) -> None:
        if not (math.isfinite(self.friction) and self.friction > 0):
            raise AnalysisError(f"The detector's friction ({self.friction!r}) must be a "
                                "finite coefficient > 0.")
        if not 0 < self.bandwidth_hz < SAMPLE_RATE_HZ / 2:
            raise AnalysisError(f"The detector's bandwidth ({self.bandwidth_hz!r} Hz) must "
                                f"lie between 0 and {SAMPLE_RATE_HZ / 2:g} Hz.")

    @classmethod
    def for_resolution(cls, friction: float, res: Resolution) -> MarginDetector:
        """The threshold k sigma_m of ``res`` (its bandwidth, noise and k) at ``friction``."""
        sigma = margin_sigma_n(friction, res.sigma_n[0], res.sigma_n[2])
        return cls(friction, res.bandwidth_hz, res.k * sigma)

    def least_margin_n(self) -> float:
        """The true margin [N] a hold at rest needs for the false-alarm rate: twice the
        threshold (the filtered margin then reaches it k sigma below its mean)."""
        return 2.0 * self.threshold_n

    def margin(self, ft_n: np.ndarray, fn_n: np.ndarray) -> np.ndarray:
        """The filtered margin [N] along 1 kHz samples of Ft and Fn (causal; the filter
        starts settled on the mean of the first 1 / bandwidth of samples, as a hold that
        was already running)."""
        from scipy.signal import butter, lfilter, lfilter_zi

        b, a = butter(2, self.bandwidth_hz / (SAMPLE_RATE_HZ / 2))
        zi = lfilter_zi(b, a)
        lead = max(1, math.ceil(SAMPLE_RATE_HZ / self.bandwidth_hz))
        ft = np.asarray(ft_n, float)
        fn = np.asarray(fn_n, float)
        ft_f, _ = lfilter(b, a, ft, zi=zi * float(np.mean(ft[:lead])))
        fn_f, _ = lfilter(b, a, fn, zi=zi * float(np.mean(fn[:lead])))
        return self.friction * fn_f - np.abs(ft_f)

    def first_alarm(self, ft_n: np.ndarray, fn_n: np.ndarray, start: int = 0) -> int | None:
        """Index of the first sample from ``start`` at which it fires, or None."""
        below = np.flatnonzero(self.margin(ft_n, fn_n)[start:] < self.threshold_n)
        return int(below[0]) + start if below.size else None

    def alarms(self, ft_n: np.ndarray, fn_n: np.ndarray) -> int:
        """How many times it fires (downward crossings of the threshold)."""
        below = self.margin(ft_n, fn_n) < self.threshold_n
        return int(np.count_nonzero(below[1:] & ~below[:-1]) + int(below[0]))


def detection_delay_s(detector: MarginDetector, t_s: np.ndarray, ft_n: np.ndarray,
                      fn_n: np.ndarray, onset_s: float, from_s: float = 0.0) -> float | None:
    """From the slip's onset to the first alarm at or after ``from_s`` [s] (negative: it
    warned before the contact broke away), or None when it never fired."""
    first = detector.first_alarm(ft_n, fn_n, int(np.searchsorted(t_s, from_s)))
    return None if first is None else float(t_s[first] - onset_s)
