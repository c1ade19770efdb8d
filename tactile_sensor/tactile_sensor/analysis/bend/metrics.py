"""Angle error, hysteresis and lag of a finger's recording, phase by phase (pure numpy).

A recording of the bend configuration holds the true joint angle and fingertip force (the
mock's ground truth) and the driver's estimate, on their own stamps. The truth is
interpolated to the estimate's stamps, and the run is cut into bends:

- a **bend** runs from one rest (the last minimum of the true angle before it rises) to the
  next (the first minimum after it falls), through one peak
  above half the run's largest angle; its rate is 1 / (2 x the time above half its own
  peak), exact for the protocols' raised cosines;
- a bend is **with contact** where the true tip force exceeds ``CONTACT_N`` in it;
- a **phase** is the bends of one rate, with or without contact.

Per bend: the RMSE of estimate minus truth; the **lag**, the delay that best lines the
estimate up with the truth (least squares over +-``MAX_LAG_S``, to the millisecond, with a
parabola through the best three); the **hysteresis per bend (noise included)**, the largest
difference between the estimate on the way up and on the way down at the same true angle,
in % of the bend's true range (the branches' means in ``HYSTERESIS_LEVELS`` bins of the
true angle over 5-95 % of it). Per phase: the mean over its bends with the standard error
of that mean (``sem``: the sample standard deviation / sqrt(bends); none for one bend), and
the RMSE over all its samples. Samples the driver read as NaN are counted, not scored.

A phase's **hysteresis** is that of its averaged cycle (``group_hysteresis``): the
branches' bin means pooled over all its bends, with a bootstrap standard error and the
**noise floor**, the figure noise alone would give. One bend's bins near the peak hold a
few tens of ms of samples, so the max over its 19 noisy gaps reads high whatever the
hysteresis; the per-bend figure is kept beside it as ``hysteresis_pct_per_bend``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: A bend is with contact where the true tip force exceeds this [N].
CONTACT_N = 0.05
#: The lag is looked for within this much either way [s].
MAX_LAG_S = 0.2
LAG_STEP_S = 0.001
HYSTERESIS_LEVELS = 19


@dataclass(frozen=True)
class Bend:
    start: int  # sample indices [start, end)
    end: int
    frequency_hz: float
    contact: bool
    peak_rad: float
    rmse_rad: float
    lag_s: float
    hysteresis_pct: float
    invalid: int  # samples the driver read as NaN
    max_tip_force_n: float


def cut_bends(t: np.ndarray, truth: np.ndarray) -> list[tuple[int, int, float]]:
    """(start, end, rate [Hz]) of every whole bend of the true angle."""
    if truth.size < 3 or not np.isfinite(truth).all():
        return []
    half = 0.5 * float(truth.max())
    if half <= 0:
        return []
    above = truth > half
    ups = np.flatnonzero(~above[:-1] & above[1:]) + 1
    downs = np.flatnonzero(above[:-1] & ~above[1:]) + 1
    out = []
    for u in ups:
        later = downs[downs > u]
        if later.size == 0:
            break
        d = int(later[0])
        prev_down = downs[downs < u]
        lo = int(prev_down[-1]) if prev_down.size else 0
        next_up = ups[ups > d]
        hi = int(next_up[0]) if next_up.size else truth.size
        before = truth[lo:u][::-1]  # the rest's last sample: a bend, not the rest before it
        start = u - 1 - int(np.argmin(before))
        end = d + int(np.argmin(truth[d:hi])) + 1
        own_half = 0.5 * float(truth[start:end].max())
        width = np.flatnonzero(truth[start:end] > own_half)
        if width.size < 2 or end - start < 10:
            continue
        duration = float(t[start + width[-1]] - t[start + width[0]])
        if duration <= 0:
            continue
        out.append((start, end, 1.0 / (2.0 * duration)))
    return out


def best_lag(t: np.ndarray, truth: np.ndarray, estimate: np.ndarray) -> float:
    """The delay [s] of ``estimate`` behind ``truth`` that fits them best (NaN: none)."""
    ok = np.isfinite(estimate)
    if ok.sum() < 10:
        return math.nan
    lags = np.arange(-MAX_LAG_S, MAX_LAG_S + LAG_STEP_S / 2, LAG_STEP_S)
    te, ee = t[ok], estimate[ok]
    costs = np.array([np.mean((np.interp(te - lag, t, truth) - ee) ** 2) for lag in lags])
    k = int(np.argmin(costs))
    if 0 < k < lags.size - 1:  # a parabola through the best three
        c0, c1, c2 = costs[k - 1:k + 2]
        denom = c0 - 2 * c1 + c2
        if denom > 0:
            return float(lags[k] + 0.5 * LAG_STEP_S * (c0 - c2) / denom)
    return float(lags[k])


def _branch_bins(truth: np.ndarray, estimate: np.ndarray,
                 edges: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """(sums, counts), each (2, bins): the estimate's sum and number of finite samples per
    bin of the true angle on the way up (row 0, to the peak) and down (row 1, from it);
    None for a bend without both ways."""
    k = int(np.argmax(truth)) if truth.size else 0
    if k < 2 or truth.size - k < 2:
        return None
    bins = edges.size - 1
    sums, counts = np.zeros((2, bins)), np.zeros((2, bins))
    for row, (a, e) in enumerate(((truth[:k + 1], estimate[:k + 1]),
                                  (truth[k:], estimate[k:]))):
        ok = np.isfinite(e) & np.isfinite(a)
        which = np.digitize(a[ok], edges) - 1
        inside = (which >= 0) & (which < bins)
        sums[row] = np.bincount(which[inside], e[ok][inside], bins)
        counts[row] = np.bincount(which[inside], None, bins)
    return sums, counts


def _largest_gap(sums: np.ndarray, counts: np.ndarray) -> float:
    """max over bins of |up - down| of the branches' means (NaN: no bin holds both)."""
    with np.errstate(invalid="ignore", divide="ignore"):
        means = sums / counts
    gap = np.abs(means[0] - means[1])
    return float(np.nanmax(gap)) if np.isfinite(gap).any() else math.nan


def hysteresis_pct(truth: np.ndarray, estimate: np.ndarray) -> float:
    """Largest |up - down| of the estimate at equal true angle, % of the true range: the
    branches' mean estimates in ``HYSTERESIS_LEVELS`` bins of the true angle over 5-95 % of
    its range. One bend's bins hold few samples near the peak, so its figure includes the
    output's noise (a max over noisy gaps); ``group_hysteresis`` averages it out."""
    if truth.size == 0:
        return math.nan
    lo, hi = float(truth.min()), float(truth.max())
    span = hi - lo
    if not span > 0:
        return math.nan
    binned = _branch_bins(truth, estimate, lo + span * np.linspace(0.05, 0.95,
                                                                  HYSTERESIS_LEVELS + 1))
    return math.nan if binned is None else 100.0 * _largest_gap(*binned) / span


@dataclass(frozen=True)
class GroupHysteresis:
    """The hysteresis of a group of bends' averaged cycle, % of their common range."""

    pct: float  # the largest |up - down| of the branches' means pooled over the bends
    sem_pct: float  # its standard error: bootstrap over bends (NaN below two bends)
    noise_floor_pct: float  # what noise alone gives: the same max with no up/down difference
    lo_rad: float  # the common range: the highest of the bends' minima ...
    hi_rad: float  # ... to the lowest of their peaks
    bends: int  # bends that have both ways


#: Draws of the bootstrap and of the noise floor; fixed seed, so a figure is reproducible.
GROUP_DRAWS = 200
GROUP_SEED = 20260


def group_hysteresis(pieces: list[tuple[np.ndarray, np.ndarray]],
                     draws: int = GROUP_DRAWS, seed: int = GROUP_SEED) -> GroupHysteresis:
    """The hysteresis of the bends' averaged cycle, its uncertainty and its noise floor.

    ``pieces`` are the bends' (true angle, estimate). The bins (``HYSTERESIS_LEVELS`` over
    5-95 %) span the range every bend covers, from the highest of the bends' minima to the
    lowest of their peaks, so each bin is fed by every bend. Each branch's mean per bin is
    pooled over all samples of all bends (sum and count), and the figure is the largest
    |up - down| over the bins in % of that range: near 90 deg one bend's bin holds ~30 ms of
    noisy samples, the group's all of them, so the noise's upward bias of a max shrinks.

    - ``sem_pct``: the standard deviation of the figure over ``draws`` resamplings of the
      bends with replacement.
    - ``noise_floor_pct``: the mean of the figure when every bend's up - down difference per
      bin, less the group's mean difference (so a real hysteresis is not counted as noise),
      has its sign flipped at random (the branches swapped within the bend), scaled by
      sqrt(n / (n - 1)) for the removed mean. A measured figure near it is noise; one well
      above it is hysteresis.
    Bad input (no bend with both ways, nothing finite) gives NaN, never an error.
    """
    nan = GroupHysteresis(math.nan, math.nan, math.nan, math.nan, math.nan, 0)
    kept = [(np.asarray(a, float), np.asarray(e, float)) for a, e in pieces if len(a) >= 3]
    kept = [(a, e) for a, e in kept if np.isfinite(a).all()]
    if not kept:
        return nan
    lo = max(float(a.min()) for a, _ in kept)
    hi = min(float(a.max()) for a, _ in kept)
    span = hi - lo
    if not span > 0:
        return nan
    edges = lo + span * np.linspace(0.05, 0.95, HYSTERESIS_LEVELS + 1)
    binned = [b for b in (_branch_bins(a, e, edges) for a, e in kept) if b is not None]
    if not binned:
        return nan
    sums = np.stack([s for s, _ in binned])  # (bends, 2, bins)
    counts = np.stack([c for _, c in binned])
    n = len(binned)
    pct = 100.0 * _largest_gap(sums.sum(0), counts.sum(0)) / span
    if n < 2 or not math.isfinite(pct):
        return GroupHysteresis(pct, math.nan, math.nan, lo, hi, n)
    rng = np.random.default_rng(seed)
    picks = rng.integers(0, n, (draws, n))
    boot = np.array([_largest_gap(sums[i].sum(0), counts[i].sum(0)) for i in picks])
    boot = boot[np.isfinite(boot)]
    sem = float(100.0 * boot.std(ddof=1) / span) if boot.size > 1 else math.nan
    with np.errstate(invalid="ignore", divide="ignore"):
        per_bend = sums / counts
    diff = per_bend[:, 0] - per_bend[:, 1]  # (bends, bins)
    have = np.isfinite(diff)
    k = have.sum(0)
    usable = k >= 2
    floor = math.nan
    if usable.any():
        filled = np.where(have, diff, 0.0)
        mean = filled.sum(0) / np.maximum(k, 1)
        centred = np.where(have, filled - mean, 0.0)
        scale = np.sqrt(k[usable] / (k[usable] - 1.0)) / k[usable]
        signs = rng.choice((-1.0, 1.0), (draws, n))
        gaps = np.abs(signs @ centred[:, usable]) * scale  # (draws, usable bins)
        floor = float(100.0 * gaps.max(1).mean() / span)
    return GroupHysteresis(pct, sem, floor, lo, hi, n)


def score_bends(t: np.ndarray, truth: np.ndarray, estimate: np.ndarray,
                tip_force: np.ndarray) -> list[Bend]:
    out = []
    for start, end, f in cut_bends(t, truth):
        sl = slice(start, end)
        a, e = truth[sl], estimate[sl]
        ok = np.isfinite(e)
        rmse = float(np.sqrt(np.mean((e[ok] - a[ok]) ** 2))) if ok.any() else math.nan
        force = float(np.nanmax(tip_force[sl])) if tip_force[sl].size else 0.0
        out.append(Bend(start, end, f, force > CONTACT_N, float(a.max()), rmse,
                        best_lag(t[sl], a, e), hysteresis_pct(a, e), int((~ok).sum()),
                        force))
    return out


def _mean_sem(values: list[float]) -> dict[str, float | None]:
    v = np.array([x for x in values if x == x], float)
    if v.size == 0:
        return {"mean": None, "sem": None}
    sem = float(v.std(ddof=1) / math.sqrt(v.size)) if v.size > 1 else None
    return {"mean": float(v.mean()), "sem": sem}


def _none(x: float) -> float | None:
    return x if math.isfinite(x) else None


def _group_entry(g: GroupHysteresis) -> dict[str, float | int | list | None]:
    """metrics.json's group hysteresis: ``mean`` and ``sem`` keep the keys of the earlier
    per-bend mean, so a reader of ``hysteresis_pct["mean"]`` gets the group's figure."""
    span = [_none(math.degrees(g.lo_rad)), _none(math.degrees(g.hi_rad))]
    return {"mean": _none(g.pct), "sem": _none(g.sem_pct),
            "noise_floor": _none(g.noise_floor_pct), "range_deg": span, "bends": g.bends}


def rate_label(frequency_hz: float) -> float:
    """A bend's rate rounded to two significant digits: the phase it belongs to."""
    return float(f"{frequency_hz:.2g}")


def phases(t: np.ndarray, truth: np.ndarray, estimate: np.ndarray, tip_force: np.ndarray,
           force_estimate: np.ndarray | None = None) -> list[dict]:
    """Every phase (rate, contact) with its bends' metrics: means with their standard
    errors, and the RMSE over all its samples; angles in degrees, lag in s."""
    bends = score_bends(t, truth, estimate, tip_force)
    groups: dict[tuple[float, bool], list[Bend]] = {}
    for b in bends:
        groups.setdefault((rate_label(b.frequency_hz), b.contact), []).append(b)
    out = []
    for (rate, contact), members in sorted(groups.items()):
        idx = np.concatenate([np.arange(b.start, b.end) for b in members])
        err = estimate[idx] - truth[idx]
        ok = np.isfinite(err)
        phase = {
            "rate_hz": rate, "contact": contact, "bends": len(members),
            "peak_deg": math.degrees(max(b.peak_rad for b in members)),
            "max_tip_force_n": max(b.max_tip_force_n for b in members),
            "rmse_deg": math.degrees(float(np.sqrt(np.mean(err[ok] ** 2)))) if ok.any()
            else None,
            "rmse_deg_per_bend": {k: None if v is None else math.degrees(v)
                                  for k, v in _mean_sem([b.rmse_rad for b in members]).items()},
            "lag_s": _mean_sem([b.lag_s for b in members]),
            "hysteresis_pct": _group_entry(group_hysteresis(
                [(truth[b.start:b.end], estimate[b.start:b.end]) for b in members])),
            "hysteresis_pct_per_bend": _mean_sem([b.hysteresis_pct for b in members]),
            "nan_samples": int((~ok).sum()), "samples": int(idx.size),
        }
        if force_estimate is not None:
            fe = force_estimate[idx] - tip_force[idx]
            okf = np.isfinite(fe)
            phase["tip_force_rmse_n"] = float(np.sqrt(np.mean(fe[okf] ** 2))) if okf.any() \
                else None
        out.append(phase)
    return out
