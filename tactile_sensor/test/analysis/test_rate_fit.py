"""Fitting the rate-aware calibration from synthetic recordings with a known truth.

The truth: a static curve F_s = 7 N (d / 3 mm)^1.3, a module output 0.5 V (d / 3 mm)^0.9
that follows the indentation, and physics' own RateDependentForce (the mock's defaults
g = 0.05, 0.04 and tau = 0.1, 1.5 s) making the gauge force; small noise on both.
"""

from __future__ import annotations

import numpy as np
import pytest

from tactile_sensor.analysis.calibration_fit import fit_calibration
from tactile_sensor.analysis.errors import RateFitError
from tactile_sensor.analysis.rate.evaluation import phase_table, table_dict
from tactile_sensor.analysis.rate.fit import (
    TermCount,
    fit_rate_calibration,
    resolvable_tau_range,
)
from tactile_sensor.analysis.rate.history import rate_force_history
from tactile_sensor.analysis.rate.record import (
    LOADING,
    OUTSIDE,
    UNLOADING,
    RateRecord,
)
from tactile_sensor.analysis.synthetic import rate_press_record
from tactile_sensor.sensing.rate_calibration import RateCalibration

TRUE_G = (0.05, 0.04)
TRUE_TAU_S = (0.1, 1.5)
SPEEDS_M_S = (0.3e-3, 1e-3, 10e-3)  # 0.3 not 0.1 mm/s: a third of the samples, same physics


def synthetic(speeds_m_s=SPEEDS_M_S, hold_s=2.0, g=TRUE_G, tau_s=TRUE_TAU_S,
              rate_hz=1000.0, seed=0) -> RateRecord:
    return rate_press_record(speeds_m_s, hold_s, g, tau_s, rate_hz, seed)


@pytest.fixture(scope="module")
def record() -> RateRecord:
    return synthetic()


@pytest.fixture(scope="module")
def two_term_fit(record):
    return fit_rate_calibration(record, "synthetic", terms=2)


def test_recovers_the_true_terms(two_term_fit):
    """Within 25 % on g and 30 % on tau: the output noise and a 16-knot curve for a power
    law leave that much room for the fast term (0.1 s is 20 periods of the fit grid)."""
    cal = two_term_fit.calibration
    assert cal.g == pytest.approx(TRUE_G, rel=0.25)
    assert cal.tau_s == pytest.approx(TRUE_TAU_S, rel=0.3)
    assert cal.instant_gain == pytest.approx(1 + sum(TRUE_G), rel=0.03)
    # the static curve is the relaxed one, not a speed's
    for out in (0.1, 0.3, 0.45):
        truth = 7.0 * (out / 0.5) ** (1.3 / 0.9)
        assert cal.static.force(out) == pytest.approx(truth, abs=0.06)
    assert two_term_fit.in_sample_rmse_n < 0.03  # noise is 0.01 N


def test_every_held_out_speed_is_predicted_far_better_than_by_a_static_curve(two_term_fit):
    folds = two_term_fit.folds
    assert set(folds.held_out_rmse_n) == {"0.3", "1.0", "10.0"}
    for key, rmse in folds.held_out_rmse_n.items():
        assert rmse <= 0.5 * folds.static_rmse_n[key], key


@pytest.mark.parametrize("held_out", [1e-3, 10e-3])
def test_held_out_speed_halves_the_static_error_in_every_phase(record, held_out):
    """Fit on the other speeds, rate-aware against a static curve fitted on the same
    speeds' ramps (today's calibration), scored on the held-out speed per phase."""
    train = [s * 1e3 for s in SPEEDS_M_S if s != held_out]
    keep = ~np.isin(record.speed_mm_s, [held_out * 1e3])
    train_record = RateRecord(record.t_s, record.output_v, record.force_n,
                              np.where(keep, record.speed_mm_s, np.nan),
                              np.where(keep, record.phase, OUTSIDE).astype(np.int8))
    assert train_record.speeds() == train
    fit = fit_rate_calibration(train_record, "train", terms=2)
    ramps = record.mask(train) & np.isin(record.phase, (LOADING, UNLOADING))
    static = fit_calibration(record.output_v[ramps], record.force_n[ramps], "static")
    rows = [r for r in phase_table(record, static, fit.calibration)
            if r.speed_mm_s == held_out * 1e3]
    assert {r.phase for r in rows} == {"loading", "hold", "unloading"}
    for r in rows:
        assert r.rate_rmse_n <= 0.5 * r.static_rmse_n, r


def test_number_of_terms_is_chosen_by_held_out_error():
    """A one-term truth gives one term: fits with more do not resolve them (a term with
    g ~ 0 or two terms at one time), though held out they score within the tolerance."""
    rec = synthetic(speeds_m_s=(1e-3, 10e-3), hold_s=1.0, g=(0.08,), tau_s=(0.5,))
    fit = fit_rate_calibration(rec, "one-term")
    assert set(fit.counts) == {1, 2, 3}
    assert fit.terms == 1
    assert fit.calibration.g == pytest.approx((0.08,), rel=0.15)
    assert fit.calibration.tau_s == pytest.approx((0.5,), rel=0.2)
    meta = fit.metadata()
    assert meta["terms"] == 1 and set(meta["held_out_rmse_n"]) == {"1", "2", "3"}


def test_choices_are_scored_by_their_worst_phase_held_out(record, two_term_fit):
    """The score is the goal's own measure: per held-out speed, the low-passed error of its
    worst phase, as ``phase_table`` gives it for a fit on the other speeds."""
    folds = two_term_fit.folds
    assert set(folds.worst_phase_n) == set(folds.held_out_rmse_n)
    assert folds.score_n == pytest.approx(np.mean(list(folds.worst_phase_n.values())))
    held_out = 10e-3
    keep = ~np.isin(record.speed_mm_s, [held_out * 1e3])
    train = fit_rate_calibration(RateRecord(
        record.t_s, record.output_v, record.force_n, np.where(keep, record.speed_mm_s, np.nan),
        np.where(keep, record.phase, OUTSIDE).astype(np.int8)), "train", terms=2)
    ramps = record.mask([0.3, 1.0]) & np.isin(record.phase, (LOADING, UNLOADING))
    static = fit_calibration(record.output_v[ramps], record.force_n[ramps], "static")
    errors = [r.rate_model_rmse_n for r in phase_table(record, static, train.calibration)
              if r.speed_mm_s == held_out * 1e3]
    assert len(errors) == 3 and max(errors) > 1.5 * min(errors)  # the phases differ
    assert folds.worst_phase_n["10.0"] == pytest.approx(max(errors), rel=0.05)


def test_a_count_without_phase_scores_falls_back_to_whole_presses():
    count = TermCount(1, {"1.0": 0.1, "10.0": 0.3}, {}, 0)
    assert count.score_n == pytest.approx(0.2)
    assert TermCount(1, {"1.0": 0.1, "10.0": 0.3}, {}, 0,
                     {"1.0": 0.2, "10.0": 0.4}).score_n == pytest.approx(0.3)


def test_phase_table_reports_every_speed_and_phase(record, two_term_fit):
    static = two_term_fit.calibration.static
    table = table_dict(phase_table(record, static, two_term_fit.calibration))
    assert set(table) == {"0.3", "1.0", "10.0"}
    fast = table["10.0"]
    assert set(fast) == {"loading", "hold", "unloading"}
    # the relaxed curve alone misses the fast press's rate force most while loading
    assert fast["loading"]["static_rmse_n"] > 3 * fast["loading"]["rate_rmse_n"]


def test_batch_history_equals_the_drivers_estimator(two_term_fit, record):
    cal: RateCalibration = two_term_fit.calibration
    part = slice(0, 3000)
    est = cal.estimator()
    stream = [est.update(float(o), float(t))[0]
              for o, t in zip(record.output_v[part], record.t_s[part], strict=True)]
    batch = rate_force_history(cal, record.t_s[part], record.output_v[part])
    assert np.allclose(stream, batch, rtol=1e-9, atol=1e-9)


# -- errors a user can cause ----------------------------------------------------------------

def test_one_speed_cannot_give_rate_terms():
    rec = synthetic(speeds_m_s=(1e-3,))
    with pytest.raises(RateFitError, match="cannot be fitted from one speed; record the "
                                           "`speeds` protocol"):
        fit_rate_calibration(rec, "x")


@pytest.mark.parametrize("bounds", [(0.001, 1.0), (0.1, 500.0), (2.0, 1.0)])
def test_requested_times_outside_what_the_recording_resolves(record, bounds):
    lo, hi = resolvable_tau_range(record, 200.0)
    # the fit's 4 Hz low-pass resolves no faster time than its own, 1 / (2 pi 4 Hz)
    assert lo == pytest.approx(0.0398, rel=0.01) and hi == pytest.approx(22.0, rel=0.01)
    with pytest.raises(RateFitError, match="outside what this recording resolves"):
        fit_rate_calibration(record, "x", tau_bounds_s=bounds)


def test_times_pinned_to_a_bound_are_refused(record):
    """Bounds that exclude the truth force every fit onto a bound: not resolved."""
    with pytest.raises(RateFitError, match="sits on the edge of what this recording"):
        fit_rate_calibration(record, "x", terms=1, tau_bounds_s=(5.0, 20.0))


def test_a_term_faster_than_the_record_resolves_is_kept_at_the_fastest_it_resolves():
    """A true 20 ms term lies below the 40 ms the fit resolves: it lands on that floor and
    is kept (once refused, the two-term fit could not be had at all), said in a note. On
    ramps such a term shows only as g x tau, which the fit recovers."""
    rec = synthetic(tau_s=(0.02, TRUE_TAU_S[1]))
    floor, _ = resolvable_tau_range(rec, 200.0)
    fit = fit_rate_calibration(rec, "x", terms=2)
    fast, slow = fit.calibration.terms
    assert fast.tau_s == pytest.approx(floor, rel=0.02)
    assert fast.g * fast.tau_s == pytest.approx(TRUE_G[0] * 0.02, rel=0.5)
    assert slow.tau_s == pytest.approx(TRUE_TAU_S[1], rel=0.3)
    assert any("so it is at most that" in note for note in fit.notes), fit.notes


@pytest.mark.parametrize(("kwargs", "match"), [
    ({"terms": 4}, "1 to 3, got 4"),
    ({"terms": 0}, "1 to 3, got 0"),
    ({"knots": 1}, "2 to 200 knots"),
])
def test_bad_options_are_refused(record, kwargs, match):
    with pytest.raises(RateFitError, match=match):
        fit_rate_calibration(record, "x", **kwargs)


def test_a_record_with_mismatched_arrays_is_refused():
    from tactile_sensor.analysis.errors import SegmentError

    t = np.arange(5.0)
    with pytest.raises(SegmentError, match="differ in length"):
        RateRecord(t, t, t[:4], t, t.astype(np.int8))
