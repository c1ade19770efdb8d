"""Servo samples and module outputs paired by their stamps."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from tactile_sensor.control.stamp_pairing import outputs_at


@given(st.floats(-1.0, 1.0), st.integers(0, 500))
def test_each_sample_takes_the_mean_of_the_outputs_stamped_around_it(
        slope: float, shuffle_seed: int):
    """A ramp sampled at 1 kHz, listed in any order: the mean around each 10 ms servo
    sample is the ramp at that sample, whatever the readings' delivery did."""
    ticks = 1000.0 + 0.01 * np.arange(1, 50)
    stamps = 1000.0 + 0.001 * np.arange(0, 600) + 0.0005
    order = np.random.default_rng(shuffle_seed).permutation(stamps.size)
    kept, means = outputs_at(ticks, stamps[order], (slope * (stamps - 1000.0))[order])
    assert kept.tolist() == list(range(ticks.size))
    assert means == pytest.approx(slope * (ticks - 1000.0), abs=1e-9)


@given(st.floats(0.1, 1.0), st.lists(st.floats(0.005, 0.4), min_size=2, max_size=30))
def test_a_gap_between_samples_does_not_lend_later_outputs_to_the_sample_before(
        slope: float, gaps: list[float]):
    """Servo samples as a starved control loop takes them (gaps of 5 ms to 0.4 s), outputs
    of a steady close at 1 kHz: each sample's mean is the ramp at that sample, within the
    1 ms between readings. A window reaching half way into a 0.38 s gap read the ramp 95 ms
    late."""
    ticks = 1000.0 + np.cumsum([0.01, *gaps])
    stamps = np.arange(999.5, ticks[-1] + 0.5, 0.001) + 0.0005
    kept, means = outputs_at(ticks, stamps, slope * (stamps - 1000.0))
    assert kept.tolist() == list(range(ticks.size))
    assert means == pytest.approx(slope * (ticks[kept] - 1000.0), abs=slope * 0.001)


def test_samples_without_a_reading_are_left_out():
    kept, means = outputs_at([1.0, 1.01, 1.02, 1.03], [0.999, 1.001, 1.021], [1.0, 3.0, 5.0])
    assert kept.tolist() == [0, 2]
    assert means.tolist() == [2.0, 5.0]
    assert outputs_at([1.0], [1.0], [7.0])[1].tolist() == [7.0]
    assert outputs_at([], [1.0], [7.0])[0].size == 0
    assert outputs_at([1.0, 2.0], [], [])[0].size == 0


def test_malformed_inputs_are_refused():
    with pytest.raises(ValueError, match="must pair up"):
        outputs_at([1.0, 2.0], [1.0], [1.0, 2.0])
    with pytest.raises(ValueError, match="must not decrease"):
        outputs_at([2.0, 1.0], [1.0], [1.0])
