"""The array skin (grid interpolation) and the three-axis bench world, on the FEM's own grid
(four modules, cached like the curve; a cold cache computes it once, ~1 min)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tactile_sensor.physics.array_grid import load_or_compute_grid
from tactile_sensor.physics.params import PhysicsParams
from tactile_sensor.physics.prediction import module_output
from tactile_sensor.physics.viscoelastic import RateDependentForce
from tactile_sensor.sim.array_world import ArrayBenchWorld, ArraySkin, stage_path
from tactile_sensor.sim.errors import SimError
from tactile_sensor.sim.profiles import LoadProfile, ShearProfile, array_profile_from_protocol
from tactile_sensor.sim.skin_block import filtered_rate_force

PARAMS = PhysicsParams(modules="front,back,left,right")
FACES = ("front", "back", "left", "right")
MIRROR_X = [0, 1, 3, 2]  # x -> -x swaps left and right
MIRROR_Y = [1, 0, 2, 3]  # y -> -y swaps front and back


@pytest.fixture(scope="module")
def grid():
    return load_or_compute_grid(PARAMS)


@pytest.fixture(scope="module")
def skin(grid):
    rest = float(module_output(PARAMS, 0.0)[1])
    return ArraySkin(grid, rest, source="test")


def test_from_params_reads_the_cached_grid_and_the_rest_voltage(skin):
    built = ArraySkin.from_params(PARAMS)
    assert built.faces == FACES
    # the photoreflector's rest voltage: the single-module curve's voltage at 0
    assert built.rest_voltage_v == pytest.approx(skin.rest_voltage_v)
    assert built.rest_voltage_v == pytest.approx(float(module_output(PARAMS, 0.0)[1]))
    assert built.max_shear_ratio == pytest.approx(PARAMS.array_shear_ratio)
    assert built.max_indentation_m == pytest.approx(PARAMS.max_indentation)
    assert built.directions == PARAMS.array_directions


def test_exact_at_every_grid_point(grid, skin):
    state = skin.state(grid.indentation_m, grid.shear_x_m, grid.shear_y_m)
    expected = np.column_stack([grid.output_matrix(), grid.force_matrix()])
    np.testing.assert_allclose(state, expected, atol=1e-12, rtol=1e-9)


def test_rest_and_no_contact_give_nothing(skin):
    assert np.all(skin.state(0.0, 0.0, 0.0) == 0.0)
    assert np.all(skin.state(0.0, 0.004, -0.002) == 0.0)   # lateral motion without contact
    assert np.all(skin.state(-0.001, 0.0, 0.0) == 0.0)     # probe lifted off
    np.testing.assert_allclose(skin.voltages_v(0.0), [skin.rest_voltage_v] * 4)


def test_voltages_are_rest_minus_outputs(skin):
    d, sx, sy = 0.0021, 0.0013, -0.0024
    np.testing.assert_allclose(skin.voltages_v(d, sx, sy),
                               skin.rest_voltage_v - skin.outputs_v(d, sx, sy))
    assert skin.force_n(d, sx, sy).shape == (3,)
    assert skin.outputs_v([d, d], [sx, 0], [sy, 0]).shape == (2, 4)


def test_plus_x_and_minus_x_mirror_left_right_and_flip_fx(skin):
    plus, minus = skin.state(0.003, 0.006, 0.0), skin.state(0.003, -0.006, 0.0)
    np.testing.assert_allclose(minus[:4], plus[:4][MIRROR_X], atol=1e-12)
    assert minus[4] == pytest.approx(-plus[4]) and plus[4] > 0.5
    assert minus[6] == pytest.approx(plus[6])
    # the face the probe moves toward bulges out, the opposite one draws in (less output)
    out = dict(zip(FACES, plus[:4], strict=True))
    assert out["right"] > out["front"] > out["left"]


@settings(max_examples=150, deadline=None)
@given(d=st.floats(0.0, 0.0045), sx=st.floats(-0.012, 0.012), sy=st.floats(-0.012, 0.012))
def test_mirror_symmetry_holds_between_grid_points(skin, d, sx, sy):
    s, mx, my = skin.state(d, sx, sy), skin.state(d, -sx, sy), skin.state(d, sx, -sy)
    np.testing.assert_allclose(mx[:4], s[:4][MIRROR_X], atol=1e-9)
    np.testing.assert_allclose(mx[4:], s[4:] * [-1, 1, 1], atol=1e-8)
    np.testing.assert_allclose(my[:4], s[:4][MIRROR_Y], atol=1e-9)
    np.testing.assert_allclose(my[4:], s[4:] * [1, -1, 1], atol=1e-8)


def test_shear_is_clamped_beyond_the_slip_ratio(skin):
    d = 0.002
    limit = skin.state(d, 3.0 * d * np.cos(0.4), 3.0 * d * np.sin(0.4))
    for ratio in (3.5, 10.0, 1000.0):
        np.testing.assert_allclose(
            skin.state(d, ratio * d * np.cos(0.4), ratio * d * np.sin(0.4)), limit)
    assert not np.allclose(skin.state(d, 2.0 * d, 0.0), skin.state(d, 3.0 * d, 0.0))


def test_beyond_the_deepest_level_outputs_hold_and_forces_keep_their_slope(skin, grid):
    d_max = skin.max_indentation_m
    at, beyond, below = (skin.state(d, 0.5 * d, 0.0) for d in (d_max, 1.5 * d_max,
                                                                 5 / 6 * d_max))
    # r = 0.5 at every depth: outputs hold the d_max value at that ratio
    np.testing.assert_allclose(beyond[:4], at[:4])
    slope = (at[4:] - below[4:]) / (d_max / 6)
    np.testing.assert_allclose(beyond[4:], at[4:] + slope * 0.5 * d_max, rtol=1e-9)
    assert beyond[6] > at[6]


@settings(max_examples=200, deadline=None)
@given(d=st.floats(0.0, 0.005), sx=st.floats(-0.015, 0.015), sy=st.floats(-0.015, 0.015),
       hx=st.floats(-1e-6, 1e-6), hy=st.floats(-1e-6, 1e-6), hd=st.floats(-1e-6, 1e-6))
def test_finite_and_continuous_everywhere(skin, d, sx, sy, hx, hy, hd):
    """Lipschitz: a 1 um step moves nothing by more than the steepest grid slope allows
    (a jump, e.g. at the centre, first contact or the periodic seam, would break it)."""
    a = skin.state(d, sx, sy)
    b = skin.state(d + hd, sx + hx, sy + hy)
    assert np.all(np.isfinite(a)) and np.all(np.isfinite(b))
    step = max(abs(hx), abs(hy), abs(hd))
    # steepest slopes on the grid: under 0.1 V and 1.5 N per 0.5 mm; 20x margin
    bound = np.array([0.1] * 4 + [1.5] * 3) / 0.0005 * 20.0
    assert np.all(np.abs(b - a) <= bound * step + 1e-12)


def test_bad_inputs_are_refused(grid, skin):
    with pytest.raises(SimError, match="finite"):
        skin.state(float("nan"), 0.0, 0.0)
    with pytest.raises(SimError, match="rest_voltage_v"):
        ArraySkin(grid, float("inf"))
    partial = SimpleNamespace(**{k: getattr(grid, k) for k in (
        "indentation_m", "shear_x_m", "shear_y_m", "force_x_n", "force_y_n", "force_n",
        "direction", "level", "step", "digest")}, outputs_v=dict(grid.outputs_v))
    keep = grid.direction != 3                      # a direction missing
    for name in ("indentation_m", "shear_x_m", "shear_y_m", "force_x_n", "force_y_n",
                 "force_n", "direction", "level", "step"):
        setattr(partial, name, getattr(grid, name)[keep])
    partial.outputs_v = {f: v[keep] for f, v in grid.outputs_v.items()}
    with pytest.raises(SimError, match="incomplete"):
        ArraySkin(partial, 2.0)


# -- the world ---------------------------------------------------------------------------------


def test_slow_gauge_reads_the_grid_forces(skin):
    """At 0.1 mm/s the rate effect is negligible: the gauge is the grid's force."""
    profile = ShearProfile(depth_m=0.002, speed_m_s=0.0001, amplitude_m=0.004, directions=4,
                           rest_s=0.5)
    world = ArrayBenchWorld(profile, skin, RateDependentForce.from_params(PARAMS),
                            grid_hz=200.0)
    t = np.linspace(0.0, world.duration_s, 4001)
    stage = world.stage_m(t)
    expected = skin.force_n(stage[:, 0], stage[:, 1], stage[:, 2])
    span = expected.max(axis=0) - expected.min(axis=0)
    assert np.all(np.abs(world.force_n(t) - expected).max(axis=0) < 0.01 * span)
    assert np.abs(world.force_n(t) - expected).max() > 1e-5  # the rate effect is there


def test_faster_shear_raises_the_lateral_force(skin):
    peaks = []
    for speed in (0.0001, 0.01):
        profile = ShearProfile(depth_m=0.002, speed_m_s=speed, amplitude_m=0.004,
                               directions=4, rest_s=0.1)
        world = ArrayBenchWorld(profile, skin, RateDependentForce.from_params(PARAMS))
        peaks.append(world.force_n(np.linspace(0, world.duration_s, 20001))[:, 0].max())
    assert peaks[1] > peaks[0] * 1.01


def test_world_stage_voltages_and_shapes(skin):
    profile = array_profile_from_protocol("shear")
    world = ArrayBenchWorld(profile, skin, output_play_m=PARAMS.output_play)
    assert world.duration_s == pytest.approx(104.0)
    t = np.linspace(0, world.duration_s, 77)
    assert world.photoreflector_voltage(t).shape == (77, 4)
    assert world.photoreflector_voltage(3.0).shape == (4,)
    assert world.force_n(t).shape == (77, 3) and world.stage_m(t).shape == (77, 3)
    assert isinstance(world.indentation_m(4.0), float)
    # before the start and after the end the stage rests where the run starts and ends
    np.testing.assert_allclose(world.stage_m([-1.0, 1e6]), [[0.0] * 3, [0.0] * 3])
    np.testing.assert_allclose(world.photoreflector_voltage(-1.0), [skin.rest_voltage_v] * 4)
    np.testing.assert_allclose(world.stage_m(t), stage_path(profile, t), atol=1e-12)
    np.testing.assert_allclose(world.photoreflector_voltage(0.5), [skin.rest_voltage_v] * 4)
    # at the +x extreme (4 + 6 s): the modules read the skin at the stage's state, the
    # indentation through the play (it trails by its width once the press stopped)
    np.testing.assert_allclose(world.photoreflector_voltage(10.0), skin.voltages_v(
        0.003 - PARAMS.output_play, 0.006, 0.0), atol=1e-9)
    # the output play: while pressing, the modules trail the indentation
    assert world.photoreflector_voltage(2.0)[0] > skin.voltages_v(0.001)[0]


def test_compression_on_the_array_presses_without_shear(skin):
    world = ArrayBenchWorld(array_profile_from_protocol("compression"), skin)
    assert world.duration_s == pytest.approx(8.0)
    f = world.force_n(4.0)
    assert f[0] == 0.0 and f[1] == 0.0 and f[2] == pytest.approx(skin.force_n(0.003)[2])
    v = world.photoreflector_voltage(4.0)
    np.testing.assert_allclose(v, [v[0]] * 4)  # all four faces alike


def test_world_refuses_a_path_beyond_the_slip_limit_and_bad_settings(skin):
    with pytest.raises(SimError, match="array_shear_ratio"):
        ArrayBenchWorld(ShearProfile(depth_m=0.002, amplitude_m=0.0061), skin)
    with pytest.raises(SimError, match="grid_hz"):
        ArrayBenchWorld(LoadProfile(), skin, grid_hz=0.5)
    with pytest.raises(SimError, match="output_play_m"):
        ArrayBenchWorld(LoadProfile(), skin, output_play_m=0.01)


def test_rate_filter_matches_the_streaming_model():
    model = RateDependentForce.from_params(PARAMS)
    t = np.linspace(0.0, 5.0, 5001)
    f = np.interp(t, [0, 1, 2, 3, 5], [0.0, 0.0, 7.0, -2.0, 0.0])
    np.testing.assert_allclose(filtered_rate_force(model, t, f), model.force_history(t, f),
                               atol=1e-12)


def test_loop_repeats(skin):
    world = ArrayBenchWorld(ShearProfile(directions=4), skin, loop=True)
    np.testing.assert_allclose(world.stage_m(10.0 + world.duration_s), world.stage_m(10.0))


def test_the_press_skin_is_the_grids_pure_press(grid, skin):
    press = skin.press_skin()
    pure = grid.level == 0
    d, fz = grid.indentation_m[pure], grid.force_n[pure]
    assert [press.force_n(float(x)) for x in d] == pytest.approx(fz.tolist())
    assert press.force_n(0.0) == 0.0
    assert [press.voltage_v(float(x)) for x in d] == pytest.approx(
        skin.voltages_v(d)[:, 0].tolist())
