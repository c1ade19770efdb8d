"""The bend analysis's metrics on traces whose error, lag and hysteresis are known."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tactile_sensor.analysis.bend.metrics import cut_bends, hysteresis_pct, phases
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
