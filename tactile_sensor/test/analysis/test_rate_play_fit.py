"""Fitting play (two static branches) with the rate terms, from synthetic recordings whose
output trails the indentation by a known play (``sim.bench_world.play``, as the mock)."""

from __future__ import annotations

import numpy as np
import pytest

from tactile_sensor.analysis.calibration_fit import fit_calibration
from tactile_sensor.analysis.rate.evaluation import phase_table
from tactile_sensor.analysis.rate.fit import fit_rate_calibration
from tactile_sensor.analysis.rate.history import loading_history, rate_force_history
from tactile_sensor.analysis.rate.record import LOADING, UNLOADING, RateRecord
from tactile_sensor.analysis.synthetic import rate_press_record

PLAY_M = 65e-6  # the mock's output_play
SPEEDS_M_S = (0.3e-3, 1e-3, 10e-3)


def played(speeds_m_s=SPEEDS_M_S, seed=0, play_m=PLAY_M) -> RateRecord:
    return rate_press_record(speeds_m_s, hold_s=2.0, seed=seed, output_noise_v=2e-3,
                             play_m=play_m)


def true_half_gap(output_v: float, play_m: float = PLAY_M) -> float:
    """Half the loading-minus-unloading relaxed force at one output: the output reads
    d − play while loading and d while unloading (7 N (d / 3 mm)^1.3)."""
    d = 3e-3 * (output_v / 0.5) ** (1 / 0.9)
    return 0.5 * 7.0 * (((d + play_m) / 3e-3) ** 1.3 - (d / 3e-3) ** 1.3)


@pytest.fixture(scope="module")
def record() -> RateRecord:
    return played()


@pytest.fixture(scope="module")
def fit(record):
    return fit_rate_calibration(record, "played", terms=2)


def test_play_is_chosen_and_its_half_gap_recovered(fit):
    cal = fit.calibration
    assert cal.play is not None and fit.metadata()["play"] is True
    for out in (0.1, 0.25, 0.4):
        half = np.interp(out, cal.static.output_v, cal.play.half_gap_n)
        assert half == pytest.approx(true_half_gap(out), abs=0.03), out
    assert cal.g == pytest.approx((0.05, 0.04), rel=0.4)
    assert cal.tau_s == pytest.approx((0.1, 1.5), rel=0.4)
    # held out, play cuts the error of the same number of terms without it
    assert fit.folds.mean_rmse_n < 0.7 * fit.other_counts[2].mean_rmse_n


@pytest.fixture(scope="module")
def plain_record() -> RateRecord:
    return played(play_m=0.0)


def test_without_play_in_the_record_none_is_fitted(plain_record):
    fit = fit_rate_calibration(plain_record, "no play", terms=2)
    assert fit.calibration.play is None  # exactly today's model
    assert fit.metadata()["play"] is False and set(fit.other_counts) == {2}


def test_play_false_fits_todays_model_only(plain_record):
    fit = fit_rate_calibration(plain_record, "plain", terms=2, play=False)
    assert fit.calibration.play is None and fit.other_counts == {}


def test_held_out_speeds_halve_the_static_error_in_every_phase_with_play(fit):
    """Fitted on 0.3, 1, 10 mm/s; scored on 3 and 20 mm/s with 2 s holds against a static
    curve fitted on the held-out record's own 3 mm/s ramps (in-sample, favoured)."""
    check = played(speeds_m_s=(3e-3, 20e-3), seed=1)
    ramps = check.mask([3.0]) & np.isin(check.phase, (LOADING, UNLOADING))
    static = fit_calibration(check.output_v[ramps], check.force_n[ramps], "static")
    rows = phase_table(check, static, fit.calibration)
    assert len(rows) == 6
    for r in rows:
        assert r.rate_model_rmse_n <= 0.5 * r.static_model_rmse_n, r
        assert r.rate_model_rmse_n <= 0.015 * 7.0, r


def test_batch_history_with_play_equals_the_drivers_estimator(fit, record):
    cal = fit.calibration
    part = slice(0, 30000)  # the 0.3 mm/s press: loading, hold, unloading
    t, out = record.t_s[part], record.output_v[part]
    est = cal.estimator()
    stream, branch = [], []
    for o, s in zip(out.tolist(), t.tolist(), strict=True):
        stream.append(est.update(o, s)[0])
        branch.append(est.loading)
    assert np.allclose(stream, rate_force_history(cal, t, out), rtol=1e-9, atol=1e-9)
    assert branch == loading_history(cal.play, t, out).tolist()
    assert not all(branch) and any(branch)  # both branches were used
