"""How sure each figure is: intervals over cycles, a fit's standard error, propagation.

Why: a figure from one press is a single draw of the sensor's noise. The lag of one
cycle at 1 mm/s scattered 0.04-0.11 s between runs, so a number without its spread
claims more than was measured. Each per-cycle figure carries the half-width of a 95 %
interval from Student's t over its cycles; one cycle gives none (``ONE_CYCLE``).
Formulas: docs/analysis-metrics.md, "Uncertainties".
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import stats

#: What a figure says when it has one cycle and so no spread to estimate.
ONE_CYCLE = "one cycle: no estimate"
#: The standard error of a median of n normal values is about this times sd / sqrt(n).
MEDIAN_EFFICIENCY = 1.2533
CONFIDENCE = 0.95


def t95(dof: int) -> float:
    """Two-sided 95 % quantile of Student's t with ``dof`` degrees of freedom."""
    return float(stats.t.ppf(0.5 + CONFIDENCE / 2, dof))


@dataclass(frozen=True)
class Spread:
    """Per-cycle values of one figure and how well their centre is known."""

    values: tuple[float, ...]
    centre: float | None  # mean or median of the values
    sd: float | None  # sample standard deviation (ddof 1)
    se: float | None  # standard error of the centre
    ci95: float | None  # half-width of the 95 % interval of the centre

    @property
    def cycles(self) -> int:
        return len(self.values)


def spread(values: Sequence[float | None], statistic: str = "mean") -> Spread:
    """The spread of per-cycle values (None and non-finite dropped) about their mean or
    median; fewer than two values give no sd, se or interval."""
    if statistic not in ("mean", "median"):
        raise ValueError(f"statistic must be 'mean' or 'median', not {statistic!r}")
    kept = tuple(float(v) for v in values if v is not None and math.isfinite(v))
    n = len(kept)
    if n == 0:
        return Spread(kept, None, None, None, None)
    x = np.asarray(kept)
    centre = float(np.mean(x) if statistic == "mean" else np.median(x))
    if n < 2:
        return Spread(kept, centre, None, None, None)
    sd = float(np.std(x, ddof=1))
    se = sd / math.sqrt(n) * (MEDIAN_EFFICIENCY if statistic == "median" else 1.0)
    return Spread(kept, centre, sd, se, t95(n - 1) * se)


def slope_standard_error(x: np.ndarray, residuals: np.ndarray) -> float | None:
    """Standard error of a least-squares slope whose residuals are correlated in time.

    Why the correction: at 1 kHz neighbouring residuals are nearly equal (they are the
    curve's bend and the filtered noise, not independent draws), and the textbook
    ``s / sqrt(Sxx)`` would then shrink with the sample rate. With the residuals' lag-1
    autocorrelation r the variance grows by (1 + r) / (1 - r) (an AR(1) residual on a
    ramp), which is what it would be with the fewer independent samples really there."""
    n = x.size
    if n < 3 or residuals.size != n:
        return None
    sxx = float(np.sum((x - x.mean()) ** 2))
    if sxx <= 0:
        return None
    s2 = float(np.sum(residuals ** 2)) / (n - 2)
    e = residuals - residuals.mean()
    denom = float(np.sum(e ** 2))
    r = float(np.sum(e[1:] * e[:-1]) / denom) if denom > 0 else 0.0
    r = min(max(r, 0.0), 0.999)  # negative r would shrink it: keep the textbook value
    return math.sqrt(s2 / sxx * (1 + r) / (1 - r))


def cv_interval(cv_pct: float | None, cycles: int) -> tuple[float, float] | None:
    """95 % interval of a coefficient of variation [%] from ``cycles`` values: the
    chi-square interval of their standard deviation (normal values) scaled by the same
    mean; None below two cycles."""
    if cv_pct is None or cycles < 2 or not math.isfinite(cv_pct):
        return None
    dof = cycles - 1
    lo = cv_pct * math.sqrt(dof / stats.chi2.ppf(0.5 + CONFIDENCE / 2, dof))
    hi = cv_pct * math.sqrt(dof / stats.chi2.ppf(0.5 - CONFIDENCE / 2, dof))
    return float(lo), float(hi)


def drift_ci95(peaks_v: np.ndarray, k: int) -> float | None:
    """Half-width of the 95 % interval of the drift [%] (last k against the first k peak
    outputs): two means of k cycles differ with standard error sd sqrt(2 / k), sd over all
    the cycles (a real drift only widens it); None below two cycles or k 0."""
    n = peaks_v.size
    if n < 2 or k < 1:
        return None
    first = float(np.mean(peaks_v[:k]))
    if first <= 0:
        return None
    se = float(np.std(peaks_v, ddof=1)) * math.sqrt(2.0 / k)
    return 100.0 * t95(n - 1) * se / first


def relative_se(value: float | None, se: float | None) -> float | None:
    """se / |value|, None when either is missing or the value is 0."""
    if value is None or se is None or value == 0:
        return None
    return abs(se / value)


def quotient_se(value: float, *relative: float | None) -> float | None:
    """Standard error of a product or quotient of independent factors, from their
    relative errors (first order); None when any is unknown."""
    if any(r is None for r in relative):
        return None
    return abs(value) * math.sqrt(sum(float(r) ** 2 for r in relative))  # type: ignore[arg-type]


def decibel_se(*relative: float | None) -> float | None:
    """Standard error [dB] of 20 log10 of a quotient, from its factors' relative errors."""
    if any(r is None for r in relative):
        return None
    return 20.0 / math.log(10.0) * math.sqrt(sum(float(r) ** 2 for r in relative))  # type: ignore[arg-type]


def normal_ci95(se: float | None) -> float | None:
    """Half-width of a 95 % interval from a propagated standard error (normal)."""
    return None if se is None else float(stats.norm.ppf(0.5 + CONFIDENCE / 2)) * se
