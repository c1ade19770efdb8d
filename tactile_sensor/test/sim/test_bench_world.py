from __future__ import annotations

import numpy as np
import pytest

from tactile_sensor.sim.bench_world import BenchWorld
from tactile_sensor.sim.errors import SimError
from tactile_sensor.sim.profiles import parse_profile
from tactile_sensor.sim.skin_response import TabulatedSkin

D = np.linspace(0.0, 0.003, 31)
# a monotone test curve: stiffening force, falling voltage (test input, not physics)
SKIN = TabulatedSkin(D, 7.0 * (D / 0.003) ** 1.3, 1.98 - 0.49 * D / 0.003)


class RateStiffening:
    """Test viscoelastic model: adds c·dF/dt (more force when pressing faster)."""

    def __init__(self, c_s: float = 0.05) -> None:
        self.c_s = c_s
        self.reset()

    def reset(self) -> None:
        self._last = None

    def step(self, elastic_force_n: float, dt: float) -> float:
        rate = 0.0 if self._last is None else (elastic_force_n - self._last) / dt
        self._last = elastic_force_n
        return elastic_force_n + self.c_s * max(rate, 0.0)


def test_world_follows_the_profile_and_the_skin():
    world = BenchWorld(parse_profile("compression"), SKIN)
    assert world.indentation_m(4.0) == pytest.approx(0.003)
    assert world.force_n(4.0) == pytest.approx(7.0)
    assert world.photoreflector_voltage(0.5) == pytest.approx(1.98)
    assert world.photoreflector_voltage(4.0) == pytest.approx(1.49)
    t = np.linspace(0, world.duration_s, 50)
    assert world.photoreflector_voltage(t).shape == (50,)
    assert isinstance(world.force_n(1.0), float)


def test_faster_pressing_raises_force_but_not_voltage():
    forces, volts = [], []
    for speed in (0.0001, 0.001, 0.01):
        world = BenchWorld(parse_profile(f"ramp:speed={speed}"), SKIN, RateStiffening())
        t = np.linspace(0, world.duration_s, 20001)
        forces.append(world.force_n(t).max())
        volts.append(world.photoreflector_voltage(t).min())
    assert forces[0] < forces[1] < forces[2]
    assert volts == pytest.approx([volts[0]] * 3)


def test_loop_repeats_and_plain_worlds_rest_after_the_end():
    profile = parse_profile("compression")
    looped = BenchWorld(profile, SKIN, loop=True)
    once = BenchWorld(profile, SKIN)
    assert looped.indentation_m(4.0 + profile.duration_s) == pytest.approx(0.003)
    assert once.indentation_m(4.0 + profile.duration_s) == 0.0


def test_bad_grid_and_bad_table():
    with pytest.raises(SimError, match="grid_hz"):
        BenchWorld(parse_profile("compression"), SKIN, grid_hz=0.0)
    with pytest.raises(SimError, match="strictly increasing"):
        TabulatedSkin([0.0, 0.0], [0.0, 1.0], [2.0, 1.0])
    with pytest.raises(SimError, match="equal length"):
        TabulatedSkin([0.0, 1.0], [0.0], [2.0, 1.0])
    with pytest.raises(SimError, match="NaN"):
        TabulatedSkin([0.0, 1.0], [0.0, np.nan], [2.0, 1.0])


def test_physics_adapters_give_the_papers_trends():
    from tactile_sensor.physics.params import PhysicsParams
    from tactile_sensor.physics.prediction import curve_from_sweep
    from tactile_sensor.physics.viscoelastic import RateDependentForce

    params = PhysicsParams()
    # a mechanical sweep given as test input; the physics optics turn it into volts
    d = np.linspace(0.0, 0.003, 13)
    curve = curve_from_sweep(params, d, 7.0 * (d / 0.003) ** 1.3, 0.4 * d, nodes=0,
                             seconds=0.0)
    skin = TabulatedSkin.from_prediction_curve(curve)
    assert skin.source == f"fem:{curve.digest}"
    np.testing.assert_allclose(skin.voltage_v(d), curve.voltage_v)
    peaks = []
    for speed in (0.0001, 0.001, 0.01):
        world = BenchWorld(parse_profile(f"ramp:speed={speed},rest=0.5"), skin,
                           RateDependentForce.from_params(params))
        t = np.linspace(0.0, world.duration_s, 5001)
        peaks.append((world.force_n(t).max(), world.photoreflector_voltage(t).min()))
    forces, volts = zip(*peaks, strict=True)
    assert forces[0] <= forces[1] < forces[2]
    assert volts == pytest.approx([volts[0]] * 3)


@pytest.mark.parametrize("speed", [0.0001, 0.001, 0.01])
def test_output_play_delays_the_output_by_width_over_speed(speed):
    from tactile_sensor.sim.profiles import LoadProfile

    profile = LoadProfile(depth_m=0.003, speeds_m_s=(speed,), cycles=1, rest_s=0.5)
    plain = BenchWorld(profile, SKIN, grid_hz=10_000.0)
    played = BenchWorld(profile, SKIN, grid_hz=10_000.0, output_play_m=6.5e-5)
    t = np.linspace(0.0, profile.duration_s, 200_001)
    half = (SKIN.voltage_v(0.0) + SKIN.voltage_v(0.003)) / 2  # voltage falls with pressing

    def crossing(world: BenchWorld) -> float:
        return float(t[np.argmax(world.photoreflector_voltage(t) <= half)])

    assert crossing(played) - crossing(plain) == pytest.approx(6.5e-5 / speed, rel=0.05)
    # unloading ends where it started: no lasting offset
    assert played.photoreflector_voltage(profile.duration_s) == pytest.approx(
        plain.photoreflector_voltage(profile.duration_s))


def test_bad_play_is_refused():
    with pytest.raises(SimError, match="output_play_m"):
        BenchWorld(parse_profile("compression"), SKIN, output_play_m=-1e-5)


def test_a_stiffer_skin_pushes_back_harder_at_the_same_voltage():
    stiff = BenchWorld(parse_profile("compression"), SKIN, stiffness_ratio=1.15)
    assert stiff.force_n(4.0) == pytest.approx(1.15 * 7.0)
    assert stiff.photoreflector_voltage(4.0) == pytest.approx(1.49)


@pytest.mark.parametrize("ratio", [0.0, float("nan"), 6.0])
def test_an_impossible_stiffness_is_refused(ratio):
    with pytest.raises(SimError, match=r"skin\.stiffness_ratio"):
        BenchWorld(parse_profile("compression"), SKIN, stiffness_ratio=ratio)
