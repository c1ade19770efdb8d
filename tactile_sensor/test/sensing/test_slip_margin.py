"""The friction margin's filter and threshold (sensing/slip_margin.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.signal import butter, lfilter

from tactile_sensor.sensing.errors import SensingError
from tactile_sensor.sensing.slip_margin import (
    LowPass2,
    MarginFilter,
    MarginNoise,
    margin_sigma_n,
    threshold_sigmas,
)


@settings(max_examples=20, deadline=None)
@given(cutoff=st.floats(1.0, 40.0), seed=st.integers(0, 1000))
def test_the_low_pass_is_scipy_s_butterworth(cutoff: float, seed: int) -> None:
    x = np.random.default_rng(seed).standard_normal(300)
    b, a = butter(2, cutoff / 50.0)
    expected = lfilter(b, a, x - x[0]) + x[0]  # settled on the first value
    lp = LowPass2(cutoff, 100.0)
    assert [lp.update(float(v)) for v in x] == pytest.approx(list(expected), abs=1e-9)


def test_the_margin_filter_gives_the_grip_and_the_shear_s_magnitude() -> None:
    f = MarginFilter(20.0, 100.0)
    fn, ft = f.update(2.0, 0.3, -0.4)
    assert (fn, ft) == pytest.approx((2.0, 0.5))


def test_the_threshold_is_the_study_s() -> None:
    """docs/gripper.md: the least margin at 20 Hz is 0.57 / 0.65 / 0.92 N at mu 0.3 / 0.5
    / 1.0 (2 k sigma_m with 55.0 mN of Ft and 80.7 mN of Fn)."""
    noise = MarginNoise(0.0389 / math.sqrt(10.0), 0.0570 / math.sqrt(10.0))
    for mu, least in ((0.3, 0.57), (0.5, 0.65), (1.0, 0.92)):
        assert 2 * noise.threshold_n(mu, 20.0) == pytest.approx(least, abs=0.01)
    assert margin_sigma_n(0.0, 0.1, 5.0) == pytest.approx(0.1)


def test_bad_settings_are_refused_in_one_sentence() -> None:
    with pytest.raises(SensingError, match="must be > 0"):
        threshold_sigmas(0.0, 10.0)
    with pytest.raises(SensingError, match="noise densities"):
        MarginNoise(0.0, 0.01)
    with pytest.raises(SensingError, match="twice it"):
        LowPass2(60.0, 100.0)
