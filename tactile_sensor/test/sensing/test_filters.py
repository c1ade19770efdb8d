from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.signal import butter, sosfilt, sosfilt_zi

from tactile_sensor.sensing.errors import SensingError
from tactile_sensor.sensing.filters import (
    DEFAULT_FILTER,
    FILTERS,
    MovingAverage,
    SavitzkyGolayLinear,
    SavitzkyGolayQuadratic,
    make_filter,
)

signals = st.lists(st.floats(-5, 5, allow_nan=False), min_size=1, max_size=200)


def run(f, xs):
    return np.array([f.update(float(x)) for x in xs])


@given(signals, st.integers(1, 20))
def test_moving_average_is_the_mean_of_the_last_window(xs, window):
    got = run(MovingAverage(window), xs)
    want = [np.mean(xs[max(0, k - window + 1):k + 1]) for k in range(len(xs))]
    np.testing.assert_allclose(got, want, atol=1e-9)


def newest_of_fit(seg: np.ndarray, degree: int) -> float:
    """The least-squares polynomial of ``degree`` through ``seg``, at its newest sample;
    too few samples for it: the newest sample itself."""
    if len(seg) <= degree:
        return float(seg[-1])
    return float(np.polyval(np.polyfit(np.arange(len(seg)), seg, degree), len(seg) - 1))


@settings(max_examples=40)
@given(signals, st.integers(3, 60), st.sampled_from([1, 2]))
def test_savgol_is_the_least_squares_fit_at_the_newest_sample(xs, window, degree):
    """Degree 1: the line (``SavitzkyGolayLinear``); degree 2: the parabola."""
    kind = SavitzkyGolayLinear if degree == 1 else SavitzkyGolayQuadratic
    got = run(kind(window), xs)
    for k, g in enumerate(got):
        seg = np.asarray(xs[max(0, k - window + 1):k + 1])
        assert g == pytest.approx(newest_of_fit(seg, degree), abs=1e-7)


def test_savgol_has_no_lag_on_a_ramp_where_the_average_lags():
    ramp = 0.001 * np.arange(200)
    sg = run(SavitzkyGolayLinear(40), ramp)
    ma = run(MovingAverage(9), ramp)
    np.testing.assert_allclose(sg[40:], ramp[40:], atol=1e-9)
    np.testing.assert_allclose(ramp[40:] - ma[40:], 0.004, atol=1e-9)  # (9−1)/2 samples


def test_default_filter_is_less_noisy_than_the_nine_point_average():
    rng = np.random.default_rng(0)
    noise = rng.normal(0.0, 1.0, 100_000)
    default = run(make_filter(DEFAULT_FILTER, 1000.0), noise)[100:]
    ma9 = run(make_filter("moving_average", 1000.0), noise)[100:]
    assert np.std(default) < np.std(ma9)
    # the theory: √((4N−2)/(N(N+1))) for the linear fit, 1/3 for the average
    assert np.std(default) == pytest.approx(np.sqrt(158 / 1640), rel=0.03)
    assert np.std(ma9) == pytest.approx(1 / 3, rel=0.03)


def test_savgol_quadratic_stays_exact_past_its_running_sums_refresh():
    xs = 1.5 + np.sin(np.arange(40_000) / 300.0)
    got = run(SavitzkyGolayQuadratic(180), xs)
    for k in (179, 16_383, 16_384, 39_999):
        seg = xs[k - 179:k + 1]
        want = np.polyval(np.polyfit(np.arange(180), seg, 2), 179)
        assert got[k] == pytest.approx(want, abs=1e-8)


def test_savgol_quadratic_holds_a_turnaround_where_the_line_overshoots():
    t = np.arange(600) * 1e-3  # a bend's top: 90 deg - 222 deg/s² t², as rad
    top = np.radians(90.0) - np.radians(222.0) * (t - 0.3) ** 2
    line = run(SavitzkyGolayLinear(180), top)
    parabola = run(SavitzkyGolayQuadratic(180), top)
    np.testing.assert_allclose(parabola[180:], top[180:], atol=1e-9)
    # the line's error: curvature x (window)² / 12, here 2 x 222 deg/s² x (0.18 s)² / 12
    assert np.degrees(line[180:] - top[180:]).mean() == pytest.approx(
        2 * 222 * 0.18 ** 2 / 12, rel=0.05)


def test_savgol_quadratic_noise_gain_is_the_theory():
    noise = np.random.default_rng(0).normal(0.0, 1.0, 100_000)
    n = 180
    got = run(make_filter("savgol_quadratic", 1000.0, {"window": n}), noise)[n:]
    assert np.std(got) == pytest.approx(
        np.sqrt((9 * n * n - 9 * n + 6) / (n * (n + 1) * (n + 2))), rel=0.03)


def test_butterworth_matches_scipy_started_in_steady_state():
    xs = np.random.default_rng(1).normal(1.0, 0.1, 500)
    sos = butter(3, 40.0, fs=1000.0, output="sos")
    want, _ = sosfilt(sos, xs, zi=sosfilt_zi(sos) * xs[0])
    got = run(make_filter("butterworth", 1000.0, {"order": 3, "cutoff_hz": 40.0}), xs)
    np.testing.assert_allclose(got, want, atol=1e-9)


@pytest.mark.parametrize("name", sorted(FILTERS))
def test_every_filter_holds_a_constant_and_resets(name):
    f = make_filter(name, 1000.0)
    assert run(f, [1.25] * 300) == pytest.approx(1.25, abs=1e-9)
    f.reset()
    assert f.update(-2.0) == pytest.approx(-2.0)


def test_one_euro_follows_fast_moves_faster_than_slow_ones():
    step = [0.0] * 50 + [1.0] * 30
    slow = run(make_filter("one_euro", 1000.0, {"beta": 0.0}), step)
    fast = run(make_filter("one_euro", 1000.0, {"beta": 5.0}), step)
    assert fast[-1] > slow[-1]


@pytest.mark.parametrize(("name", "params", "match"), [
    ("median", None, "Unknown filter 'median'"),
    ("moving_average", {"width": 3}, "no parameter width"),
    ("moving_average", {"window": 0}, "window"),
    ("moving_average", {"window": 2.5}, "window"),
    ("savgol", {"window": 1}, "window"),
    ("savgol", {"window": float("nan")}, "window"),
    ("savgol_quadratic", {"window": 2}, "window"),
    ("butterworth", {"cutoff_hz": 600.0}, "cutoff_hz"),
    ("butterworth", {"order": 0}, "order"),
    ("one_euro", {"beta": -1.0}, "beta"),
])
def test_bad_filter_choices_name_the_problem(name, params, match):
    with pytest.raises(SensingError, match=match):
        make_filter(name, 1000.0, params)


def test_bad_rate_is_refused():
    with pytest.raises(SensingError, match="sample rate"):
        make_filter("moving_average", 0.0)
