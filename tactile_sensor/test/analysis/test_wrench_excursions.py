"""Per-excursion gain and RMSE of a wrench component (analysis/array/excursions.py)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from tactile_sensor.analysis.array.excursions import (
    EXCURSION_FRACTION,
    excursion_metrics,
    excursions,
    stretches,
    worst_gain,
)


def pulses(amplitudes: list[float], width: int = 41, gap: int = 30) -> np.ndarray:
    """Triangular pulses of the given amplitudes (signed) with rest between them."""
    tri = 1.0 - np.abs(np.linspace(-1.0, 1.0, width))
    parts = [np.zeros(gap)]
    for a in amplitudes:
        parts += [a * tri, np.zeros(gap)]
    return np.concatenate(parts)


def test_stretches_are_the_runs_of_true():
    assert stretches(np.array([0, 1, 1, 0, 1, 0, 0, 1], bool)) == [(1, 3), (4, 5), (7, 8)]
    assert stretches(np.zeros(4, bool)) == []


@settings(max_examples=60, deadline=None)
@given(amplitudes=st.lists(st.floats(0.3, 5.0).map(float) | st.floats(-5.0, -0.3), min_size=1,
                           max_size=5),
       gains=st.lists(st.floats(0.2, 2.0), min_size=5, max_size=5))
def test_each_excursion_reads_the_gain_it_was_given(amplitudes, gains):
    reference = pulses(amplitudes)
    estimate = pulses([a * g for a, g in zip(amplitudes, gains, strict=False)])
    found = excursions(estimate, reference)
    top = float(np.max(np.abs(reference)))
    peak = float(np.max(pulses([1.0])))           # the sampled triangle's peak
    wanted = [g for a, g in zip(amplitudes, gains, strict=False)
              if abs(a) * peak > EXCURSION_FRACTION * top]
    assert [round(x.gain, 9) for x in found] == [round(g, 9) for g in wanted]
    for x, g in zip(found, wanted, strict=True):
        r = reference[x.start:x.stop]
        assert np.all(np.abs(r) > EXCURSION_FRACTION * top)
        assert np.isclose(x.rmse, abs(g - 1.0) * np.sqrt(np.mean(r ** 2)))


@settings(max_examples=40, deadline=None)
@given(offset=st.floats(-0.5, 0.5), noise=st.floats(0.0, 0.05), seed=st.integers(0, 99))
def test_noise_does_not_move_the_gain_an_offset_does_split_it_by_sign(offset, noise, seed):
    reference = pulses([2.0, -2.0], width=401)
    estimate = reference + offset + np.random.default_rng(seed).normal(0, noise,
                                                                        reference.size)
    up, down = excursions(estimate, reference)
    assert abs(up.gain - (1 + offset * _mean_over_square(reference[up.start:up.stop])))\
        < 0.02
    assert abs((up.gain - 1) + (down.gain - 1)) < 0.02       # an offset: up high, down low


def _mean_over_square(r: np.ndarray) -> float:
    return float(np.sum(r) / np.sum(r ** 2))


def test_a_quiet_component_has_no_excursion_and_nan_estimate_no_gain():
    assert excursions(np.ones(10), np.zeros(10)) == []
    found = excursions(np.full(130, np.nan), pulses([1.0]))
    assert len(found) == 1 and np.isnan(found[0].gain) and np.isnan(found[0].rmse)


def test_worst_gain_is_the_one_farthest_from_one():
    assert worst_gain([1.02, 0.9, 1.08, float("nan")]) == 0.9
    assert worst_gain([float("nan")]) is None


def test_metrics_name_every_component_with_times_and_the_worst_gain():
    reference = np.column_stack([pulses([1.0, -1.0]), pulses([0.0, 2.0])])
    estimate = reference * np.array([0.5, 1.0])
    t = np.arange(reference.shape[0]) * 0.01
    m = excursion_metrics(("fx", "tz"), estimate, reference, t)
    assert [x["gain"] for x in m["fx"]] == [0.5, 0.5] and len(m["tz"]) == 1
    assert m["worst_gain"] == 0.5 and m["fraction_of_peak"] == EXCURSION_FRACTION
    assert 0.3 < m["fx"][0]["start_s"] < m["fx"][0]["end_s"] < 0.7


def test_rest_noise_is_the_estimates_spread_where_the_gauge_reads_no_load():
    reference = np.column_stack([pulses([1.0]), pulses([-2.0])])
    rng = np.random.default_rng(0)
    estimate = reference + rng.normal(0, [0.01, 0.03], reference.shape)
    estimate[:, 1] += 0.5 * (reference[:, 0] != 0)           # loaded: not rest
    m = excursion_metrics(("fx", "tz"), estimate, reference, np.arange(reference.shape[0]))
    rest = m["rest_noise"]
    assert rest["samples"] == 62                   # the rest either side, the pulse's ends
    assert abs(rest["fx"] - 0.01) < 0.004
    assert abs(rest["tz"] - 0.03) < 0.012
