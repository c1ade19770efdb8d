"""Rate-aware forces along a whole record at once, as the driver computes them per sample.

The driver's estimator (``sensing.rate_calibration``) steps a Prony series per sample; on
a uniform grid each term is a first-order linear filter with the same coefficients
(``sensing.prony.term_coefficients``), which scipy's ``lfilter`` runs ~100x faster than a
Python loop: the fit evaluates the model thousands of times. Non-uniform times fall back
to the streaming series itself.
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import lru_cache

import numpy as np
from scipy.signal import butter, lfilter, lfilter_zi

from tactile_sensor.sensing.prony import PronySeries, term_coefficients
from tactile_sensor.sensing.rate_calibration import DirectionTracker, Play, RateCalibration

UNIFORM_RTOL = 1e-6


def unit_responses(t_s: np.ndarray, driving: np.ndarray, tau_s: Sequence[float]) -> np.ndarray:
    """(samples, terms): each term's h_i for g_i = 1, from rest at the first sample."""
    out = np.zeros((driving.size, len(tau_s)))
    if driving.size < 2:
        return out
    dt = np.diff(t_s)
    change = np.concatenate(([0.0], np.diff(driving)))
    uniform = np.allclose(dt, dt[0], rtol=UNIFORM_RTOL, atol=0.0)
    for k, tau in enumerate(tau_s):
        if uniform:
            decay, gain = term_coefficients(float(tau), float(dt[0]))
            out[:, k] = lfilter([gain], [1.0, -decay], change)
        else:
            series = PronySeries([1.0], [float(tau)])
            steps = np.concatenate(([0.0], dt)).tolist()
            out[:, k] = [series.step(x, s) for x, s in zip(driving.tolist(), steps,
                                                             strict=True)]
    return out


def static_force(curve_output_v: np.ndarray, curve_force_n: np.ndarray,
                 output_v: np.ndarray) -> np.ndarray:
    """The curve as the driver applies it: linear, clamped to its end forces."""
    return np.interp(output_v, curve_output_v, curve_force_n)


def loading_history(play: Play, t_s: np.ndarray, output_v: np.ndarray) -> np.ndarray:
    """True where the driver's direction tracker (one, from rest) is on the loading branch:
    the same class per sample, so the fit and the report see exactly what the driver does."""
    tracker = DirectionTracker(play.band_v, play.smoothing_hz)
    steps = np.concatenate(([0.0], np.diff(t_s))).tolist()
    update = tracker.update
    return np.fromiter((update(x, dt) for x, dt in zip(output_v.tolist(), steps, strict=True)),
                       dtype=bool, count=output_v.size)


def branch_static_force(cal: RateCalibration, t_s: np.ndarray, output_v: np.ndarray
                        ) -> np.ndarray:
    """F_s at every sample: the curve, or with play the branch the tracker picks."""
    loading, unloading = cal.branches
    fs = static_force(np.asarray(loading.output_v), np.asarray(loading.force_n), output_v)
    if cal.play is None:
        return fs
    down = static_force(np.asarray(unloading.output_v), np.asarray(unloading.force_n),
                        output_v)
    return np.where(loading_history(cal.play, t_s, output_v), fs, down)


def rate_force_history(cal: RateCalibration, t_s: np.ndarray, output_v: np.ndarray
                       ) -> np.ndarray:
    """The driver's rate-aware force at every sample of a record (one estimator from rest)."""
    fs = branch_static_force(cal, t_s, output_v)
    return fs + unit_responses(t_s, fs, cal.tau_s) @ np.asarray(cal.g)


LOW_PASS_ORDER = 2


@lru_cache(maxsize=64)
def _low_pass_design(wn: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Butterworth (b, a) and its step's steady state: designing them cost more than the
    filtering itself when a rate fit filters thousands of short runs at one cut-off."""
    b, a = butter(LOW_PASS_ORDER, wn)
    return b, a, lfilter_zi(b, a)


def zero_phase_low_pass(period_s: float, cutoff_hz: float, values: np.ndarray,
                        long_pad: bool = False) -> np.ndarray | None:
    """``values`` (uniform, ``period_s`` apart along the last axis) forwards and backwards
    through a Butterworth low-pass at ``cutoff_hz``: no delay, so an estimate and its gauge
    filtered alike stay aligned. None when the cut-off is not below the Nyquist rate or the
    record is too short to filter. ``long_pad`` extends the ends by one cut-off period
    (odd, so a ramp goes on as a ramp) instead of a few samples: a short run then has no
    start-up transient.

    The forward-backward pass is scipy's ``filtfilt`` with ``padtype="odd"`` (each end
    mirrored through its end value, both passes started in the steady state of their first
    sample), with the design cached."""
    wn = 2.0 * cutoff_hz * period_s
    if not (0.0 < wn < 1.0):
        return None
    b, a, zi = _low_pass_design(wn)
    length = values.shape[-1]
    short = 3 * max(a.size, b.size)
    if length <= short:
        return None
    pad = min(length - 1, max(short, round(2.0 / wn))) if long_pad else short
    x = np.asarray(values, dtype=float)
    first, last = x[..., :1], x[..., -1:]
    extended = np.concatenate((2 * first - x[..., pad:0:-1], x,
                               2 * last - x[..., -2:-pad - 2:-1]), axis=-1)
    forward, _ = lfilter(b, a, extended, zi=zi * extended[..., :1])
    backward, _ = lfilter(b, a, forward[..., ::-1], zi=zi * forward[..., -1:])
    return backward[..., ::-1][..., pad:-pad]
