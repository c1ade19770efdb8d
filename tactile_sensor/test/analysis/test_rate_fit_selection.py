"""How the rate fit denoises its record and picks the number of terms.

Each phase run is low-passed on its own (a corner stays a corner), and of the counts the
held-out speeds do not rule out, the most terms the fit resolves win: the fold that holds
the fastest speed out cannot confirm a term only that speed shows.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from tactile_sensor.analysis.rate.fit import (
    TermCount,
    _count_order,
    _resolves_every_term,
    fit_rate_calibration,
)
from tactile_sensor.analysis.rate.grid import SEGMENT_CUTOFF_HZ
from tactile_sensor.analysis.rate.grid import low_pass_runs as _low_pass_runs
from tactile_sensor.analysis.rate.grid import run_starts as _run_starts
from tactile_sensor.analysis.rate.history import zero_phase_low_pass
from tactile_sensor.analysis.synthetic import rate_press_record
from tactile_sensor.sensing.calibration import Calibration
from tactile_sensor.sensing.rate_calibration import RateCalibration, RateTerm

PERIOD_S = 1e-3


def ramp_then_hold(noise_v: float = 0.0, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(values, phase labels): 0.3 s ramp to 0.5 V, then a 1 s hold."""
    t = np.arange(0.0, 1.3, PERIOD_S)
    values = np.minimum(t / 0.3, 1.0) * 0.5
    values += np.random.default_rng(seed).normal(0.0, noise_v, t.size)
    return values, np.where(t < 0.3, 1, 2).astype(np.int8)


def test_each_run_is_low_passed_on_its_own_so_a_corner_stays_sharp():
    clean, phase = ramp_then_hold()
    per_run = _low_pass_runs(PERIOD_S, _run_starts(phase), clean)
    whole = zero_phase_low_pass(PERIOD_S, SEGMENT_CUTOFF_HZ, clean)
    assert whole is not None
    corner = slice(250, 350)
    # a line and a constant pass a maximally flat zero-phase filter unchanged, run by run;
    # across the corner the same filter rounds it by tens of mV
    assert np.max(np.abs(per_run - clean)) < 1e-3
    assert np.max(np.abs(whole[corner] - clean[corner])) > 0.02


def test_the_low_pass_removes_noise_and_leaves_short_or_unread_runs_alone():
    noisy, phase = ramp_then_hold(noise_v=0.01, seed=1)
    clean, _ = ramp_then_hold()
    smooth = _low_pass_runs(PERIOD_S, _run_starts(phase), noisy)
    assert np.std(smooth - clean) < 0.25 * np.std(noisy - clean)
    only = phase == 2  # the ramp run is never read: it stays as it was
    partly = _low_pass_runs(PERIOD_S, _run_starts(phase), noisy, only)
    assert np.array_equal(partly[phase == 1], noisy[phase == 1])
    short = np.array([0.0, 1.0, 0.0, 1.0])  # too short to filter
    assert np.array_equal(_low_pass_runs(PERIOD_S, np.array([], int), short), short)
    # columns by time: every row alike
    rows = _low_pass_runs(PERIOD_S, _run_starts(phase), np.vstack((noisy, noisy)))
    assert np.allclose(rows[0], smooth) and np.allclose(rows[1], smooth)


def curve() -> Calibration:
    return Calibration.from_curve([0.0, 0.5], [0.0, 7.0], "t")


@pytest.mark.parametrize(("terms", "resolved"), [
    ([(0.05, 0.1), (0.04, 1.5)], True),
    ([(0.05, 0.1)], True),
    ([(0.05, 0.1), (0.0005, 1.5)], False),  # a term that does nothing
    ([(0.05, 1.0), (0.04, 1.5)], False),  # two terms at nearly one time
    ([(0.05, 0.1), (0.04, 1.5), (0.01, 2.0)], False),
    ([(0.05, 0.1), (0.04, 1.5), (0.008, 5.0)], False),  # under a tenth of the sum
    ([(0.05, 0.1), (0.04, 1.5), (0.011, 5.0)], True),
])
def test_a_fit_resolves_every_term_only_with_distinct_working_terms(terms, resolved):
    cal = RateCalibration(curve(), [RateTerm(g, tau) for g, tau in terms])
    assert _resolves_every_term(cal) is resolved


def test_a_two_term_truth_gives_its_two_terms():
    """A two-term truth with holds, terms chosen: two come out, near the truth."""
    rec = rate_press_record((0.3e-3, 1e-3, 10e-3), 2.0, (0.05, 0.04), (0.1, 1.5), 1000.0, 0)
    heard: list[tuple[float, str]] = []
    fit = fit_rate_calibration(rec, "two-term", play=False,
                               progress=lambda f, what: heard.append((f, what)))
    fractions = [f for f, _ in heard]
    assert fractions == sorted(fractions) and fractions[-1] == 1.0 and len(heard) >= 10
    assert heard[0][1] == "1 term(s) without play, 0.3 mm/s held out"
    assert heard[-1][1] == "2 term(s) without play chosen"
    assert fit.terms == 2
    assert fit.calibration.tau_s == pytest.approx((0.1, 1.5), rel=0.3)
    assert fit.calibration.g == pytest.approx((0.05, 0.04), rel=0.25)
    assert math.isclose(fit.calibration.instant_gain, 1.09, rel_tol=0.03)


def counts(scores: dict[int, float]) -> dict[int, TermCount]:
    return {n: TermCount(n, {"1.0": v}, {"1.0": 1.0}, 0, {"1.0": v}) for n, v in scores.items()}


@pytest.mark.parametrize(("scores", "order"), [
    # the mock pairs: held out, one fast term more changes nothing (its fold lacks 10 mm/s)
    ({1: 0.102, 2: 0.098, 3: 0.097}, [3, 2, 1]),
    ({1: 0.096, 2: 0.102, 3: 0.100}, [3, 2, 1]),
    # more terms that do worse held out are tried last
    ({1: 0.090, 2: 0.120, 3: 0.130}, [1, 2, 3]),
    ({1: 0.130, 2: 0.090, 3: 0.105}, [2, 3, 1]),
])
def test_held_out_scores_only_rule_counts_out(scores, order):
    assert _count_order(counts(scores)) == order


def test_the_cli_shows_the_fit_progress_every_ten_percent(capsys):
    from tactile_sensor.analysis.cli import _Progress

    show = _Progress(True, "fitting rate terms: {pct:3d}% ({detail})")
    for k in range(1, 41):
        show(k / 40, f"fold {k}")
    lines = capsys.readouterr().err.splitlines()
    assert lines[0] == "fitting rate terms:   2% (fold 1)"
    assert lines[-1] == "fitting rate terms: 100% (fold 40)"
    assert len(lines) == 11  # 2 %, then each new tenth, 100 %
