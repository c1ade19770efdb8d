"""The paper's characterisation metrics, computed from aligned, segmented signals.

Every formula is written out in docs/analysis-metrics.md; names here follow it.
Outputs and forces are changes from the rest baseline (the paper's "change in output
from its initial value"). A metric the recording cannot give is None.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .alignment import Aligned
from .segmentation import Cycle, Segmentation
from .uncertainty import slope_standard_error

PEAK_WINDOW = 0.98  # samples at >= 98 % of a cycle's peak indentation form its "peak"
HYSTERESIS_RANGE = (0.05, 0.95)  # fraction of full-scale force compared
HYSTERESIS_BINS = 20
MIN_BIN_SAMPLES = 3
MIN_NOISE_SAMPLES = 20
DRIFT_CYCLES = 10


@dataclass(frozen=True)
class Signals:
    """Baseline-removed signals (the paper's 'change from the initial value')."""

    t_s: np.ndarray
    output_v: np.ndarray
    force_n: np.ndarray
    indentation_m: np.ndarray
    output_baseline_v: float
    force_baseline_n: float


def baseline(aligned: Aligned, seg: Segmentation) -> Signals:
    """Subtract the median at rest before the first press (else all rest, else its start)."""
    first = seg.cycles[0].load[0]
    before = np.flatnonzero(seg.rest[:first])
    pick = before if before.size >= 10 else np.flatnonzero(seg.rest)
    if pick.size == 0:
        pick = np.array([first])
    b_out = float(np.median(aligned.output_v[pick]))
    b_force = float(np.median(aligned.force_n[pick]))
    return Signals(t_s=aligned.t_s, output_v=aligned.output_v - b_out,
                   force_n=aligned.force_n - b_force, indentation_m=aligned.indentation_m,
                   output_baseline_v=b_out, force_baseline_n=b_force)


def moving_average(x: np.ndarray, n: int) -> np.ndarray:
    """n-point moving average, 'valid' part only (length len(x) - n + 1)."""
    if n <= 1:
        return x.copy()
    c = np.cumsum(np.concatenate(([0.0], x)))
    return (c[n:] - c[:-n]) / n


def ramp_indices(cycles: Sequence[Cycle], which: str) -> np.ndarray:
    """Sample indices of the loading ('load') or unloading ('unload') ramps of cycles."""
    parts = [np.arange(*getattr(c, which)) for c in cycles]
    return np.concatenate(parts) if parts else np.zeros(0, dtype=int)


def peak_values(sig: Signals, cycle: Cycle) -> tuple[float, float]:
    """(output, force) averaged over the samples at >= 98 % of the cycle's peak indentation."""
    a, b = cycle.window
    d = sig.indentation_m[a:b]
    top = np.flatnonzero(d >= d.min() + PEAK_WINDOW * (cycle.peak_indentation_m - d.min()))
    return float(sig.output_v[a:b][top].mean()), float(sig.force_n[a:b][top].mean())


@dataclass(frozen=True)
class LinearFit:
    slope: float
    intercept: float
    r2: float
    slope_se: float | None = None  # the fit's standard error, correlated residuals counted


def sensitivity(sig: Signals, cycles: Sequence[Cycle]) -> LinearFit | None:
    """Least-squares slope of output against force over the loading ramps [V/N], with its
    standard error (``uncertainty.slope_standard_error``)."""
    idx = ramp_indices(cycles, "load")
    if idx.size < 3 or np.ptp(sig.force_n[idx]) <= 0:
        return None
    x, y = sig.force_n[idx], sig.output_v[idx]
    slope, intercept = np.polyfit(x, y, 1)
    resid = y - (slope * x + intercept)
    ss = float(np.sum((y - y.mean()) ** 2))
    r2 = 1.0 - float(np.sum(resid ** 2)) / ss if ss > 0 else 0.0
    return LinearFit(float(slope), float(intercept), r2, slope_standard_error(x, resid))


def sensitivities(sig: Signals, cycles: Sequence[Cycle]) -> list[float | None]:
    """Each cycle's own sensitivity [V/N] (None where its ramp gives no fit): their
    spread is how much the pooled slope moves from press to press."""
    fits = [sensitivity(sig, [c]) for c in cycles]
    return [f.slope if f is not None else None for f in fits]


@dataclass(frozen=True)
class Noise:
    sigma_v: float
    source: str
    samples: int
    runs_v: tuple[float, ...] = ()  # the RMS of each rest (or hold) on its own


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    m = np.concatenate(([False], mask, [False])).astype(np.int8)
    edges = np.flatnonzero(np.diff(m))
    return list(zip(edges[::2].tolist(), edges[1::2].tolist(), strict=True))


def noise(sig: Signals, seg: Segmentation, window: int) -> Noise | None:
    """Output noise: RMS of the window-point mean of the output at rest, after removing
    each rest run's mean (slow drift between rests is not noise; a fitted line would
    also remove part of the low-passed noise and bias it low); the first quarter of
    each rest is skipped so a lagging output still settling is not counted.

    Falls back to the holds at peak when the recording has no rest long enough.
    """
    def pooled(runs: list[tuple[int, int]]) -> tuple[np.ndarray, list[np.ndarray]]:
        parts = []
        for a, b in runs:
            if b - a < window + 5:
                continue
            y = sig.output_v[a:b]
            parts.append(moving_average(y - y.mean(), window))
        return (np.concatenate(parts) if parts else np.zeros(0)), parts

    settled = [(a + (b - a) // 4, b) for a, b in _runs(seg.rest)]  # skip the settling
    values, parts = pooled(settled)
    source = f"rest (unloaded, between presses), {window}-point mean, mean removed per rest"
    if values.size < MIN_NOISE_SAMPLES:
        holds = [(c.load[1], c.unload[0]) for c in seg.cycles]
        values, parts = pooled(holds)
        source = f"holds at peak indentation, {window}-point mean, mean removed per hold"
    if values.size < MIN_NOISE_SAMPLES:
        return None
    runs = tuple(float(np.sqrt(np.mean(p ** 2))) for p in parts if p.size >= MIN_NOISE_SAMPLES)
    return Noise(float(np.sqrt(np.mean(values ** 2))), source, int(values.size), runs)


@dataclass(frozen=True)
class Hysteresis:
    pct_fs: float
    force_bins_n: np.ndarray
    load_v: np.ndarray
    unload_v: np.ndarray


def _bin_means(x: np.ndarray, y: np.ndarray, edges: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    which = np.digitize(x, edges) - 1
    ok = (which >= 0) & (which < edges.size - 1)
    counts = np.bincount(which[ok], minlength=edges.size - 1)
    sums = np.bincount(which[ok], weights=y[ok], minlength=edges.size - 1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return sums / counts, counts


def hysteresis(sig: Signals, cycles: Sequence[Cycle], full_scale_n: float,
               full_scale_v: float) -> Hysteresis | None:
    """Largest gap between loading and unloading output at equal force [% of output FS]."""
    if full_scale_n <= 0 or full_scale_v <= 0:
        return None
    load, unload = ramp_indices(cycles, "load"), ramp_indices(cycles, "unload")
    edges = np.linspace(HYSTERESIS_RANGE[0] * full_scale_n, HYSTERESIS_RANGE[1] * full_scale_n,
                        HYSTERESIS_BINS + 1)
    lv, lc = _bin_means(sig.force_n[load], sig.output_v[load], edges)
    uv, uc = _bin_means(sig.force_n[unload], sig.output_v[unload], edges)
    ok = (lc >= MIN_BIN_SAMPLES) & (uc >= MIN_BIN_SAMPLES)
    if not np.any(ok):
        return None
    centres = 0.5 * (edges[1:] + edges[:-1])
    gap = float(np.max(np.abs(lv[ok] - uv[ok])))
    return Hysteresis(100.0 * gap / full_scale_v, centres[ok], lv[ok], uv[ok])


def hysteresis_per_cycle(sig: Signals, cycles: Sequence[Cycle], full_scale_n: float,
                         full_scale_v: float) -> list[float | None]:
    """Each cycle's own hysteresis [% FS] on the pooled bins (None where a cycle fills no
    bin on both ramps): the pooled figure's scatter from press to press."""
    found = [hysteresis(sig, [c], full_scale_n, full_scale_v) for c in cycles]
    return [h.pct_fs if h is not None else None for h in found]


@dataclass(frozen=True)
class Repeatability:
    peaks_v: np.ndarray
    cv_pct: float | None
    drift_pct: float | None
    drift_cycles: int


def repeatability(peaks_v: np.ndarray) -> Repeatability:
    """CV of per-cycle peak output and drift of the last k against the first k cycles."""
    n = peaks_v.size
    if n < 2 or np.mean(peaks_v) <= 0:
        return Repeatability(peaks_v, None, None, 0)
    cv = 100.0 * float(np.std(peaks_v, ddof=1) / np.mean(peaks_v))
    k = min(DRIFT_CYCLES, n // 2)
    first, last = float(np.mean(peaks_v[:k])), float(np.mean(peaks_v[-k:]))
    drift = 100.0 * (last - first) / first if first > 0 else None
    return Repeatability(peaks_v, cv, drift, k)


LAG_EDGE = (0.05, 0.35)  # part of the rising edge fitted, as fractions of the top


def _onset_time(x: np.ndarray, top: float, smooth: int, dt: float) -> float | None:
    """Time at which a straight line fitted to the foot of the rising edge (5 % to 35 %
    of top) meets the rest level: when the signal starts to rise. The edge is located
    on the moving mean, the fit uses the raw samples, so noise averages over the foot.

    Why the foot and not the middle: output and force are different static functions of
    the indentation (the FEM output is nearly linear, the force is not), so their
    mid-level crossings part by a fixed indentation, i.e. by a time ``Δd / speed`` that
    looks exactly like a lag falling with speed although nothing is late. Near the rest
    level both rise almost linearly, and that bias is a few µm of indentation."""
    if top <= 0:
        return None
    ma = moving_average(x, smooth) / top
    lo = np.flatnonzero(ma >= LAG_EDGE[0])
    hi = np.flatnonzero(ma >= LAG_EDGE[1])
    if lo.size == 0 or hi.size == 0:
        return None
    a, b = int(lo[0]) + smooth // 2, int(hi[0]) + smooth // 2 + 1
    if b - a < 3:
        return None
    t = np.arange(a, b) * dt
    slope, intercept = np.polyfit(t, x[a:b] / top, 1)
    return float(-intercept / slope) if slope > 0 else None


def _plateau(x: np.ndarray, smooth: int) -> tuple[float, int]:
    """(level, middle index) of the signal's top: median of the middle half of the
    longest run where its moving mean stays above 90 % of its maximum. A signal that never
    rises above its rest level (a module whose output falls during the press) has no top:
    (0.0, the middle), and so no onset."""
    ma = moving_average(x, smooth)
    peak = float(ma.max()) if ma.size else 0.0
    if not peak > 0:
        return 0.0, x.size // 2
    runs = _runs(ma >= 0.9 * peak)
    a, b = max(runs, key=lambda r: r[1] - r[0])
    a, b = a + smooth // 2, b + smooth // 2  # 'valid' mean index -> sample index
    quarter = (b - a) // 4
    return float(np.median(x[a + quarter:b - quarter])), (a + b) // 2


def phase_lag(sig: Signals, cycles: Sequence[Cycle], rate_hz: float) -> float | None:
    """Delay of the output behind the force on the loading edges [s]: the median over
    cycles of :func:`phase_lags`; None when no cycle gives one."""
    lags = phase_lags(sig, cycles, rate_hz)
    return float(np.median(lags)) if lags else None


def phase_lags(sig: Signals, cycles: Sequence[Cycle], rate_hz: float) -> list[float]:
    """Per-cycle delay of the output behind the force on the loading edge [s]; positive:
    output late.

    Per cycle, each signal less its level just before the press (median over a twentieth
    of the ramp, at most half the rest) is normalised by its own top (the median of the
    middle half of the run where its moving mean - over a twentieth of the ramp, at most
    half the hold - stays above 90 % of its maximum); a line fitted to the foot of its
    rising edge (5 % to 35 %, located on the moving mean) gives the time it leaves the
    rest level. The lag is
    the median over cycles of output onset minus force onset. Unlike cross-correlation
    of a slow ramp (where a delay is indistinguishable from an offset) it uses only the
    loading edge, so unloading hysteresis does not bias it, and unlike a mid-level
    crossing it is not biased by the different shapes of output and force.
    """
    dt = 1.0 / rate_hz
    lags = []
    prev_stop = 0
    for c in sorted(cycles, key=lambda c: c.window[0]):
        a, b = c.window
        ramp, hold = c.load[1] - c.load[0], c.unload[0] - c.load[1]
        smooth = max(1, ramp // 20)  # a twentieth of the ramp: the edge and the rest level
        top_smooth = max(1, min(smooth, hold // 2)) if hold >= 2 else smooth
        rest = max(1, min(smooth, (a - prev_stop) // 2))
        prev_stop = b
        times = []
        for full in (sig.force_n, sig.output_v):
            # from this press's own rest level: between presses the force still recovers
            # from the last unloading (viscoelastic), and ambient light drifts the output
            x = full[a:b] - float(np.median(full[max(0, a - rest):a + 1]))
            top, middle = _plateau(x, top_smooth)
            times.append(_onset_time(x[:middle], top, smooth, dt))
        if times[0] is not None and times[1] is not None:
            lags.append(times[1] - times[0])
    return lags


@dataclass(frozen=True)
class EstimationError:
    rmse_n: float
    max_n: float
    rmse_pct_fs: float
    max_pct_fs: float
    samples: int


def estimation_error(estimate_n: np.ndarray, force_n: np.ndarray,
                     full_scale_n: float) -> EstimationError | None:
    """RMSE and largest absolute error of a force estimate against the reference."""
    if estimate_n.size == 0 or full_scale_n <= 0:
        return None
    err = estimate_n - force_n
    rmse = float(np.sqrt(np.mean(err ** 2)))
    worst = float(np.max(np.abs(err)))
    return EstimationError(rmse, worst, 100 * rmse / full_scale_n, 100 * worst / full_scale_n,
                           int(err.size))


@dataclass(frozen=True)
class PredictionComparison:
    indentation_m: np.ndarray  # bin centres
    measured_v: np.ndarray
    predicted_v: np.ndarray
    rmse_v: float
    max_v: float
    rmse_pct_fs: float


def compare_prediction(sig: Signals, cycles: Sequence[Cycle], pred_indentation_m: np.ndarray,
                       pred_output_v: np.ndarray, full_scale_v: float,
                       bins: int = 30) -> PredictionComparison | None:
    """Loading output binned by indentation against the model's output at the bin centres."""
    idx = ramp_indices(cycles, "load")
    d = sig.indentation_m[idx]
    lo = max(float(d.min()), float(pred_indentation_m.min()))
    hi = min(float(d.max()), float(pred_indentation_m.max()))
    if idx.size == 0 or hi <= lo or full_scale_v <= 0:
        return None
    edges = np.linspace(lo, hi, bins + 1)
    means, counts = _bin_means(d, sig.output_v[idx], edges)
    ok = counts >= MIN_BIN_SAMPLES
    if not np.any(ok):
        return None
    centres = 0.5 * (edges[1:] + edges[:-1])[ok]
    predicted = np.interp(centres, pred_indentation_m, pred_output_v)
    diff = means[ok] - predicted
    rmse = float(np.sqrt(np.mean(diff ** 2)))
    return PredictionComparison(centres, means[ok], predicted, rmse,
                                float(np.max(np.abs(diff))), 100 * rmse / full_scale_v)
