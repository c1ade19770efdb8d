"""Fit a rate-aware calibration (static curve + 1–3 rate terms) from several speeds.

Model (``sensing.rate_calibration``): F = C(output) + sum_i h_i, dh_i/dt = g_i dC/dt −
h_i/tau_i. The static curve C is monotone piecewise-linear on ``knots`` outputs (a force at
the first knot plus non-negative increments); all of it and every (g_i, log tau_i) are
fitted together by bounded least squares on the in-press samples of the training speeds.

Why this way:
- Together (by variable projection, ``_fit``), not curve first: a curve fitted at one
  speed already holds that speed's rate force, and the terms would then fit the
  difference between speeds only.
- On a coarser grid (``fit_rate_hz``, 200 Hz by default, block means): a 0.1 mm/s press at
  1 kHz is 60 000 samples of nearly nothing happening; 200 Hz still gives a 10 mm/s ramp
  (0.3 s) 60 points. The times it can resolve run from ``MIN_TAU_PERIODS`` grid periods
  (25 ms at 200 Hz), or the time constant of the fit's low-pass if longer (40 ms at
  ``SEGMENT_CUTOFF_HZ``), to the longest press: a faster term cannot be told from the
  curve's instant response, a slower one from a constant offset. (Without the low-pass's
  limit a `speeds` record without holds fitted a third term, 0.15 @ 28 ms.)
- Number of terms (and play) by held-out error: leave one speed out, fit on the rest, and
  score the held-out speed as the goal scores a recording: the error low-passed at
  ``evaluation.MODEL_CUTOFF_HZ`` (the output's white noise, the same for every
  choice, would hide the differences), RMS per phase, the worst phase counting
  (``TermCount.worst_phase_n``). Held-out speeds only rule counts out: the fold that holds
  the fastest speed out cannot fit a term only that speed resolves, so a fast term scores
  no better held out even where it is true. Of the counts within ``SELECT_TOLERANCE`` of
  the best mean, the most terms whose fit on all speeds resolves every term (each g at
  least ``MIN_TERM_SHARE`` of their sum, no time on a bound but the record's fastest,
  times ``MIN_TAU_RATIO`` apart) wins; with the fewest, two of three mock pairs kept one
  ~1.5 s term and missed 20 mm/s. A score over whole presses let the holds, most of a
  press's samples, decide, and kept play out although it halved the unloading error
  (0.120 against 0.117 N whole, 0.13 against 0.115 N worst phase, on a `speeds` recording
  with holds).
- Every speed weighs the same (``speed_weights``): on the grid a 0.1 mm/s press has ~100x
  the samples of a 10 mm/s one, so unweighted the fit served the slow press, where the
  rate force is nearly nil, and fitted the fast terms to nothing (one 18 s term came out).
- Output and force are low-passed, zero phase, at ``SEGMENT_CUTOFF_HZ`` before the block
  means, each run of one phase label (a ramp, a hold, a rest) on its own
  (``low_pass_runs``), and the model's force goes through the same low-pass before it is
  compared (``_fit``). Why: the curve and the terms are regressions on the noisy output,
  and noise in a regressor biases them (errors in variables). It flattens the curve at
  both ends, and a fast term, g x the output's changes over its time, passes the noise
  on: least squares paid more for the noise it amplified on the slow presses than it
  gained on the fast ramps, and fitted no fast term even where it is true (on a simulated
  `speeds` record with the driver's noise, the true 0.05 @ 0.1 s + 0.04 @ 1.5 s cost 77.2
  against 72.6 for one 1 s term). A low-pass over the whole record would blur the
  reversals, where the fast term shows; per run, padded oddly (a ramp goes on as a ramp),
  it keeps them. Filtering the model's force as the gauge's keeps the fast transient at
  a ramp's start alike on both sides (without it 3 Hz fitted g 0.11 @ 25 ms for
  0.05 @ 0.1 s). With 20 Hz over the whole record three mock pairs fitted one ~1 s term
  and missed 20 mm/s; with 4 Hz per run they fit 0.044-0.049 @ 0.12-0.14 s and
  0.038-0.052 @ 1.4-2.3 s (the simulation: 0.05 @ 0.1 s, 0.04 @ 1.5 s).
- The curve is fitted on the output as recorded, not low-passed: its hat functions are
  taken per recorded sample, averaged per grid block and then low-passed per run like the
  force (``prepare_grid``'s blocks). The driver applies the curve to the noisy output, and
  the mean of C(output + noise) is not C(output) where the curve bends: fitted on the
  low-passed output, the curve ended flat just past the holds' mean output, the noise
  above it was clamped, and every hold of the mock's pairs read 0.03-0.09 N low (0.14-
  0.16 N with 30 mV of noise). The low-pass after the hats still keeps the noise out of
  the regression (errors in variables, above). On five mock pairs the holds' error fell
  from 0.062 to 0.043 N mean; the unloading's rose from 0.074 to 0.084 N.
- The start of each unloading ramp, until the output has fallen by ``REVERSAL_SHARE`` of
  its range, is left out: the output has a play (the bulge trails the probe by ~0.065 mm),
  so after a reversal it stands still while the force drops; no static curve or rate term
  can follow that, and those samples pulled the top of the curve down, which showed as a
  constant error in every hold.
- Play (``play``): the same play makes the relaxed force at one output differ by direction
  (loading above unloading by ~K'(d) x play, in holds too), so the curve may have two
  branches, curve ± half_gap (``sensing.rate_calibration.Play``). Both are fitted with the
  terms in the same linear solve, each sample on the branch of its press phase (loading
  and hold: loading; unloading: unloading; between presses: the last); a mild penalty on
  the half-gap's change between knots fills knots one branch never reaches (the top of
  the unloading one). The driver's direction tracker gets a band of ``BAND_SIGMAS`` x the
  noise of the output smoothed at ``TRACKER_SMOOTHING_HZ``, measured on the record. Play
  is kept only when it cuts the leave-one-speed-out score by more than
  ``PLAY_TOLERANCE``; the held-out folds run the tracker as the driver would.
"""

from __future__ import annotations

import itertools
import math
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.optimize import least_squares, lsq_linear
from scipy.signal import lfilter

from tactile_sensor.sensing.calibration import Calibration as StaticCurve
from tactile_sensor.sensing.prony import term_coefficients
from tactile_sensor.sensing.rate_calibration import (
    MAX_RATE_TERMS,
    Play,
    RateCalibration,
    RateTerm,
)

from ..calibration_fit import fit_calibration
from ..errors import RateFitError
from ..segmentation import speed_key
from .evaluation import MODEL_CUTOFF_HZ
from .grid import (
    SEGMENT_CUTOFF_HZ,
    TRACKER_SMOOTHING_HZ,
    low_pass_runs,
    low_passed,
    on_uniform_times,
    prepare_grid,
    rms,
    rmse,
    speed_weights,
    tracker_band_v,
)
from .history import rate_force_history, static_force, zero_phase_low_pass
from .record import HOLD, LOADING, OUTSIDE, UNLOADING, RateRecord

MIN_TAU_PERIODS = 5
SELECT_TOLERANCE = 0.10  # counts held out within 10 % of the best are not ruled out
MIN_TAU_RATIO = 2.0  # resolved terms' times lie at least this factor apart
MIN_TERM_SHARE = 0.1  # ... and each carries this share of the sum of g (a clean two-term
# truth fitted a third of 2 %, a two-speed record one of 8 %)
# play is kept when it cuts the held-out score by > 2 %: it costs the driver no CPU (24.6
# against 24.7 % of a core at 1 kHz), on records without play it scores 25-40 % worse
# (tests), and on the mock's `speeds` with holds it gained 5.5-37 %, once at the edge of 5 %
PLAY_TOLERANCE = 0.02
AT_BOUND = 0.01  # a fitted time within 1 % of a bound sits on it (not resolved)
NEGLIGIBLE_G = 1e-3  # a term this small does nothing; its time does not matter
START_G = 0.02
KNOT_MARGIN_SIGMAS = 3.0  # the curve reaches this many output-noise RMS past the data
FIT_TOLERANCE = 1e-6  # relative change of cost / parameters that ends a fit
GAP_SMOOTHING = 0.3  # penalty on half-gap changes between knots / mean data weight
CURVE_SMOOTHING = 1e-3  # penalty on the curve's second differences / mean data weight
ONE_SPEED = ("the rate terms cannot be fitted from one speed; record the `speeds` protocol "
             "(0.1, 1 and 10 mm/s).")


@dataclass(frozen=True)
class TermCount:
    """Leave-one-speed-out scores of one number of terms."""

    terms: int
    held_out_rmse_n: dict[str, float]  # speed key -> its RMSE held out (low-passed)
    static_rmse_n: dict[str, float]  # the same folds with a static curve fitted on the rest
    pinned_folds: int  # folds whose fit put a time on a bound (one speed alone may)
    # speed key -> the RMS of its worst phase's model error held out (the choice's score)
    worst_phase_n: dict[str, float] = field(default_factory=dict)

    @property
    def mean_rmse_n(self) -> float:
        return float(np.mean(list(self.held_out_rmse_n.values())))

    @property
    def score_n(self) -> float:
        """What choices are compared by: the mean over folds of the worst phase's model
        error (the whole-press RMSE when the record is too short to low-pass)."""
        return float(np.mean(list((self.worst_phase_n or self.held_out_rmse_n).values())))


@dataclass(frozen=True)
class RateFit:
    """The chosen calibration (fitted on every speed) and how each choice scored."""

    calibration: RateCalibration
    tau_range_s: tuple[float, float]
    counts: dict[int, TermCount]
    in_sample_rmse_n: float
    fit_rate_hz: float
    notes: list[str] = field(default_factory=list)
    other_counts: dict[int, TermCount] = field(default_factory=dict)  # the rejected choice

    @property
    def terms(self) -> int:
        return len(self.calibration.terms)

    @property
    def folds(self) -> TermCount:
        return self.counts[self.terms]

    @property
    def play(self) -> Play | None:
        return self.calibration.play

    def metadata(self) -> dict[str, Any]:
        """What the calibration file's ``fit`` records about this fit."""
        return {
            "method": "static curve and Prony rate terms by bounded least squares on each "
                      "phase run low-passed; terms: the most the fit resolves of the counts "
                      "leave-one-speed-out does not rule out",
            "terms": self.terms, "tau_range_s": list(self.tau_range_s),
            "fit_rate_hz": self.fit_rate_hz, "in_sample_rmse_n": self.in_sample_rmse_n,
            "held_out_rmse_n": {str(n): c.held_out_rmse_n for n, c in self.counts.items()},
            "held_out_worst_phase_n": {str(n): c.worst_phase_n
                                       for n, c in self.counts.items()},
            "static_held_out_rmse_n": self.folds.static_rmse_n,
            "play": self.play is not None,
            "other_play_held_out_rmse_n": {str(n): c.held_out_rmse_n
                                           for n, c in self.other_counts.items()},
        }


def resolvable_tau_range(record: RateRecord, fit_rate_hz: float) -> tuple[float, float]:
    """[lowest, highest] relaxation time [s] this record resolves on the fit grid after
    the fit's low-pass."""
    period = max(float(np.median(np.diff(record.t_s))), 1.0 / fit_rate_hz)
    return (max(MIN_TAU_PERIODS * period, 1.0 / (2.0 * math.pi * SEGMENT_CUTOFF_HZ)),
            record.longest_press_s())


FitProgress = Callable[[float, str], None]  # (fraction done, what was just fitted)


def fit_rate_calibration(record: RateRecord, source: str, terms: int | None = None,
                         tau_bounds_s: tuple[float, float] | None = None, knots: int = 16,
                         fit_rate_hz: float = 200.0, play: bool | None = None,
                         progress: FitProgress | None = None) -> RateFit:
    """The rate-aware calibration of ``record``; ``terms`` None chooses 1..3 by held-out
    error, ``play`` None with or without play likewise (False: never, today's model).
    RateFitError for one speed only or times the record cannot resolve. ``progress`` hears
    of every fit (a minute or more on a `speeds` recording)."""
    speeds = record.speeds()
    lo, hi, floor_s = _tau_range(record, speeds, terms, tau_bounds_s, knots, fit_rate_hz)
    grid, blocks_v, noise_v, loading, runs = prepare_grid(record, fit_rate_hz)
    margin_v = KNOT_MARGIN_SIGMAS * noise_v
    split = _Split(loading, tracker_band_v(record), TRACKER_SMOOTHING_HZ)
    choices = {False: None, True: split} if play is None else {play: split if play else None}
    numbers = [terms] if terms is not None else list(range(1, MAX_RATE_TERMS + 1))
    # every fold of every choice, then at most one fit on all speeds per number of terms
    step = _stepper(progress, len(choices) * len(numbers) * len(speeds) + len(numbers))
    tried: dict[bool, dict[int, TermCount]] = {}
    for key, how in choices.items():
        tried[key] = {n: _cross_validate(record, grid, blocks_v, runs, speeds, n, (lo, hi),
                                         knots, margin_v, how, step, floor_s)
                      for n in numbers}
    best_of = {key: min(c.score_n for c in counts.values())
               for key, counts in tried.items()}
    use_play = (best_of[True] < best_of[False] * (1 - PLAY_TOLERANCE) if len(tried) == 2
                else next(iter(tried)))
    counts = tried[use_play]
    how = split if use_play else None
    n, cal = _choose_count(counts, lambda n: _fit(grid, blocks_v, runs, speeds, n, (lo, hi),
                                                  knots, source, margin_v, how, floor_s),
                           step, (lo, hi))
    if progress is not None:
        progress(1.0, f"{n} term(s) {'with' if how else 'without'} play chosen")
    cal, notes = _tidy_terms(cal, floor_s)
    if counts[n].pinned_folds:
        notes.append(f"{counts[n].pinned_folds} of {len(speeds)} leave-one-speed-out fits put "
                     "a relaxation time on a bound (their training speeds alone do not "
                     "resolve it); their held-out errors are pessimistic.")
    in_press = record.mask()
    force = rate_force_history(cal, record.t_s, record.output_v)
    in_sample = float(np.sqrt(np.mean((force[in_press] - record.force_n[in_press]) ** 2)))
    return RateFit(cal, (lo, hi), counts, in_sample, fit_rate_hz, notes,
                   tried.get(not use_play, {}))


def _tau_range(record: RateRecord, speeds: list[float], terms: int | None,
               tau_bounds_s: tuple[float, float] | None, knots: int, fit_rate_hz: float
               ) -> tuple[float, float, float]:
    """(lowest, highest relaxation time to fit [s], the floor a term may sit on): what the
    record resolves, or the caller's bounds inside it; RateFitError for arguments or a
    record the fit cannot work with."""
    if len(speeds) < 2:
        raise RateFitError(ONE_SPEED)
    if terms is not None and not (isinstance(terms, int) and 1 <= terms <= MAX_RATE_TERMS):
        raise RateFitError(f"the number of rate terms must be 1 to {MAX_RATE_TERMS}, got "
                           f"{terms!r}; pass 1, 2 or 3, or none to choose by held-out error.")
    if not 2 <= knots <= 200:
        raise RateFitError(f"the static curve needs 2 to 200 knots, got {knots}; pass e.g. 16.")
    lo, hi = resolvable_tau_range(record, fit_rate_hz)
    if not hi > 2 * lo:
        raise RateFitError(f"the longest press lasts {hi:.3g} s, too short to resolve any "
                           f"relaxation time above {lo:.3g} s; record whole presses with holds.")
    if tau_bounds_s is None:
        return lo, hi, lo  # a term on the floor is kept (_fit)
    a, b = (float(v) for v in tau_bounds_s)
    if not (lo <= a < b <= hi):
        raise RateFitError(
            f"the requested relaxation times {a:.3g}..{b:.3g} s lie outside what this "
            f"recording resolves ({lo:.3g}..{hi:.3g} s: from the fit's {fit_rate_hz:g} Hz "
            f"grid and {SEGMENT_CUTOFF_HZ:g} Hz low-pass up to the longest press); request "
            "times in that range or record longer presses and holds.")
    return a, b, 0.0


def _stepper(progress: FitProgress | None, total: int) -> Callable[[str], None]:
    """Counts the fits done and tells ``progress`` the share of ``total``."""
    done = 0

    def step(what: str) -> None:
        nonlocal done
        done += 1
        if progress is not None:
            progress(min(1.0, done / total), what)
    return step


def _choose_count(counts: dict[int, TermCount],
                  fit_all: Callable[[int], tuple[RateCalibration, bool]],
                  step: Callable[[str], None], tau_range: tuple[float, float]
                  ) -> tuple[int, RateCalibration]:
    """Held-out speeds cannot confirm a term only the fastest speed resolves (the fold that
    holds that speed out lacks it), so they only rule counts out: of the counts within
    the tolerance of the best held-out error, the most terms whose fit on all speeds
    resolves every term wins, then the rest by error; never a fit with a time on a bound
    (but the fastest the record resolves: that term is at most as fast, see _fit)."""
    chosen: tuple[int, RateCalibration] | None = None
    for n in _count_order(counts):
        cal, pinned = fit_all(n)
        step(f"{n} term(s) on all speeds")
        if pinned:
            continue
        if chosen is None:
            chosen = (n, cal)
        if _resolves_every_term(cal):
            chosen = (n, cal)
            break
    if chosen is None:
        lo, hi = tau_range
        raise RateFitError(
            f"every fitted relaxation time sits on the edge of what this recording resolves "
            f"({lo:.3g}..{hi:.3g} s), so the rate terms are not determined; record the "
            "`speeds` protocol with holds (e.g. --protocol speeds:hold=2).")
    return chosen


def _tidy_terms(cal: RateCalibration, floor_s: float) -> tuple[RateCalibration, list[str]]:
    """Negligible terms dropped, and a note where the fastest term sits on the floor."""
    notes = []
    kept = [t for t in cal.terms if t.g >= NEGLIGIBLE_G] or [max(cal.terms, key=lambda t: t.g)]
    if len(kept) < len(cal.terms):
        notes.append(f"{len(cal.terms) - len(kept)} rate term(s) with g < {NEGLIGIBLE_G:g} "
                     "were dropped (they change the force by less than 0.1 %).")
        cal = RateCalibration(cal.static, kept, cal.play)
    fastest = min(cal.terms, key=lambda t: t.tau_s)
    if floor_s and math.log(fastest.tau_s / floor_s) < AT_BOUND:
        notes.append(f"the fastest term's time sits on the fastest this recording resolves "
                     f"({floor_s * 1e3:.0f} ms), so it is at most that; on ramps only its "
                     f"g x tau ({fastest.g * fastest.tau_s * 1e3:.2f} ms) shows.")
    return cal, notes


# -- internals -----------------------------------------------------------------------------

@dataclass(frozen=True)
class _Split:
    """How a fit splits the curve by direction: each grid sample's branch (True: loading)
    and the driver's tracker settings."""

    loading: np.ndarray
    band_v: float
    smoothing_hz: float


def _fold_bounds(record: RateRecord, train: list[float], tau_bounds: tuple[float, float]
                 ) -> tuple[float, float]:
    """The times a fold's training speeds resolve: up to their own longest press (a fold
    without the slow press would otherwise fit times only the slow press can show, and
    score them on it), unless that leaves no range."""
    phase = np.where(record.mask(train), record.phase, OUTSIDE).astype(np.int8)
    longest = RateRecord(record.t_s, record.output_v, record.force_n, record.speed_mm_s,
                         phase).longest_press_s()
    hi = min(tau_bounds[1], longest)
    return (tau_bounds[0], hi) if hi > 2 * tau_bounds[0] else tau_bounds


def _cross_validate(record: RateRecord, grid: RateRecord, blocks_v: np.ndarray,
                    runs: np.ndarray, speeds: list[float], n: int,
                    tau_bounds: tuple[float, float], knots: int, margin_v: float,
                    split: _Split | None = None,
                    step: Callable[[str], None] | None = None,
                    floor_s: float = 0.0) -> TermCount:
    """Each held-out speed scored on the low-passed record (whole presses) and by its worst
    phase's model error (module docstring): the output's white noise, the same for every
    choice, would otherwise swamp the differences between them."""
    held: dict[str, float] = {}
    worst: dict[str, float] = {}
    static: dict[str, float] = {}
    pinned_folds = 0
    uniform = on_uniform_times(record)
    scored = low_passed(uniform)
    period = float(uniform.t_s[1] - uniform.t_s[0])
    for out in speeds:
        train = [s for s in speeds if s != out]
        cal, pinned = _fit(grid, blocks_v, runs, train, n,
                           _fold_bounds(record, train, tau_bounds), knots, "fold", margin_v,
                           split, floor_s)
        if step is not None:
            step(f"{n} term(s) {'with' if split else 'without'} play, "
                 f"{speed_key(out)} mm/s held out")
        pinned_folds += int(pinned)
        test = scored.mask([out])
        force = rate_force_history(cal, scored.t_s, scored.output_v)
        held[speed_key(out)] = rmse(force[test], scored.force_n[test])
        error = zero_phase_low_pass(period, MODEL_CUTOFF_HZ, rate_force_history(
            cal, uniform.t_s, uniform.output_v) - uniform.force_n)
        phases = [uniform.mask([out], code) for code in (LOADING, HOLD, UNLOADING)]
        if error is not None:
            worst[speed_key(out)] = max(rms(error[m]) for m in phases if np.any(m))
        curve = _static_competitor(record, train)
        static[speed_key(out)] = rmse(
            static_force(curve.output_v, curve.force_n, scored.output_v[test]),
            scored.force_n[test])
    return TermCount(n, held, static, pinned_folds,
                     worst if len(worst) == len(held) else {})


def _static_competitor(record: RateRecord, speeds: list[float]) -> Any:
    """Today's static calibration from the same speeds: ramps pooled, one curve."""
    ramps = record.mask(speeds) & np.isin(record.phase, (LOADING, UNLOADING))
    return fit_calibration(record.output_v[ramps], record.force_n[ramps], "static")


def _count_order(counts: dict[int, TermCount]) -> list[int]:
    """The numbers of terms to try, in turn: those held out within ``SELECT_TOLERANCE`` of
    the best score, most terms first, then the rest by score."""
    best = min(c.score_n for c in counts.values())
    order = sorted((n for n, c in counts.items() if c.score_n <= best * (1 + SELECT_TOLERANCE)),
                   reverse=True)
    return order + sorted((n for n in counts if n not in order), key=lambda n: counts[n].score_n)


def _resolves_every_term(cal: RateCalibration) -> bool:
    """Every term carries a share of the rate force (g >= ``NEGLIGIBLE_G`` and at least
    ``MIN_TERM_SHARE`` of the sum) and its time stands apart from the next one's
    (``MIN_TAU_RATIO``): no term is a copy or a rest of another."""
    taus = sorted(t.tau_s for t in cal.terms)
    floor = max(NEGLIGIBLE_G, MIN_TERM_SHARE * sum(cal.g))
    return (all(t.g >= floor for t in cal.terms)
            and all(b >= MIN_TAU_RATIO * a for a, b in itertools.pairwise(taus)))


def _fit(grid: RateRecord, blocks_v: np.ndarray, runs: np.ndarray, speeds: list[float],
         n: int, tau_bounds: tuple[float, float], knots: int, source: str,
         margin_v: float = 0.0, split: _Split | None = None, floor_s: float = 0.0
         ) -> tuple[RateCalibration, bool]:
    """Least squares on ``speeds``' in-press samples of the grid; (calibration, whether a
    non-negligible term's time sits on a bound). The lower bound counts only above
    ``floor_s``, the fastest time the record resolves: a term there is a term at most that
    fast, whose g x tau is what a ramp shows (pair 5 of the mock's recordings: 0.13 @ 40 ms
    for the simulation's 0.05 @ 0.1 s, the same 5 ms). The model's force is the driver's, from
    the output as recorded (``blocks_v``: the curve's hats per sample, averaged per grid
    block), and goes through the low-pass the force went through (per phase run, starting
    at ``runs``), so both are compared alike.

    Variable projection: for given (g, tau) the force is linear in the curve's knot forces,
    F = (B + sum_i g_i L_i B) c with B the hat functions of the knots and L_i term i's
    filter, so the curve comes from a bounded linear solve (increments >= 0) inside a
    nonlinear fit of 2n numbers only; ~20x faster than fitting all together. With a
    ``split`` B has each branch's hats on its own samples (2 x knots columns)."""
    score = grid.mask(speeds)
    knot_v = _knot_outputs(grid.output_v[score], margin_v, knots)
    hats, cumulative, lower_u, penalty = _curve_basis(knot_v, blocks_v, split)
    columns = hats.shape[1]
    # columns x samples, C order: lfilter along the last axis runs ~3x faster than strided
    hat_changes = np.ascontiguousarray(
        np.vstack((np.zeros((1, columns)), np.diff(hats, axis=0))).T)
    dt = float(grid.t_s[1] - grid.t_s[0])
    root_w = np.sqrt(speed_weights(grid, speeds, score))
    measured = grid.force_n[score] * root_w
    upper_u = np.full(columns, np.inf)
    ridge = 1e-12 * max(1.0, float(np.sum(hats[score] ** 2)))
    smoothing = penalty.T @ penalty * (float(np.sum(root_w ** 2)) / knots)

    def low_pass(columns_by_time: np.ndarray) -> np.ndarray:
        return low_pass_runs(dt, runs, columns_by_time, score)[:, score].T

    hats_scored = low_pass(np.ascontiguousarray(hats.T)) * root_w[:, None]

    # a term's filtered columns depend on its time only: the Jacobian's steps in g (and in
    # the other terms' times) reuse them, which halves a fit's filtering (least recently
    # used first out; the current point's times are used on every step, so they stay)
    responses: OrderedDict[float, np.ndarray] = OrderedDict()

    def response(tau_s: float) -> np.ndarray:
        cached = responses.get(tau_s)
        if cached is not None:
            responses.move_to_end(tau_s)
            return cached
        decay, gain = term_coefficients(tau_s, dt)
        cached = low_pass(lfilter([gain], [1.0, -decay], hat_changes)) * root_w[:, None]
        responses[tau_s] = cached
        if len(responses) > 2 * n + 1:
            responses.popitem(last=False)
        return cached

    def design(p: np.ndarray) -> np.ndarray:
        out = hats_scored.copy()
        for gi, ti in zip(p[:n].tolist(), np.exp(p[n:]).tolist(), strict=True):
            out += gi * response(ti)
        return out

    def solve(p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        # the bounded solve on the knots x knots Cholesky factor of the normal equations:
        # the same minimiser as on the samples x knots design, without a tall LAPACK call
        # (10-100x slower on a loaded 2-core machine with threaded BLAS)
        a = design(p)
        gram = a.T @ a + ridge * np.eye(columns) + smoothing
        r = np.linalg.cholesky(gram).T
        z = np.linalg.solve(r.T, a.T @ measured)
        u = lsq_linear(r @ cumulative, z, bounds=(lower_u, upper_u), method="bvls").x
        return u, a @ (cumulative @ u) - measured

    best = _multi_start(lambda p: solve(p)[1], n, tau_bounds)
    u, _ = solve(best)
    return _calibration(knot_v, cumulative @ u, best, tau_bounds, split, source, floor_s)


def _knot_outputs(x: np.ndarray, margin_v: float, knots: int) -> np.ndarray:
    """The curve's knots [V] over the scored outputs ``x``. They reach ``margin_v`` beyond
    the (low-passed) outputs: the driver's noisy outputs past its ends would be clamped,
    biasing a hold at full scale low."""
    lo_x, hi_x = np.percentile(x, [0.5, 99.5])
    if not hi_x > lo_x:
        raise RateFitError("the module output does not change during the presses, so no "
                           "calibration can be fitted; check the reading topic and the sensor.")
    return np.linspace(lo_x - margin_v, hi_x + margin_v, knots)


def _curve_basis(knot_v: np.ndarray, blocks_v: np.ndarray, split: _Split | None
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The curve's part of the least squares: (hat columns per grid sample, increments ->
    knot forces, the increments' lower bounds, the smoothing penalty's rows); with a
    ``split``, each branch's hats on its own samples."""
    knots = knot_v.size
    hats = _hat_basis(knot_v, blocks_v.ravel()).reshape(*blocks_v.shape, knots).mean(axis=1)
    cumulative = np.tril(np.ones((knots, knots)))  # knot forces = f0 + running increments
    lower_u = np.concatenate(([-np.inf], np.zeros(knots - 1)))
    # curvature: knots beyond the data (the margin, the top of the unloading branch)
    # continue the curve's slope instead of staying where the bounded solve leaves them
    penalty = math.sqrt(CURVE_SMOOTHING) * np.diff(np.eye(knots), 2, axis=0)
    if split is not None:  # [loading | unloading] columns, each branch monotone
        on = split.loading[:, None]
        hats = np.hstack((hats * on, hats * ~on))
        cumulative = np.kron(np.eye(2), cumulative)
        lower_u = np.tile(lower_u, 2)
        penalty = np.vstack((np.kron(np.eye(2), penalty), math.sqrt(GAP_SMOOTHING) * np.kron(
            [[1.0, -1.0]], np.diff(np.eye(knots), axis=0))))  # and the gap's changes
    return hats, cumulative, lower_u, penalty


def _multi_start(residuals: Callable[[np.ndarray], np.ndarray], n: int,
                 tau_bounds: tuple[float, float]) -> np.ndarray:
    """(g..., log tau...) of the better of two starts: times spread evenly over the
    bounds, then shifted by half a step."""
    lo_log, hi_log = math.log(tau_bounds[0]), math.log(tau_bounds[1])
    best = None
    for offset in (0.0, 0.5):
        log_tau = [lo_log + (hi_log - lo_log) * (i + 1 + offset) / (n + 1 + offset)
                   for i in range(n)]
        result = least_squares(residuals, np.array([START_G] * n + log_tau),
                               bounds=([0.0] * n + [lo_log] * n, [2.0] * n + [hi_log] * n),
                               x_scale=[0.05] * n + [1.0] * n, method="trf",
                               ftol=FIT_TOLERANCE, xtol=FIT_TOLERANCE)
        if best is None or result.cost < best.cost:
            best = result
    assert best is not None
    return best.x


def _calibration(knot_v: np.ndarray, force_knots: np.ndarray, p: np.ndarray,
                 tau_bounds: tuple[float, float], split: _Split | None, source: str,
                 floor_s: float) -> tuple[RateCalibration, bool]:
    """The fitted numbers as a calibration (branches as curve and half-gap, terms by time)
    and whether a non-negligible term's time sits on a bound (``_fit``)."""
    knots, n = knot_v.size, p.size // 2
    lo_log, hi_log = math.log(tau_bounds[0]), math.log(tau_bounds[1])
    g, log_tau = p[:n], p[n:]
    play = None
    if split is not None:
        up = np.maximum.accumulate(force_knots[:knots])
        down = np.maximum.accumulate(force_knots[knots:])
        force_knots = 0.5 * (up + down)
        play = Play(tuple((0.5 * (up - down)).tolist()), split.band_v, split.smoothing_hz)
    order = np.argsort(log_tau)
    terms = [RateTerm(float(g[i]), float(math.exp(log_tau[i]))) for i in order]
    floor_counts = tau_bounds[0] > floor_s * (1 + AT_BOUND)
    pinned = any(t.g > NEGLIGIBLE_G and (
        (floor_counts and math.log(t.tau_s) - lo_log < AT_BOUND)
        or hi_log - math.log(t.tau_s) < AT_BOUND) for t in terms)
    curve = StaticCurve.from_curve(knot_v.tolist(),
                                   np.maximum.accumulate(force_knots).tolist(), source)
    return RateCalibration(curve, terms, play), pinned


def _hat_basis(knot_v: np.ndarray, output_v: np.ndarray) -> np.ndarray:
    """(samples, knots): linear interpolation weights, clamped beyond the ends (np.interp)."""
    eye = np.eye(knot_v.size)
    return np.column_stack([np.interp(output_v, knot_v, eye[j]) for j in range(knot_v.size)])


