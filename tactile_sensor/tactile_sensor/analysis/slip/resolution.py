"""The force resolution a module layout has at an output bandwidth, and what it resolves of
the ratio |Ft| / Fn.

Near a working point the modules' outputs are linear in the load: o = o0 + S F, S (modules x
3) [V/N] the local sensitivity of the FEM array grid (``local_sensitivity``). Each module
carries independent white noise sigma_sample per 1 kHz sample; a 2nd-order Butterworth
low-pass at cutoff B leaves sigma(B) of it (``physics.output_noise``). The least-squares
force estimate (what a calibration fitted on the grid does near that point) then has the
covariance sigma(B)^2 (S^T S)^-1: its square-rooted diagonal is each force's resolution.

The friction ratio r = |Ft| / Fn of a grip Fn has, to first order, the noise
sqrt(sigma_t^2 + r^2 sigma_n^2) / Fn; a ratio is resolved from 0 when it exceeds k times
that noise, k the threshold a false-alarm rate sets (``threshold_sigmas``).

False alarms: low-passed Gaussian noise crosses a level u upward at Rice's rate
nu = (1/2 pi) sqrt(lambda2 / lambda0) exp(-u^2 / 2 sigma^2) (S. O. Rice, "Mathematical
analysis of random noise", Bell Syst. Tech. J. 24, 1945, eq. 3.3-5), lambda0 and lambda2
the spectrum's 0th and 2nd moments. For the 2nd-order Butterworth, |H|^2 = 1 / (1 +
(f/B)^4), lambda2 / lambda0 = (2 pi B)^2, so nu = B exp(-k^2 / 2) at u = k sigma.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from tactile_sensor.analysis.errors import AnalysisError
from tactile_sensor.physics.output_noise import SAMPLE_NOISE_V, noise_at_bandwidth
from tactile_sensor.sensing import slip_margin
from tactile_sensor.sensing.errors import SensingError

#: The bandwidths [Hz] a reflex needs (10 to 100 Hz), at which resolution is reported.
REFLEX_BANDWIDTHS_HZ = (10.0, 20.0, 30.0, 50.0, 100.0)
#: Force axes in the array grid's order: along the fingers (x), across (y), normal (z).
AXES = ("x", "y", "z")


def local_sensitivity(grid: Any, indentation_m: float) -> np.ndarray:
    """S (modules x 3) [V/N] of the grid's modules at ``indentation_m``: a linear fit with
    an intercept of the outputs against (Fx, Fy, Fz) over the points pressed to the nearest
    indentation level and its neighbours, unsheared or at the smallest shear level in every
    direction (the load a sticking contact carries near that grip)."""
    step = np.asarray(grid.step, int)
    level = np.asarray(grid.level, int)
    d = np.asarray(grid.indentation_m, float)
    levels = sorted({(int(s), float(x)) for s, x in zip(step, d, strict=True) if s > 0})
    if not levels:
        raise AnalysisError("The array grid holds no pressed point; recompute it with "
                            "'tactile-sensor model array-calibration'.")
    near = min(levels, key=lambda sd: abs(sd[1] - indentation_m))[0]
    rows = (np.abs(step - near) <= 1) & (level <= 1) & (step > 0)
    forces = np.asarray(grid.force_matrix(), float)[rows]
    outputs = np.asarray(grid.output_matrix(), float)[rows]
    design = np.column_stack([np.ones(forces.shape[0]), forces])
    solution, *_ = np.linalg.lstsq(design, outputs, rcond=None)
    return solution[1:].T


def force_covariance(sensitivity: np.ndarray, noise_v: float) -> np.ndarray:
    """(3 x 3) covariance [N^2] of the least-squares force from outputs with independent
    noise ``noise_v`` [V] each. An axis outside the row space of S (no combination of the
    outputs reads it alone: a single module cannot tell shear from press) has an infinite
    variance; its covariance with the rest is left 0."""
    s = np.asarray(sensitivity, float)
    pinv = np.linalg.pinv(s, rcond=1e-6)
    gram = pinv @ pinv.T
    cov = noise_v**2 * gram
    seen = np.abs(np.diag(pinv @ s) - 1.0) < 1e-6
    cov[~seen, :] = 0.0
    cov[:, ~seen] = 0.0
    cov[~seen, ~seen] = math.inf
    return cov


def threshold_sigmas(false_alarms_per_hour: float, bandwidth_hz: float,
                     two_sided: bool = False) -> float:
    """k such that 2nd-order Butterworth noise at cutoff ``bandwidth_hz`` crosses k sigma
    (either sign when ``two_sided``) ``false_alarms_per_hour`` times an hour (Rice; the
    hold uses the same, sensing/slip_margin.py)."""
    try:
        return slip_margin.threshold_sigmas(false_alarms_per_hour, bandwidth_hz, two_sided)
    except SensingError as exc:
        raise AnalysisError(str(exc)) from exc


def crossing_rate_hz(k: float, bandwidth_hz: float) -> float:
    """Rice's upward crossings per second of k sigma by 2nd-order Butterworth noise."""
    return bandwidth_hz * math.exp(-0.5 * k * k)


@dataclass(frozen=True)
class Resolution:
    """One layout at one bandwidth: each force's noise [N] and the ratio |Ft| / Fn it
    resolves from zero at a grip ``normal_n`` with the threshold ``k`` sigmas."""

    bandwidth_hz: float
    noise_v: float
    sigma_n: tuple[float, float, float]
    normal_n: float
    k: float

    @property
    def tangential_n(self) -> float:
        """The noise of the force along the fingers (x) [N]."""
        return self.sigma_n[0]

    @property
    def resolved_ratio(self) -> float:
        """The smallest |Ft| / Fn told from 0 at ``normal_n`` (k sigma)."""
        return self.k * self.tangential_n / self.normal_n

    def ratio_noise(self, ratio: float) -> float:
        """The noise of |Ft| / Fn at ``ratio`` (first order)."""
        return math.hypot(self.sigma_n[0], ratio * self.sigma_n[2]) / self.normal_n


def resolution(sensitivity: np.ndarray, bandwidth_hz: float, normal_n: float,
               false_alarms_per_hour: float = 1.0,
               sample_noise_v: float = SAMPLE_NOISE_V) -> Resolution:
    """The layout's resolution at ``bandwidth_hz`` (module noise ``sample_noise_v`` per
    sample) for a grip ``normal_n`` [N], the threshold set by ``false_alarms_per_hour``."""
    if not (math.isfinite(normal_n) and normal_n > 0):
        raise AnalysisError(f"The grip ({normal_n!r} N) must be a finite force > 0.")
    noise = noise_at_bandwidth(bandwidth_hz, sample_noise_v)
    cov = force_covariance(sensitivity, noise)
    sigma = tuple(float(math.sqrt(v)) for v in np.diag(cov))
    return Resolution(bandwidth_hz, noise, (sigma[0], sigma[1], sigma[2]), normal_n,
                      threshold_sigmas(false_alarms_per_hour, bandwidth_hz))
