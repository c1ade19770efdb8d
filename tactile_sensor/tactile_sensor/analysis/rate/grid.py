"""The rate fit's view of a record: on a uniform grid, each phase run low-passed on its own,
the unloading reversals left out, block means at the fit's rate, and the noise the driver's
direction tracker sees (why each: ``fit``'s module docstring)."""

from __future__ import annotations

import math

import numpy as np
from scipy.signal import lfilter

from .history import UNIFORM_RTOL, zero_phase_low_pass
from .record import HOLD, LOADING, OUTSIDE, UNLOADING, RateRecord

SEGMENT_CUTOFF_HZ = 4.0  # the fit's low-pass of each phase run (module docstring)
REVERSAL_SHARE = 0.05  # unloading samples before the output fell by this share are left out
TRACKER_SMOOTHING_HZ = 10.0  # the direction tracker's first-order low-pass
BAND_SIGMAS = 8.0  # tracker band / noise of its smoothed output: noise flips it ~never
MIN_BAND_V = 1e-6  # a noise-free record still gets a band (it must be > 0)


def prepare_grid(record: RateRecord, fit_rate_hz: float
             ) -> tuple[RateRecord, np.ndarray, float, np.ndarray, np.ndarray]:
    """(the fit's grid: uniform, low-passed, reversal plays left out, block means; the
    output as recorded (uniform, not low-passed) in the grid's blocks, one row per grid
    sample [V]; the RMS the low-pass removed from the in-press output [V], its noise; each
    grid sample's branch by its press phase, True for loading; where the grid's phase runs
    start, as the low-pass saw them, before the reversals were left out)."""
    uniform = on_uniform_times(record)
    smooth = low_passed(uniform)
    inside = uniform.mask()
    noise_v = rmse(uniform.output_v[inside], smooth.output_v[inside]) if np.any(inside) else 0.0
    grid = decimate(without_reversals(smooth), fit_rate_hz)
    q = block_size(uniform, fit_rate_hz)
    blocks_v = uniform.output_v[:grid.t_s.size * q].reshape(grid.t_s.size, q)
    phase = decimate(smooth, fit_rate_hz).phase
    return grid, blocks_v, noise_v, phase_branches(phase), run_starts(phase)


def phase_branches(phase: np.ndarray) -> np.ndarray:
    """True on loading and hold samples, False on unloading, the last of those between
    presses (True before the first)."""
    code = np.where(np.isin(phase, (LOADING, HOLD)), 1, np.where(phase == UNLOADING, 0, -1))
    known = np.flatnonzero(code >= 0)
    if known.size == 0:
        return np.ones(phase.size, dtype=bool)
    last = np.maximum.accumulate(np.where(code >= 0, np.arange(phase.size), -1))
    return np.where(last >= 0, code[np.maximum(last, 0)] == 1, True)


def tracker_band_v(record: RateRecord) -> float:
    """The direction tracker's band [V] for this record's noise: ``BAND_SIGMAS`` x the
    noise of its smoothed output (at least ``MIN_BAND_V``)."""
    return max(MIN_BAND_V, BAND_SIGMAS * tracker_noise(record))


def tracker_noise(record: RateRecord) -> float:
    """RMS noise [V] of the in-press output after the tracker's first-order smoothing:
    the robust spread of what a zero-phase low-pass at a quarter of its cut-off leaves."""
    uniform = on_uniform_times(record)
    period = float(uniform.t_s[1] - uniform.t_s[0])
    alpha = -math.expm1(-2.0 * math.pi * TRACKER_SMOOTHING_HZ * period)
    out = uniform.output_v
    smooth = lfilter([alpha], [1.0, alpha - 1.0], out - out[0]) + out[0]
    slow = zero_phase_low_pass(period, TRACKER_SMOOTHING_HZ / 4.0, smooth)
    inside = uniform.mask()
    if slow is None or not np.any(inside):
        return 0.0
    residual = (smooth - slow)[inside]
    return float(1.4826 * np.median(np.abs(residual - np.median(residual))))


def on_uniform_times(record: RateRecord) -> RateRecord:
    """The record itself when its times are uniform, else interpolated onto its median
    period (labels of the nearest later sample)."""
    period = float(np.median(np.diff(record.t_s)))
    if np.allclose(np.diff(record.t_s), period, rtol=UNIFORM_RTOL, atol=0.0):
        return record
    t = np.arange(record.t_s[0], record.t_s[-1], period)
    near = np.clip(np.searchsorted(record.t_s, t), 0, record.t_s.size - 1)
    return RateRecord(t, np.interp(t, record.t_s, record.output_v),
                      np.interp(t, record.t_s, record.force_n),
                      record.speed_mm_s[near], record.phase[near])


def low_passed(record: RateRecord) -> RateRecord:
    """Output and force through ``low_pass_runs`` (module docstring)."""
    period = float(record.t_s[1] - record.t_s[0])
    starts = run_starts(record.phase)
    return RateRecord(record.t_s, low_pass_runs(period, starts, record.output_v),
                      low_pass_runs(period, starts, record.force_n), record.speed_mm_s,
                      record.phase)


def run_starts(phase: np.ndarray) -> np.ndarray:
    """Indices where a run of one phase label starts (after the first)."""
    return np.flatnonzero(np.diff(phase)) + 1


def low_pass_runs(period_s: float, starts: np.ndarray, values: np.ndarray,
                   only: np.ndarray | None = None) -> np.ndarray:
    """``values`` (time along the last axis), each run between ``starts`` on its own,
    through a zero-phase low-pass at ``SEGMENT_CUTOFF_HZ`` padded by a cut-off period;
    runs too short to filter stay as they are, and so do runs without an ``only`` sample
    (the caller never reads them)."""
    out = np.array(values, dtype=float)
    for run in np.split(np.arange(out.shape[-1]), starts):
        if only is not None and not np.any(only[run]):
            continue
        part = slice(int(run[0]), int(run[-1]) + 1) if run.size else slice(0, 0)
        smooth = zero_phase_low_pass(period_s, SEGMENT_CUTOFF_HZ, out[..., part], long_pad=True)
        if smooth is not None:
            out[..., part] = smooth
    return out


def without_reversals(record: RateRecord) -> RateRecord:
    """The record with the first samples of each unloading ramp labelled OUTSIDE, until
    the output has fallen by ``REVERSAL_SHARE`` of the in-press output range."""
    inside = record.mask()
    if not np.any(inside):
        return record
    drop = REVERSAL_SHARE * float(np.ptp(record.output_v[inside]))
    unloading = record.phase == UNLOADING
    starts = np.flatnonzero(unloading & ~np.concatenate(([False], unloading[:-1])))
    phase = record.phase.copy()
    for start in starts.tolist():
        after = np.flatnonzero(~unloading[start:])
        stop = start + (int(after[0]) if after.size else unloading.size - start)
        moved = np.flatnonzero(record.output_v[start:stop] <= record.output_v[start] - drop)
        phase[start:start + (int(moved[0]) if moved.size else stop - start)] = OUTSIDE
    return RateRecord(record.t_s, record.output_v, record.force_n, record.speed_mm_s, phase)


def speed_weights(record: RateRecord, speeds: list[float], score: np.ndarray) -> np.ndarray:
    """Per scored sample, 1 / (that speed's scored samples), scaled to a mean of 1: each
    speed counts the same, however long its presses last."""
    labels = record.speed_mm_s[score]
    weights = np.zeros(labels.size)
    for s in speeds:
        mine = labels == s
        if np.any(mine):
            weights[mine] = 1.0 / np.count_nonzero(mine)
    return weights * (weights.size / weights.sum())


def decimate(record: RateRecord, fit_rate_hz: float) -> RateRecord:
    """The record on a uniform grid near ``fit_rate_hz``: block means of time, output and
    force, labels of each block's middle sample (a non-uniform record is first
    interpolated onto its median period)."""
    record = on_uniform_times(record)
    q = block_size(record, fit_rate_hz)
    if q == 1:
        return record
    n = record.t_s.size // q * q

    def mean(a: np.ndarray) -> np.ndarray:
        return a[:n].reshape(-1, q).mean(axis=1)

    mid = np.arange(q // 2, n, q)
    return RateRecord(mean(record.t_s), mean(record.output_v), mean(record.force_n),
                      record.speed_mm_s[mid], record.phase[mid])


def block_size(record: RateRecord, fit_rate_hz: float) -> int:
    """Samples per grid block of a uniform record (``decimate``)."""
    return max(1, round(1.0 / (fit_rate_hz * float(np.median(np.diff(record.t_s))))))


def rmse(a: np.ndarray, b: np.ndarray) -> float:
    return rms(a - b)


def rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(x ** 2))) if x.size else math.nan
