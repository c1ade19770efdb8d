"""The Prony rate term: the paper's Fig. 9 speed effect, streaming = batch, relaxation."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tactile_sensor.physics.errors import PhysicsError
from tactile_sensor.physics.params import PhysicsParams
from tactile_sensor.physics.viscoelastic import RateDependentForce

STIFFNESS_N_PER_M = 7.0 / 3e-3  # a linear elastic curve: ~7 N at 3 mm
DEPTH_M = 3e-3


def ramp_force_at_depth(speed_m_s: float, dt: float = 1e-3) -> tuple[float, float]:
    """(rate-dependent force, elastic force) at the end of a ramp to 3 mm."""
    duration = DEPTH_M / speed_m_s
    t = np.linspace(0.0, duration, max(round(duration / dt), 50) + 1)
    elastic = STIFFNESS_N_PER_M * speed_m_s * t
    force = RateDependentForce.from_params(PhysicsParams()).force_history(t, elastic)
    return float(force[-1]), float(elastic[-1])


def test_force_rises_with_indentation_speed_by_a_few_percent():
    slow, elastic = ramp_force_at_depth(0.1e-3)
    mid, _ = ramp_force_at_depth(1e-3)
    fast, _ = ramp_force_at_depth(10e-3)
    assert fast > mid > slow > elastic
    assert 0.02 < fast / elastic - 1 < 0.09  # "a few percent" at 10 mm/s
    assert slow / elastic - 1 < 0.01  # quasi-static at 0.1 mm/s


def test_ramp_matches_closed_form():
    """For a linear ramp F_el = k v t each term is g k v tau (1 - exp(-t / tau))."""
    params = PhysicsParams()
    speed = 1e-3
    force, elastic = ramp_force_at_depth(speed, dt=0.05)
    t = DEPTH_M / speed
    extra = sum(g * STIFFNESS_N_PER_M * speed * tau * (1 - np.exp(-t / tau))
                for g, tau in zip(params.prony_g, params.prony_tau, strict=True))
    assert force == pytest.approx(elastic + extra, rel=1e-9)


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(2, 60))
def test_streaming_step_equals_force_history(seed, n):
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.uniform(0.0, 0.2, n))
    elastic = np.cumsum(rng.normal(0.0, 0.5, n))
    model = RateDependentForce([0.05, 0.04], [0.1, 1.5])
    batch = model.force_history(t, elastic)
    stream = [model.step(float(elastic[0]), 0.0)]
    stream += [model.step(float(f), float(dt))
               for f, dt in zip(elastic[1:], np.diff(t), strict=True)]
    assert np.allclose(stream, batch, rtol=1e-12, atol=1e-12)


def test_force_history_leaves_a_streaming_state_untouched():
    model = RateDependentForce([0.1], [1.0])
    model.step(0.0, 0.0)
    model.step(1.0, 0.01)
    reference = RateDependentForce([0.1], [1.0])
    reference.step(0.0, 0.0)
    reference.step(1.0, 0.01)
    model.force_history(np.linspace(0, 1, 11), np.linspace(0, 5, 11))
    assert model.step(1.0, 0.1) == reference.step(1.0, 0.1)


def test_force_relaxes_to_the_elastic_force_during_a_hold():
    model = RateDependentForce.from_params(PhysicsParams())
    dt = 1e-3
    ramp_t = np.arange(0.0, 0.3 + dt / 2, dt)  # 10 mm/s to 3 mm
    hold_t = 0.3 + np.arange(1, 10001) * dt  # 10 s hold
    t = np.concatenate([ramp_t, hold_t])
    elastic = STIFFNESS_N_PER_M * np.minimum(10e-3 * t, DEPTH_M)
    force = model.force_history(t, elastic)
    peak = force[ramp_t.size - 1]
    assert peak > 1.02 * elastic[-1]
    assert np.all(np.diff(force[ramp_t.size:]) <= 1e-12)  # monotone relaxation
    assert force[-1] == pytest.approx(elastic[-1], rel=1e-3)


def test_step_change_with_zero_dt_adds_the_instant_modulus():
    model = RateDependentForce([0.05, 0.04], [0.1, 1.5])
    model.step(0.0, 0.0)
    assert model.step(10.0, 0.0) == pytest.approx(10.0 * 1.09)


def test_reset_forgets_the_history():
    model = RateDependentForce([0.1], [1.0])
    model.step(0.0, 0.0)
    model.step(5.0, 0.01)
    model.reset()
    assert model.step(5.0, 0.01) == 5.0


@pytest.mark.parametrize(("g", "tau"), [
    ([0.1, 0.2], [1.0]),  # lengths differ
    ([-0.1], [1.0]),  # negative modulus
    ([0.1], [0.0]),  # zero time
    ([0.1], [float("inf")]),  # infinite time
    ([float("nan")], [1.0]),
    ([[0.1]], [[1.0]]),  # not 1-D
])
def test_invalid_prony_series_is_refused(g, tau):
    with pytest.raises(PhysicsError):
        RateDependentForce(g, tau)


@pytest.mark.parametrize("dt", [-1e-3, float("nan"), float("inf")])
def test_invalid_time_step_is_refused(dt):
    model = RateDependentForce([0.1], [1.0])
    model.step(0.0, 0.0)
    with pytest.raises(PhysicsError, match="Time step"):
        model.step(1.0, dt)


def test_force_history_refuses_bad_arrays():
    model = RateDependentForce([0.1], [1.0])
    with pytest.raises(PhysicsError, match="equal-length"):
        model.force_history([0.0, 1.0], [0.0])
    with pytest.raises(PhysicsError, match="increasing"):
        model.force_history([0.0, 1.0, 0.5], [0.0, 1.0, 2.0])
