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


@settings(max_examples=40)
@given(signals, st.integers(2, 50))
def test_savgol_is_the_least_squares_line_at_the_newest_sample(xs, window):
    got = run(SavitzkyGolayLinear(window), xs)
    for k, g in enumerate(got):
        seg = np.asarray(xs[max(0, k - window + 1):k + 1])
        if len(seg) == 1:
            assert g == seg[0]
            continue
        slope, intercept = np.polyfit(np.arange(len(seg)), seg, 1)
        assert g == pytest.approx(intercept + slope * (len(seg) - 1), abs=1e-7)


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
