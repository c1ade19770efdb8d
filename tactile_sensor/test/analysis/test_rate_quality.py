"""What makes the rate fit recover the terms on the mock's data, and the model-error measure.

The mock's output is noisy (13 mV), has a play (the bulge trails the probe on loading) and
the `speeds` protocol spends ~100x longer at 0.1 mm/s than at 10 mm/s; the fit weighs
speeds alike, low-passes before its grid and leaves the play after a reversal out.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tactile_sensor.analysis.rate.evaluation import (
    GOAL_RATIO,
    GOAL_SHARE_FS,
    PhaseError,
    phase_table,
    table_dict,
)
from tactile_sensor.analysis.rate.fit import fit_rate_calibration
from tactile_sensor.analysis.rate.grid import REVERSAL_SHARE
from tactile_sensor.analysis.rate.grid import speed_weights as _speed_weights
from tactile_sensor.analysis.rate.grid import without_reversals as _without_reversals
from tactile_sensor.analysis.rate.history import rate_force_history, zero_phase_low_pass
from tactile_sensor.analysis.rate.record import HOLD, LOADING, OUTSIDE, UNLOADING, RateRecord
from tactile_sensor.analysis.synthetic import TRUE_PRONY_G as TRUE_G
from tactile_sensor.analysis.synthetic import TRUE_PRONY_TAU_S as TRUE_TAU_S
from tactile_sensor.analysis.synthetic import rate_press_record
from tactile_sensor.sensing.calibration import Calibration
from tactile_sensor.sensing.rate_calibration import RateCalibration, RateTerm

PLAY_M = 6.5e-5


def mock_like(speeds_m_s=(0.3e-3, 1e-3, 10e-3), hold_s=0.0, noise_v=0.01, play_m=PLAY_M,
              seed=1) -> RateRecord:
    """Like the mock: output through a play and with noise, force with the true terms."""
    return rate_press_record(speeds_m_s, hold_s, TRUE_G, TRUE_TAU_S, seed=seed,
                             output_noise_v=noise_v, force_noise_n=0.0, play_m=play_m)


@pytest.fixture(scope="module")
def noisy_fit():
    """Today's model (no play compensation) on the mock-like record."""
    return fit_rate_calibration(mock_like(), "mock-like", terms=1, play=False)


def test_one_term_lands_between_the_true_ones_from_a_noisy_record_with_play(noisy_fit):
    """Before: g 0.07 and tau 18 s on the mock's `speeds` (the play read as a slow
    relaxation, the slow press outweighing the fast one). Without holds and with 10 mV of
    noise, and without play compensation, one term is what the data resolve: its step
    gain is the truth's 1 + sum g and its time lies between the true ones."""
    cal = noisy_fit.calibration
    assert cal.instant_gain == pytest.approx(1 + sum(TRUE_G), rel=0.03)
    assert TRUE_TAU_S[0] <= cal.tau_s[0] <= TRUE_TAU_S[1]


def test_with_play_compensated_the_held_out_error_halves_without_holds():
    """The same record, play and terms chosen by held-out error: once the play is a
    direction-aware curve rather than a rate term, the held-out error halves (measured:
    0.068 against 0.143 N). Without holds the fast term is not resolved since the fit
    low-passes each phase run on its own (measured: its time goes to the 40 ms bound)."""
    fit = fit_rate_calibration(mock_like(), "mock-like")
    assert fit.calibration.play is not None
    assert fit.folds.mean_rmse_n < 0.5 * min(c.mean_rmse_n for c in fit.other_counts.values())


def test_with_holds_play_and_both_true_terms_are_resolved():
    """The protocol the demo records (`speeds` with holds): play and two terms, the fast one
    near the truth's 0.1 s and the slow one at its 1.5 s (measured: 0.030 @ 0.146 s and
    0.039 @ 1.54 s for 0.05 @ 0.1 s and 0.04 @ 1.5 s; with 20 Hz over the whole record the
    fit kept one term between them)."""
    fit = fit_rate_calibration(mock_like(hold_s=2.0), "mock-like")
    cal = fit.calibration
    assert cal.play is not None and fit.terms == 2
    assert 0.05 <= cal.tau_s[0] <= 0.25
    assert cal.tau_s[1] == pytest.approx(TRUE_TAU_S[1], rel=0.3)
    assert cal.g[1] == pytest.approx(TRUE_G[1], rel=0.3)
    assert cal.g[0] >= 0.5 * TRUE_G[0]
    assert cal.instant_gain == pytest.approx(1 + sum(TRUE_G), rel=0.03)


def test_the_fit_helps_on_held_out_speeds_with_holds(noisy_fit):
    """Scored on other speeds with holds, after the low-pass: the rate-aware model error is
    below the static curve's in every phase of both held-out speeds."""
    check = mock_like(speeds_m_s=(3e-3, 20e-3), hold_s=2.0, seed=2)
    rows = phase_table(check, noisy_fit.calibration.static, noisy_fit.calibration)
    assert len(rows) == 6
    for r in rows:
        assert r.rate_model_rmse_n < r.static_model_rmse_n, r


def test_holds_read_right_through_the_noisy_output_the_driver_sees():
    """The driver runs the curve on the noisy output, not on a low-passed one. Fitted on
    the low-passed output, the curve ended flat just past the hold's mean output, the
    noise above it was clamped, and every hold read low (measured with 30 mV of noise:
    -0.14 to -0.16 N; the mock's pairs with 12 mV: -0.03 to -0.09 N). Fitted on the
    output as recorded (its hats averaged per grid block, then low-passed like the
    force), the holds' mean error is measured +0.012, +0.008 and -0.005 N."""
    record = mock_like(hold_s=2.0, noise_v=0.03)
    cal = fit_rate_calibration(record, "noisy", terms=2, play=True).calibration
    period = float(np.median(np.diff(record.t_s)))
    error = zero_phase_low_pass(period, 5.0, rate_force_history(
        cal, record.t_s, record.output_v) - record.force_n)
    assert error is not None
    for speed in record.speeds():
        hold = record.mask([speed], HOLD)
        assert abs(float(np.mean(error[hold]))) < 0.03, speed


# -- the pieces -----------------------------------------------------------------------------

@settings(max_examples=25, deadline=None)
@given(st.lists(st.integers(1, 400), min_size=1, max_size=4))
def test_every_speed_weighs_the_same(counts):
    speed = np.concatenate([np.full(n, float(k + 1)) for k, n in enumerate(counts)])
    rec = RateRecord(np.arange(speed.size + 2.0), np.zeros(speed.size + 2),
                     np.zeros(speed.size + 2), np.concatenate((speed, [np.nan, np.nan])),
                     np.concatenate((np.full(speed.size, LOADING), [OUTSIDE, OUTSIDE]))
                     .astype(np.int8))
    score = rec.mask()
    w = _speed_weights(rec, rec.speeds(), score)
    assert w.size == speed.size and np.mean(w) == pytest.approx(1.0)
    totals = [w[speed == k + 1].sum() for k in range(len(counts))]
    assert totals == pytest.approx([totals[0]] * len(counts))


def test_unloading_is_left_out_until_the_output_moves():
    out = np.array([0, 1, 2, 3, 3, 3, 3, 2.99, 2.9, 2, 1, 0, 0], float)
    phase = np.array([0, 1, 1, 1, 2, 3, 3, 3, 3, 3, 3, 3, 0], np.int8)
    rec = RateRecord(np.arange(out.size, dtype=float), out, out, np.where(phase, 1.0, np.nan),
                     phase)
    drop = REVERSAL_SHARE * 3.0  # 0.15 of the 0..3 range
    kept = _without_reversals(rec).phase
    first_moved = int(np.flatnonzero((out <= 3 - drop) & (phase == UNLOADING))[0])
    assert np.all(kept[5:first_moved] == OUTSIDE)
    assert np.array_equal(kept[first_moved:], phase[first_moved:])
    assert np.array_equal(kept[:5], phase[:5])


def test_an_unloading_that_never_moves_or_runs_to_the_end_is_all_left_out():
    out = np.array([0, 1, 2, 2, 2, 2], float)
    phase = np.array([0, 1, 1, 3, 3, 3], np.int8)
    rec = RateRecord(np.arange(6.0), out, out, np.where(phase, 1.0, np.nan), phase)
    assert np.array_equal(_without_reversals(rec).phase, [0, 1, 1, 0, 0, 0])


def test_a_record_without_presses_is_left_as_it_is():
    rec = RateRecord(np.arange(5.0), np.ones(5), np.ones(5), np.full(5, np.nan),
                     np.zeros(5, np.int8))
    assert _without_reversals(rec) is rec


@settings(max_examples=20, deadline=None)
@given(st.floats(0.2, 2.0), st.floats(80.0, 200.0))
def test_the_low_pass_keeps_slow_signals_without_delay_and_cuts_fast_ones(slow_hz, fast_hz):
    t = np.arange(0.0, 10.0, 1e-3)
    slow = np.sin(2 * np.pi * slow_hz * t)
    out = zero_phase_low_pass(1e-3, 5.0, slow + np.sin(2 * np.pi * fast_hz * t))
    assert out is not None
    inner = slice(2000, -2000)  # away from the ends' transients
    assert np.max(np.abs(out[inner] - slow[inner])) < 0.05


@pytest.mark.parametrize(("period", "cutoff", "size"), [(1e-3, 500.0, 100), (1e-3, 0.0, 100),
                                                        (1e-3, 5.0, 6)])
def test_the_low_pass_refuses_what_it_cannot_filter(period, cutoff, size):
    assert zero_phase_low_pass(period, cutoff, np.zeros(size)) is None


def test_model_error_leaves_the_white_noise_out():
    """The same calibration on a noise-free and a noisy output: the per-sample RMSE grows
    by the noise, the model error hardly, and the noise row says how much was removed."""
    rec = mock_like(speeds_m_s=(3e-3,), hold_s=1.0, noise_v=0.0, play_m=0.0)
    v = np.linspace(0.0, 0.6, 30)  # past the top: noise there is not clamped
    static = Calibration.from_curve(v.tolist(), (7.0 * (v / 0.5) ** (1.3 / 0.9)).tolist(), "t")
    cal = RateCalibration(static, [RateTerm(g, tau) for g, tau in zip(TRUE_G, TRUE_TAU_S,
                                                                      strict=True)])
    noisy = RateRecord(rec.t_s, rec.output_v + np.random.default_rng(3).normal(0, 0.013,
                                                                                rec.t_s.size),
                       rec.force_n, rec.speed_mm_s, rec.phase)
    clean_rows, noisy_rows = phase_table(rec, static, cal), phase_table(noisy, static, cal)
    noise_n = 0.013 * 7.0 * 1.3 / 0.9 / 0.5  # ~ the curve's slope times the noise at the top
    for clean, dirty in zip(clean_rows, noisy_rows, strict=True):
        assert clean.rate_rmse_n < 0.05 and clean.noise_rmse_n < 0.03  # ramp corners
        assert dirty.rate_rmse_n > 0.1
        assert dirty.rate_model_rmse_n < clean.rate_model_rmse_n + 0.05
        assert 0.2 * noise_n < dirty.noise_rmse_n < 1.5 * noise_n
    keys = table_dict(noisy_rows)["3.0"]["hold"]
    assert {"static_rmse_n", "rate_rmse_n", "static_model_rmse_n", "rate_model_rmse_n",
            "noise_rmse_n", "samples"} == set(keys)


def test_a_record_too_short_to_low_pass_has_no_model_error():
    t = np.arange(6) * 1e-3
    rec = RateRecord(t, np.linspace(0, 0.5, 6), np.linspace(0, 7, 6), np.full(6, 1.0),
                     np.full(6, LOADING, np.int8))
    static = Calibration.from_curve([0.0, 0.5], [0.0, 7.0], "t")
    (row,) = phase_table(rec, static, RateCalibration(static, [RateTerm(0.05, 0.1)]))
    assert math.isnan(row.rate_model_rmse_n) and math.isnan(row.noise_rmse_n)
    assert table_dict([row])["1.0"]["loading"]["rate_model_rmse_n"] is None
    assert not row.meets_goal(7.0, model=True)


@pytest.mark.parametrize(("static", "rate", "ok"), [
    (0.3, 0.1, True),  # half and 1.4 % of 7 N
    (0.3, 0.16, False),  # more than half
    (0.5, 0.11, False),  # half, but 1.6 % of 7 N
])
def test_the_goal_needs_half_the_static_error_and_1_5_percent_of_full_scale(static, rate, ok):
    assert GOAL_RATIO == 0.5 and GOAL_SHARE_FS == 0.015
    row = PhaseError(1.0, "hold", 10, static, rate, static, rate, 0.0)
    assert row.meets_goal(7.0, model=False) is ok
    assert row.meets_goal(7.0, model=True) is ok
    per_sample_only = PhaseError(1.0, "hold", 10, static, rate, 1.0, 1.0, 0.0)
    assert per_sample_only.meets_goal(7.0, model=False) is ok
    assert per_sample_only.meets_goal(7.0, model=True) is False


@settings(max_examples=40, deadline=None)
@given(rows=st.integers(1, 3), length=st.integers(7, 400), long_pad=st.booleans(),
       cutoff_hz=st.sampled_from([0.7, 5.0, 40.0]), seed=st.integers(0, 2 ** 16))
def test_the_zero_phase_low_pass_is_scipys_filtfilt_with_odd_padding(rows, length, long_pad,
                                                                     cutoff_hz, seed):
    from scipy.signal import butter, filtfilt

    from tactile_sensor.analysis.rate.history import LOW_PASS_ORDER

    values = np.random.default_rng(seed).normal(size=(rows, length)).cumsum(axis=-1)
    b, a = butter(LOW_PASS_ORDER, 2.0 * cutoff_hz * 1e-3)
    short = 3 * max(a.size, b.size)
    got = zero_phase_low_pass(1e-3, cutoff_hz, values, long_pad=long_pad)
    if length <= short:
        assert got is None
        return
    pad = min(length - 1, max(short, round(1.0 / (cutoff_hz * 1e-3)))) if long_pad else short
    np.testing.assert_allclose(got, filtfilt(b, a, values, padtype="odd", padlen=pad),
                               rtol=0, atol=1e-12)
    np.testing.assert_allclose(zero_phase_low_pass(1e-3, cutoff_hz, values[0],
                                                   long_pad=long_pad), got[0], atol=1e-12)
