"""Photoreflector model against the paper's eq. (1) and Fig. 3(b), and the optics fit."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from tactile_sensor.physics.errors import PhysicsError
from tactile_sensor.physics.optics import (
    FIT_OFFSET_V,
    FIT_SLOPE_V_PER_M,
    PIGMENTS,
    Photoreflector,
    fit_optics,
)

SWEEP_M = np.linspace(0.0, 10e-3, 2001)


def test_75_percent_white_follows_paper_fit_over_1_to_2_mm():
    x = np.linspace(1e-3, 2e-3, 401)
    fit = FIT_SLOPE_V_PER_M * x + FIT_OFFSET_V
    span = fit[-1] - fit[0]  # 1.9374 V over the window
    deviation = np.abs(Photoreflector(75.0).voltage(x) - fit)
    assert deviation.max() <= 0.02 * span


@pytest.mark.parametrize("white", PIGMENTS)
def test_voltage_rises_monotonically_with_distance(white):
    v = Photoreflector(white).voltage(SWEEP_M)
    assert np.all(np.diff(v) >= 0)
    assert v[-1] - v[0] > 0.5  # a real swing, not a flat line


@pytest.mark.parametrize("white", PIGMENTS)
@pytest.mark.parametrize("supply", [3.3, 5.0])
def test_voltage_saturates_within_the_rails(white, supply):
    sensor = Photoreflector(white, supply)
    v = sensor.voltage(np.linspace(0.0, 30e-3, 3001))
    assert np.all(v >= 0.0)
    assert np.all(v <= supply)
    far = sensor.voltage(np.array([15e-3, 20e-3, 30e-3]))
    assert np.allclose(far, far[-1]) and far[-1] > 0.98 * supply  # little light: upper rail


def test_white_skins_reach_the_lower_rail_at_contact():
    for white in (100.0, 75.0):
        assert Photoreflector(white).voltage(0.0) < 0.05


def test_swing_grows_with_whiteness():
    swings = {w: float(np.ptp(Photoreflector(w).voltage(SWEEP_M))) for w in PIGMENTS}
    ordered = [swings[w] for w in sorted(PIGMENTS)]  # 0 % ... 100 %
    assert all(b >= a for a, b in itertools.pairwise(ordered))
    assert swings[75.0] > swings[50.0] > swings[25.0] > swings[0.0]


def test_slope_matches_paper_inside_window():
    slope = Photoreflector(75.0).slope(np.array([1.25e-3, 1.5e-3, 1.75e-3]))
    assert np.allclose(slope, FIT_SLOPE_V_PER_M, rtol=0.03)


@pytest.mark.parametrize("kwargs", [dict(pigment_white=101.0), dict(pigment_white=-1.0),
                                    dict(supply_voltage=0.0), dict(supply_voltage=30.0)])
def test_invalid_photoreflector_is_refused(kwargs):
    with pytest.raises(PhysicsError):
        Photoreflector(**kwargs)


@pytest.mark.parametrize("distance", [-1e-4, float("nan"), float("inf")])
def test_invalid_distance_is_refused(distance):
    with pytest.raises(PhysicsError, match="finite and >= 0"):
        Photoreflector().voltage(np.array([1e-3, distance]))


def test_fit_recovers_the_linear_window_without_noise():
    x = np.linspace(0.0, 10e-3, 101)
    fit = fit_optics(x, Photoreflector(75.0).voltage(x))
    assert fit.window_m == pytest.approx((1e-3, 2e-3), abs=1e-4)
    assert fit.slope_v_per_m == pytest.approx(FIT_SLOPE_V_PER_M, rel=0.01)
    assert fit.offset_v == pytest.approx(FIT_OFFSET_V, abs=0.02)
    assert fit.max_deviation_v < 0.01


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), sigma=st.floats(0.0, 0.01))
@example(seed=708, sigma=0.01)  # picked 3.6-4.6 mm when the window was chosen by absolute error
def test_fit_recovers_window_and_slope_from_noisy_samples(seed, sigma):
    rng = np.random.default_rng(seed)
    x = rng.permutation(np.linspace(0.0, 10e-3, 101))  # order must not matter
    v = Photoreflector(75.0).voltage(x) + rng.normal(0.0, sigma, x.size)
    fit = fit_optics(x, v)
    low, high = fit.window_m
    assert 0.5e-3 <= low <= 1.5e-3  # overlaps the paper window [1, 2] mm by half or more
    assert high - low == pytest.approx(1e-3, abs=1e-4)
    assert fit.slope_v_per_m == pytest.approx(FIT_SLOPE_V_PER_M, rel=0.05)
    assert np.all(np.diff(fit.voltage_v) >= 0)  # the smoothed curve is monotone
    mid = fit.voltage(1.5e-3)
    assert mid == pytest.approx(FIT_SLOPE_V_PER_M * 1.5e-3 + FIT_OFFSET_V, abs=0.05)


def test_fit_needs_at_least_four_points():
    with pytest.raises(PhysicsError, match="at least 4"):
        fit_optics([1e-3, 2e-3, 3e-3], [0.1, 1.0, 2.0])


def test_fit_needs_equal_lengths():
    with pytest.raises(PhysicsError, match="equal-length"):
        fit_optics(np.linspace(0, 5e-3, 10), np.linspace(0, 5, 9))


def test_fit_refuses_nan():
    x = np.linspace(0.0, 5e-3, 20)
    v = Photoreflector().voltage(x)
    v[5] = np.nan
    with pytest.raises(PhysicsError, match="NaN"):
        fit_optics(x, v)


def test_fit_refuses_falling_data():
    x = np.linspace(0.0, 5e-3, 20)
    with pytest.raises(PhysicsError, match="does not rise"):
        fit_optics(x, 5.0 - Photoreflector().voltage(x))


def test_fit_refuses_a_range_too_short_for_the_window():
    x = np.linspace(1e-3, 1.5e-3, 20)
    with pytest.raises(PhysicsError, match="wider distance range"):
        fit_optics(x, Photoreflector().voltage(x))


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(-5.0, 5.0), min_size=3, max_size=12),
       st.lists(st.floats(0.05, 2.0), min_size=11, max_size=11))
@example([-1.0, -0.9188, 0.0499, 1.0186, 1.9873, 2.90, 3.60, 4.40, 4.75, 4.93, 4.99, 5.0,
          5.0], [0.5] * 12)
@example([0.0, 1.0, 1.0, 0.0], [1.0, 0.1, 3.0])   # flat secant and an extremum
def test_light_curve_interpolation_matches_scipy_pchip(values, widths):
    """The numpy PCHIP behind the light curve gives SciPy's PchipInterpolator's values."""
    from scipy.interpolate import PchipInterpolator

    from tactile_sensor.physics.optics import _Pchip

    y = np.asarray(values)
    x = np.concatenate([[0.0], np.cumsum(widths[:y.size - 1])])
    query = np.concatenate([np.linspace(x[0], x[-1], 501), x])
    expected = PchipInterpolator(x, y)(query)
    scale = max(1.0, float(np.abs(y).max()))
    assert np.allclose(_Pchip(x, y)(query), expected, rtol=0.0, atol=1e-12 * scale)


def test_a_secant_near_zero_gives_a_flat_slope_without_a_warning():
    """Its term of the harmonic mean overflows to inf, and the mean goes to 0, SciPy's
    limit: the intended value, not a RuntimeWarning in the user's log."""
    import warnings

    from tactile_sensor.physics.optics import _Pchip

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        pchip = _Pchip(np.array([0.0, 1.0, 2.0, 3.0]), np.array([0.0, 1e-310, 1.0, 2.0]))
    assert pchip(np.array([1.0]))[0] == pytest.approx(1e-310, abs=1e-300)


@pytest.mark.slow  # a fresh interpreter, to see what importing the optics imports
def test_the_light_curve_loads_without_scipy_interpolate():
    """A cold model sweep does not pay for importing scipy.interpolate (its optics)."""
    import subprocess
    import sys

    code = ("import sys; import tactile_sensor.physics.optics; "
            "print('scipy.interpolate' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.strip()
    assert out == "False"
