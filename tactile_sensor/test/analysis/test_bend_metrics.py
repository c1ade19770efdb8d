"""The bend analysis's metrics on traces whose error, lag and hysteresis are known."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tactile_sensor.analysis.bend.metrics import (
    cut_bends,
    group_hysteresis,
    hysteresis_pct,
    phases,
)
from tactile_sensor.sim.bend_world import BendPath

PEAK = math.pi / 2


def traces(path: BendPath, lag_s: float = 0.0, bias_rad: float = 0.0):
    t = np.arange(0.0, path.duration_s, 0.001)
    truth = path.angle(t)
    estimate = path.angle(t - lag_s) + bias_rad
    return t, truth, estimate, path.tip_force(t)


@settings(max_examples=10, deadline=None)
@given(lag=st.floats(0.0, 0.05))
def test_a_delayed_estimate_has_that_lag(lag):
    t, truth, est, force = traces(BendPath(PEAK, (0.5,), 4, 0.0, 1.0), lag)
    (phase,) = phases(t, truth, est, force)
    assert phase["bends"] == 4 and phase["rate_hz"] == 0.5 and not phase["contact"]
    assert phase["lag_s"]["mean"] == pytest.approx(lag, abs=5e-4)
    assert phase["lag_s"]["sem"] is not None


def test_a_bias_is_the_rmse_and_no_hysteresis():
    t, truth, est, force = traces(BendPath(PEAK, (0.2, 1.0), 3, 0.0, 1.0),
                                  bias_rad=math.radians(1.0))
    found = phases(t, truth, est, force)
    assert [p["rate_hz"] for p in found] == [0.2, 1.0]
    for p in found:
        assert p["rmse_deg"] == pytest.approx(1.0, rel=1e-3)
        assert p["hysteresis_pct"]["mean"] == pytest.approx(0.0, abs=1e-6)
        assert p["hysteresis_pct_per_bend"]["mean"] == pytest.approx(0.0, abs=1e-6)


def test_contact_bends_form_their_own_phase_and_nan_is_counted():
    t, truth, est, force = traces(BendPath(PEAK, (0.5,), 4, 2.0, 1.0))
    est[1500:1600] = np.nan  # in the first bend (the rest before it is not scored)
    found = phases(t, truth, est, force, force + 0.1)
    assert [(p["contact"], p["bends"]) for p in found] == [(False, 4), (True, 4)]
    assert found[1]["max_tip_force_n"] > 1.5
    assert found[1]["tip_force_rmse_n"] == pytest.approx(0.1)
    assert sum(p["nan_samples"] for p in found) == 100


def test_hysteresis_is_the_largest_gap_between_the_branches_in_percent():
    up = np.linspace(0, 1, 1001)
    truth = np.concatenate([up, up[::-1][1:]])
    est = truth.copy()
    est[1001:] += 0.02  # the way down reads 2 % of the range high
    assert hysteresis_pct(truth, est) == pytest.approx(2.0, abs=1e-6)
    noisy = est + np.random.default_rng(1).normal(0, 0.005, est.size)
    assert hysteresis_pct(truth, noisy) == pytest.approx(2.0, abs=0.5)


def test_a_run_without_a_whole_bend_has_none():
    t = np.arange(0, 1, 0.001)
    assert cut_bends(t, np.zeros_like(t)) == []
    assert cut_bends(t, np.minimum(t, 0.5)) == []


def _bends(rate_hz: float = 0.5, n: int = 6, h_pct: float = 0.0, noise_rad: float = 0.0,
           seed: int = 0) -> list[tuple[np.ndarray, np.ndarray]]:
    """(truth, estimate) of ``n`` bends 0 -> 90 deg whose way down reads ``h_pct`` % of the
    range above the way up (estimate = truth - h/2 * sign of the motion), plus a noise
    smoothed over 50 ms as a filter's output is (correlated from sample to sample)."""
    t, truth, _, _ = traces(BendPath(PEAK, (rate_hz,), n, 0.0, 1.0))
    motion = np.sign(np.gradient(truth))
    est = truth - 0.5 * h_pct / 100.0 * PEAK * motion
    if noise_rad:
        white = np.random.default_rng(seed).normal(0.0, noise_rad, t.size + 49)
        est = est + np.convolve(white, np.ones(50) / 50.0, "valid")
    return [(truth[a:b], est[a:b]) for a, b, _ in cut_bends(t, truth)]


@pytest.mark.parametrize("h_pct", [0.5, 2.0, 5.0])
def test_the_group_hysteresis_recovers_a_known_one(h_pct):
    exact = group_hysteresis(_bends(h_pct=h_pct))
    assert exact.bends == 6
    assert exact.pct == pytest.approx(h_pct, abs=0.02)  # a bin's edge sample aside
    assert exact.sem_pct == pytest.approx(0.0, abs=0.02)
    noisy = group_hysteresis(_bends(h_pct=h_pct, noise_rad=0.1))
    assert noisy.pct == pytest.approx(h_pct, abs=3 * noisy.sem_pct + noisy.noise_floor_pct)
    # the floor is the noise's alone: the same with or without the hysteresis
    assert noisy.noise_floor_pct == pytest.approx(
        group_hysteresis(_bends(noise_rad=0.1)).noise_floor_pct, rel=1e-9)


def test_pure_noise_reads_its_noise_floor_and_well_below_a_single_bend():
    ratios, per_bend = [], []
    for seed in range(8):
        pieces = _bends(noise_rad=0.1, seed=seed)
        g = group_hysteresis(pieces)
        ratios.append(g.pct / g.noise_floor_pct)
        per_bend.append(np.mean([hysteresis_pct(a, e) for a, e in pieces]) / g.pct)
    assert 0.6 < np.mean(ratios) < 1.4, ratios
    assert min(per_bend) > 1.5, per_bend  # one bend's figure is mostly its noise


def test_the_phase_reports_the_group_figure_and_keeps_the_per_bend_one():
    t, truth, est, force = traces(BendPath(PEAK, (0.5,), 4, 0.0, 1.0))
    est = est + np.random.default_rng(3).normal(0.0, 0.02, est.size)
    (p,) = phases(t, truth, est, force)
    h, per_bend = p["hysteresis_pct"], p["hysteresis_pct_per_bend"]
    assert set(h) >= {"mean", "sem", "noise_floor", "range_deg", "bends"}
    assert h["bends"] == 4 and h["range_deg"][1] == pytest.approx(90.0, abs=0.01)
    assert h["mean"] < per_bend["mean"] and per_bend["sem"] is not None


def test_bad_input_gives_nan_not_an_error():
    (one,) = _bends(n=1, noise_rad=0.1)
    g = group_hysteresis([one])
    assert g.pct == pytest.approx(hysteresis_pct(*one))  # one bend: its own figure ...
    assert math.isnan(g.sem_pct) and math.isnan(g.noise_floor_pct)  # ... with no spread
    rising = np.linspace(0.0, PEAK, 500)  # no way down
    for pieces in ([], [(rising, rising)], [(one[0], np.full_like(one[1], np.nan))],
                   [(np.zeros(100), np.zeros(100))]):
        g = group_hysteresis(pieces)
        assert math.isnan(g.pct) and math.isnan(g.sem_pct) and math.isnan(g.noise_floor_pct)
    assert math.isnan(hysteresis_pct(rising, rising))
