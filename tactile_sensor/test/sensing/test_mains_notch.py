"""The notch at the lamps' flicker: it finds 100 or 120 Hz by itself, removes the flicker
and its harmonics, and leaves a signal without flicker as the filter behind it gives it."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tactile_sensor.sensing.errors import SensingError
from tactile_sensor.sensing.filters import DEFAULT_FILTER, SavitzkyGolayLinear, make_filter
from tactile_sensor.sensing.mains_notch import MainsNotch

RATE = 1000.0


def lamp(t: np.ndarray, flicker_hz: float) -> np.ndarray:
    """A full-wave rectified lamp of mean 1 (all its harmonics), as sim/ambient_light's."""
    return np.pi / 2 * np.abs(np.sin(np.pi * flicker_hz * t))


def run(notch: MainsNotch, x: np.ndarray) -> np.ndarray:
    return np.array([notch.update(float(v)) for v in x])


@pytest.mark.parametrize("flicker_hz", [100.0, 120.0])
def test_it_finds_the_flicker_and_removes_it_with_its_harmonics(flicker_hz):
    t = np.arange(0.0, 3.0, 1.0 / RATE)
    x = 2.0 - 0.6 * lamp(t, flicker_hz)
    notch = MainsNotch(RATE, SavitzkyGolayLinear(40))
    out = run(notch, x)
    assert notch.flicker_hz == flicker_hz  # found after two half-second blocks
    ripple = np.ptp(out[t > 1.5])
    plain = np.ptp(run(MainsNotch(RATE, SavitzkyGolayLinear(40)), x)[t < 0.9])
    assert ripple < (0.002 if flicker_hz == 100.0 else 0.05) < plain


@settings(max_examples=20, deadline=None)
@given(st.lists(st.floats(0.5, 4.5), min_size=1, max_size=300))
def test_without_flicker_it_is_the_filter_behind_it(values):
    notch, plain = MainsNotch(RATE, SavitzkyGolayLinear(40)), SavitzkyGolayLinear(40)
    assert [notch.update(v) for v in values] == [plain.update(v) for v in values]


def test_a_ramp_is_delayed_by_half_a_flicker_period():
    t = np.arange(0.0, 4.0, 1.0 / RATE)
    x = 2.0 - 0.3 * lamp(t, 100.0) - 0.1 * np.maximum(t - 2.0, 0.0)
    out = run(MainsNotch(RATE, make_filter("none", RATE)), x)
    tail = t > 3.0
    level = np.median(out[(t > 1.5) & (t < 2.0)])  # the lamp's light averaged by the comb
    delay = (out[tail] - (level - 0.1 * (t[tail] - 2.0))) / 0.1
    assert np.ptp(out[(t > 1.5) & (t < 2.0)]) < 1e-9  # no flicker left
    assert np.median(delay) == pytest.approx(4.5e-3, abs=1e-5)  # (10 - 1) / 2 samples


def test_reset_forgets_the_flicker_and_its_window():
    notch = make_filter("savgol_mains", RATE)
    run(notch, 2.0 - 0.6 * lamp(np.arange(0.0, 1.5, 1e-3), 100.0))
    assert notch.flicker_hz == 100.0 and notch.window == 40 + 10
    notch.reset()
    assert notch.update(3.0) == pytest.approx(3.0)
    assert math.isclose(notch.flicker_hz, 100.0)  # the mains does not change with a reset


@settings(max_examples=20, deadline=None)
@given(st.floats(1.0, 240.0), st.lists(st.floats(0.5, 4.5), min_size=1, max_size=300))
def test_a_rate_that_cannot_see_the_flicker_passes_the_filter_behind_it(rate, values):
    """The default filter runs at any rate a driver may: below twice 120 Hz a flicker
    aliases, so the notch never looks for one."""
    notch, plain = MainsNotch(rate, SavitzkyGolayLinear(40)), SavitzkyGolayLinear(40)
    assert not notch.can_see_flicker and notch.window == 40
    assert [notch.update(v) for v in values] == [plain.update(v) for v in values]


def test_a_flicker_at_a_rate_that_cannot_see_it_is_not_looked_for():
    t = np.arange(0.0, 3.0, 1.0 / 200.0)
    notch = MainsNotch(200.0, make_filter("none", 200.0))
    out = run(notch, 2.0 - 0.6 * lamp(t + 1e-3, 100.0))
    assert notch.flicker_hz is None and np.allclose(out, 2.0 - 0.6 * lamp(t + 1e-3, 100.0))


@pytest.mark.parametrize("rate", [0.0, -1000.0, math.nan])
def test_a_rate_that_is_not_positive_is_refused(rate):
    with pytest.raises(SensingError, match="positive sample rate"):
        MainsNotch(rate, SavitzkyGolayLinear(40))


@pytest.mark.parametrize("level_v", [0.0, 1.99, 3.1234567, 4.99])
def test_a_steady_level_or_noise_is_never_taken_for_a_flicker(level_v):
    """The dark room: the default filter stays savgol, sample for sample."""
    noise = np.random.default_rng(0).normal(0.0, 0.01, 20_000)
    for x in (np.full(5_000, level_v), level_v + noise):
        notch = make_filter("savgol_mains", RATE)
        run(notch, x)
        assert notch.flicker_hz is None


def test_the_default_filter_is_the_notch_ahead_of_savgol():
    assert DEFAULT_FILTER == "savgol_mains"
    assert isinstance(make_filter(DEFAULT_FILTER, RATE), MainsNotch)
