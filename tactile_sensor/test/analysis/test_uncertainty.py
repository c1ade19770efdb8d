"""How sure each figure is: the intervals cover the truth as often as they claim, one
cycle says it has no estimate, and the report and figures carry both."""

from __future__ import annotations

import math
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from tactile_sensor.analysis import characterise as ch
from tactile_sensor.analysis import metrics as m
from tactile_sensor.analysis import plots
from tactile_sensor.analysis import uncertainty as u
from tactile_sensor.analysis.report import rows, speed_rows, write_report
from tactile_sensor.analysis.synthetic import (
    PressProtocol,
    SensorTruth,
    press_signals,
    write_press_bag,
)

values = st.lists(st.floats(min_value=-1e3, max_value=1e3), max_size=20)


@given(values, st.sampled_from(["mean", "median"]))
def test_a_spread_is_ordered_and_needs_two_cycles(xs, statistic):
    s = u.spread(xs, statistic)
    assert s.cycles == len(xs)
    if not xs:
        assert s.centre is None and s.ci95 is None
        return
    assert min(xs) - 1e-9 <= s.centre <= max(xs) + 1e-9
    if len(xs) == 1:
        assert s.sd is None and s.se is None and s.ci95 is None
        return
    assert 0.0 <= s.se <= s.ci95
    assert s.ci95 == pytest.approx(u.t95(len(xs) - 1) * s.se)


def test_missing_and_non_finite_values_are_left_out():
    s = u.spread([1.0, None, math.nan, math.inf, 3.0])
    assert s.values == (1.0, 3.0) and s.centre == 2.0
    assert s.sd == pytest.approx(math.sqrt(2.0))


def test_equal_values_have_no_spread_and_a_median_costs_efficiency():
    assert u.spread([0.5] * 4).ci95 == 0.0
    xs = [0.1, 0.4, 0.2, 0.3, 0.5]
    assert u.spread(xs, "median").se == pytest.approx(1.2533 * u.spread(xs).se)
    with pytest.raises(ValueError, match="mean"):
        u.spread(xs, "mode")


def test_students_t_widens_the_interval_for_few_cycles():
    assert u.t95(1) == pytest.approx(12.706, rel=1e-3)
    assert u.t95(4) == pytest.approx(2.776, rel=1e-3)
    assert u.t95(10_000) == pytest.approx(1.960, rel=1e-3)


@pytest.mark.parametrize("statistic, n", [("mean", 5), ("median", 7)])
def test_the_interval_covers_the_true_centre_about_95_percent_of_the_time(statistic, n):
    rng = np.random.default_rng(4)
    hits = [abs(s.centre - 1.0) <= s.ci95
            for s in (u.spread(rng.normal(1.0, 0.3, n), statistic) for _ in range(2000))]
    assert 0.93 <= np.mean(hits) <= 0.98


def _ar1(rng: np.random.Generator, n: int, rho: float) -> np.ndarray:
    w = rng.standard_normal(n)
    e = np.empty(n)
    e[0] = w[0]
    for i in range(1, n):
        e[i] = rho * e[i - 1] + math.sqrt(1 - rho ** 2) * w[i]
    return e


@pytest.mark.parametrize("rho, lowest", [(0.0, 0.92), (0.9, 0.86)])
def test_the_slopes_standard_error_holds_for_residuals_correlated_in_time(rho, lowest):
    """At 1 kHz neighbouring residuals are alike; the textbook error claims a slope known
    several times better than it is (about 0.35 coverage at r = 0.9). The corrected one
    covers 0.91-0.93 there (r estimated from 500 residuals reads a little low)."""
    rng = np.random.default_rng(7)
    x = np.linspace(0.0, 1.0, 500)
    hits, textbook = [], []
    for _ in range(400):
        y = 2.0 * x + 0.1 * _ar1(rng, x.size, rho)
        slope, intercept = np.polyfit(x, y, 1)
        resid = y - (slope * x + intercept)
        hits.append(abs(slope - 2.0) <= 1.96 * u.slope_standard_error(x, resid))
        naive = math.sqrt(np.sum(resid ** 2) / (x.size - 2) / np.sum((x - x.mean()) ** 2))
        textbook.append(abs(slope - 2.0) <= 1.96 * naive)
    assert lowest <= np.mean(hits) <= 0.98
    if rho > 0:
        assert np.mean(textbook) < 0.5


def test_a_slope_without_scatter_or_spread_has_an_exact_or_no_error():
    x = np.linspace(0.0, 1.0, 50)
    assert u.slope_standard_error(x, np.zeros_like(x)) == 0.0
    assert u.slope_standard_error(np.ones(10), np.zeros(10)) is None
    assert u.slope_standard_error(x[:2], np.zeros(2)) is None


@given(st.floats(min_value=0.01, max_value=50.0), st.integers(min_value=2, max_value=200))
def test_the_cv_interval_holds_the_cv_and_narrows_with_cycles(cv, n):
    lo, hi = u.cv_interval(cv, n)
    assert lo <= cv <= hi
    lo2, hi2 = u.cv_interval(cv, n + 10)
    assert hi2 - lo2 < hi - lo


def test_one_cycle_has_no_cv_or_drift_interval():
    assert u.cv_interval(2.0, 1) is None and u.cv_interval(None, 5) is None
    assert u.drift_ci95(np.array([0.5]), 1) is None
    assert u.drift_ci95(np.array([0.5, 0.5, 0.5, 0.5]), 2) == 0.0
    assert u.drift_ci95(np.array([-0.5, -0.4]), 1) is None  # no positive first mean


def test_propagated_errors_add_in_quadrature_and_need_every_factor():
    assert u.quotient_se(2.0, 0.03, 0.04) == pytest.approx(0.1)
    assert u.quotient_se(2.0, 0.03, None) is None
    assert u.decibel_se(0.1) == pytest.approx(0.8686, rel=1e-3)
    assert u.decibel_se(None) is None
    assert u.relative_se(0.0, 1.0) is None and u.relative_se(2.0, 0.5) == 0.25
    assert u.normal_ci95(1.0) == pytest.approx(1.96, rel=1e-3) and u.normal_ci95(None) is None


TRUTH = SensorTruth(noise_v=0.01, cycle_gain_cv=0.02)


def _analysed(tmp_path, protocol: PressProtocol) -> ch.Characterisation:
    bag = write_press_bag(tmp_path / "bag", press_signals(protocol, TRUTH, seed=5), "mcap")
    return ch.analyse_bag(str(bag), ch.Options())


@pytest.fixture(scope="module")
def several(tmp_path_factory):
    """Five presses at 1 mm/s and three at 10 mm/s, as make demo's protocol gives them."""
    return _analysed(tmp_path_factory.mktemp("several"),
                     PressProtocol(speeds_mm_s=(1.0, 10.0), cycles=(5, 3), depth_m=1e-3,
                                   hold_s=0.0, rest_s=0.5, rate_hz=500.0))


@pytest.fixture(scope="module")
def single(tmp_path_factory):
    return _analysed(tmp_path_factory.mktemp("single"),
                     PressProtocol(speeds_mm_s=(1.0,), cycles=(1,), depth_m=1e-3, hold_s=0.0,
                                   rest_s=0.5, rate_hz=500.0))


def test_every_figure_over_several_cycles_carries_its_interval(several):
    mt = several.metrics
    for key in ("full_scale_ci95_n", "full_scale_output_ci95_v", "sensitivity_se_v_per_n",
                "sensitivity_ci95_v_per_n", "noise_ci95_v", "resolution_ci95_n",
                "dynamic_range_ci95_db", "hysteresis_ci95_pct_fs", "drift_ci95_pct"):
        assert mt[key] is not None and mt[key] >= 0, key
    lo, hi = mt["peak_output_cv_ci95_pct"]
    assert lo <= mt["peak_output_cv_pct"] <= hi
    assert len(mt["hysteresis_cycles_pct_fs"]) == len(mt["peak_outputs_v"]) == 5
    for key, n in (("1.0", 5), ("10.0", 3)):
        s = mt["by_speed"][key]
        assert s["cycles"] == s["phase_lag_cycles"] == len(s["phase_lags_s"]) == n
        for name in ("peak_force_ci95_n", "peak_output_ci95_v", "sensitivity_ci95_v_per_n",
                     "phase_lag_ci95_s"):
            assert s[name] is not None and s[name] >= 0, (key, name)
    # the synthetic sensor's lag at 1 mm/s lies inside the measured interval
    lag = mt["by_speed"]["1.0"]
    assert abs(lag["phase_lag_s"] - TRUTH.lag_s[1.0]) <= lag["phase_lag_ci95_s"]


def test_one_cycle_says_it_has_no_estimate(single, tmp_path):
    mt = single.metrics
    for key in ("full_scale_ci95_n", "sensitivity_ci95_v_per_n", "hysteresis_ci95_pct_fs",
                "peak_output_cv_ci95_pct", "drift_ci95_pct"):
        assert mt[key] is None, key
    assert mt["by_speed"]["1.0"]["phase_lag_ci95_s"] is None
    assert mt["sensitivity_se_v_per_n"] is not None  # the fit has one, one press or many
    measured = {name: value for name, value, _ in rows(single)}
    for name in ("Full scale force", "Sensitivity", "Hysteresis", "Peak output CV",
                 "Drift (first vs last cycles)", "Phase lag at 1.0 mm/s (onset)"):
        assert u.ONE_CYCLE in measured[name], (name, measured[name])
    (row,) = speed_rows(mt)
    assert row[:2] == ("1.0 mm/s", "1") and all(u.ONE_CYCLE in c for c in row[3:])
    assert float(row[2].removesuffix(" mm")) == pytest.approx(1.0, abs=0.01)  # the depth
    figures = plots.all_figures(single, tmp_path)
    assert figures["speed_summary"].stat().st_size > 0


def test_the_report_gives_peak_force_and_output_at_each_speed(several, tmp_path):
    md, page = write_report(several, {}, tmp_path)
    text = md.read_text()
    by = several.metrics["by_speed"]
    for key in ("1.0", "10.0"):
        line = next(x for x in text.splitlines() if x.startswith(f"| {key} mm/s |"))
        force, output = f"{by[key]['peak_force_n']:.3g} ± ", f"{by[key]['peak_output_v']:.3g} ± "
        assert force in line and output in line, line
    assert "Peaks at each speed" in page.read_text()
    measured = {name: value for name, value, _ in rows(several)}
    assert "(5 cycles)" in measured["Hysteresis"] and " ± " in measured["Hysteresis"]
    assert "(3 cycles)" in measured["Phase lag at 10.0 mm/s (onset)"]


def test_a_recording_without_presses_has_the_same_keys_all_null(several):
    """An array recording that cannot be segmented writes the same metrics file."""
    series = {r: SimpleNamespace(topic=f"/{r}", stamp_source="header") for r in ch.ROLES}
    recording = SimpleNamespace(path="bag", storage="mcap", series=series, notes=[])
    empty = ch.unavailable_metrics(recording, "no press.")
    assert set(empty) == set(several.metrics)
    assert all(empty[k] is None for k in ch.UNCERTAINTY_KEYS)


def test_cycles_without_a_fit_are_left_out_of_the_spread(several):
    """A press whose force never changes gives no slope and no hysteresis, not an error."""
    flat = replace(several.signals, force_n=np.zeros_like(several.signals.force_n))
    cycles = several.segmentation.cycles
    assert m.sensitivities(flat, cycles) == [None] * len(cycles)
    assert m.hysteresis_per_cycle(flat, cycles, 0.0, 1.0) == [None] * len(cycles)
    assert u.spread(m.sensitivities(flat, cycles)).centre is None
