"""The lift's figures: the load profile's last rise, the phases' grip and slip, slip onset to
grip rise, and the benchmark's objects."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tactile_sensor.analysis.lift import (
    GRIP_RISE_N,
    MIN_TARGET_N,
    BenchObject,
    Trace,
    bench_objects,
    lift_figures,
    load_rise,
    peak_load_n,
    phase_summary,
)
from tactile_sensor.sim.held_object import STANDARD_GRAVITY_M_S2, LoadScript, parse_load_profile


@pytest.mark.parametrize(("profile", "rise"), [
    (["0:-1", "0.5:0", "3:0", "3.1:1"], (3.0, 3.1)),
    (["0:-1", "0.5:0"], (0.0, 0.5)),
    (["0:0", "1:0.5", "2:1", "3:1"], (0.0, 2.0)),
    (["0:1", "1:0"], None),
    ([], None),
])
def test_the_load_rise_is_the_profiles_last_growing_run(profile, rise):
    assert load_rise(parse_load_profile(profile)) == rise


def test_the_peak_load_is_the_weight_and_the_largest_pull():
    load = parse_load_profile(["0:-0.98", "0.5:0", "2:0.98"])
    assert peak_load_n(0.1, load) == pytest.approx(0.1 * STANDARD_GRAVITY_M_S2 + 0.98)
    assert peak_load_n(0.1, LoadScript()) == pytest.approx(0.1 * STANDARD_GRAVITY_M_S2)


def trace(times, values) -> Trace:
    return Trace.of(list(zip(times, values, strict=True)))


def test_a_phase_reports_its_grip_and_the_slip_gained_in_it():
    t = np.arange(0.0, 3.0, 0.01)
    grip = trace(t, np.where(t < 1.0, 2.0, 3.0))
    slip = trace(t, np.clip(t - 1.5, 0.0, None) * 1e-3)  # 1 mm/s from 1.5 s
    before = phase_summary("lift", 0.0, 1.0, grip, slip)
    after = phase_summary("load", 1.5, 2.5, grip, slip)
    assert before.slip_m == 0.0 and before.grip_mean_n == pytest.approx(2.0, abs=0.02)
    assert after.slip_m == pytest.approx(1e-3, abs=2e-5) and after.grip_peak_n == 3.0
    assert "slip 1.00 mm" in after.line() and "phase load" in after.line()


def test_slip_onset_to_grip_rise_from_the_ground_truth():
    t = np.arange(100.0, 106.0, 0.005)
    lift, rise = 100.0, (2.5, 2.6)
    slip = trace(t, np.where(t > 102.55, (t - 102.55) * 1e-3, 0.0))
    grip = trace(t, np.where(t > 102.58, 3.0, 2.0))
    f = lift_figures(lift, 105.0, rise, 2.0, grip, slip, [102.7], dropped=False)
    assert f.onset_s == pytest.approx(102.55 + 0.025, abs=0.006)  # 20 um at 1 mm/s
    assert f.grip_rise_s == pytest.approx(102.58, abs=0.006)
    assert f.latency_s == pytest.approx(0.005, abs=0.01)
    assert f.ratio == pytest.approx(1.5) and f.peak_grip_n == 3.0
    assert "dropped=no" in f.line() and "ratio=1.50" in f.line()


def test_without_slip_the_onset_is_the_holds_event_and_the_latency_may_be_negative():
    t = np.arange(0.0, 5.0, 0.005)
    grip = trace(t, np.where(t > 2.52, 2.0 + 2 * GRIP_RISE_N, 2.0))
    slip = trace(t, np.zeros_like(t))
    f = lift_figures(0.0, 5.0, (2.5, 2.6), 2.0, grip, slip, [1.0, 2.55], dropped=False)
    assert f.onset_s == 2.55 and f.latency_s == pytest.approx(-0.03, abs=0.006)
    quiet = lift_figures(0.0, 5.0, (2.5, 2.6), 2.0, trace(t, np.full_like(t, 2.0)), slip,
                         [], dropped=True)
    assert quiet.latency_s is None and "latency_ms=nan" in quiet.line()
    assert "dropped=yes" in quiet.line()


def test_a_lift_without_a_load_rise_has_no_latency():
    t = np.arange(0.0, 2.0, 0.01)
    f = lift_figures(0.0, 2.0, None, 1.0, trace(t, np.full_like(t, 2.0)),
                     trace(t, t * 1e-3), [], dropped=False)
    assert f.onset_s is None and f.slip_m == pytest.approx(1.99e-3)
    assert math.isnan(lift_figures(0.0, 1.0, None, 1.0, Trace.of([]), Trace.of([]), [],
                                   False).peak_grip_n)


@settings(max_examples=30, deadline=None)
@given(count=st.integers(1, 12), seed=st.integers(0, 2**31), ceiling=st.floats(2.0, 10.0))
def test_the_bench_objects_are_in_the_goals_range_and_holdable(count, seed, ceiling):
    objects = bench_objects(count, seed, ceiling)
    assert len(objects) == count and objects == bench_objects(count, seed, ceiling)
    for i, obj in enumerate(objects):
        assert 0.05 <= obj.mass_kg <= 0.3 and 0.3 <= obj.friction_static <= 1.0
        assert obj.friction_kinetic == pytest.approx(
            obj.friction_static * (1.0 if i % 2 == 0 else 0.8), abs=0.006)
        assert obj.least_doubled_n <= 0.8 * ceiling
        assert obj.target_n >= MIN_TARGET_N


def test_a_bench_objects_profile_eases_the_weight_on_then_doubles_it():
    obj = BenchObject(0.2, 0.5, 0.5)
    load = parse_load_profile(obj.load_profile)
    weight = 0.2 * STANDARD_GRAVITY_M_S2
    assert load.force_n(0.0) == pytest.approx(-weight)  # with gravity: no load at the lift
    assert load.force_n(1.0) == pytest.approx(0.0, abs=1e-5)
    assert peak_load_n(0.2, load) == pytest.approx(2 * weight, rel=1e-5)
    assert obj.least_doubled_n == pytest.approx(2 * weight / (2 * 0.5))
    # a fixed grasp at the target holds the weight alone, not the doubled load
    assert weight / (2 * 0.5) < obj.target_n < obj.least_doubled_n


def test_a_set_down_after_a_fall_gains_no_slip():
    t = np.arange(0.0, 2.0, 0.01)
    slip = trace(t, np.where(t < 1.0, 11e-3, 0.0))  # fell out, then set down: reset
    grip = trace(t, np.zeros_like(t))
    assert phase_summary("set down", 0.5, 2.0, grip, slip).slip_m == 0.0
