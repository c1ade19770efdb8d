"""WrenchSkin and WrenchBenchWorld on a grid and a wrench set built by the physics code from a
synthetic skin (the FEM solve replaced by a smooth, symmetry-respecting answer)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from tactile_sensor.physics import array_grid, wrench
from tactile_sensor.physics.array_grid import FACES, compute_grid
from tactile_sensor.physics.params import PhysicsParams, parse_modules
from tactile_sensor.physics.wrench import compute_wrench_set, map_wrench
from tactile_sensor.sim.array_world import ArraySkin
from tactile_sensor.sim.errors import SimError
from tactile_sensor.sim.profiles import WrenchProfile
from tactile_sensor.sim.wrench_world import (
    WrenchBenchWorld,
    WrenchSkin,
    wrench_points,
)

LAYOUT = ("front@-0.0055,front@0.0055,back@-0.0055,back@0.0055,left@-0.0055,left@0.0055,"
          "right@-0.0055,right@0.0055")


def _normal(face: str) -> np.ndarray:
    axis, sign = FACES[face]
    n = np.zeros(2)
    n[axis] = sign
    return n


def _answer(params: PhysicsParams, path: Any) -> dict[str, Any]:
    """What a sweep of ``path`` returns, from a smooth skin with the block's symmetry: each
    window bulges with the local indentation and tangential motion its point sees."""
    t = np.linspace(0.0, 1.0, params.array_steps + 1)
    d = t * params.max_indentation
    s = t[:, None] * np.array([path.shear_x_m, path.shear_y_m])
    r = t[:, None] * np.array([path.tilt_x_rad, path.tilt_y_rad, path.twist_z_rad])
    bulges, tangents = {}, {}
    for lab in params.window_labels:
        ((face, offset),) = parse_modules(lab)
        n = _normal(face)
        tangent = np.array([abs(n[1]), abs(n[0])])
        p = n * params.width / 2 + tangent * offset
        local = d - (r[:, 0] * p[1] - r[:, 1] * p[0])
        u = s + r[:, 2:3] * np.array([-p[1], p[0]])
        bulges[lab] = 0.03 * local + 0.01 * (u @ n) + 4.0 * (u @ tangent) ** 2 + 8.0 * local ** 2
        tangents[lab] = 0.1 * (u @ np.array([-n[1], n[0]]))  # along z x n
    torque = np.column_stack([0.05 * d * r[:, 0] + 0.4 * d * s[:, 1],
                              0.05 * d * r[:, 1] - 0.4 * d * s[:, 0],
                              0.02 * d * r[:, 2]])
    return {"indentation_m": d, "shear_x_m": s[:, 0], "shear_y_m": s[:, 1],
            "force_x_n": 300.0 * s[:, 0], "force_y_n": 300.0 * s[:, 1],
            "force_n": 2000.0 * d + 1e5 * d ** 2 + 30.0 * d * r[:, 2] ** 2,
            "bulges_m": bulges, "tangents_m": tangents, "torque_nm": torque}


@pytest.fixture(scope="module")
def built() -> tuple[PhysicsParams, WrenchSkin, Any]:
    params = PhysicsParams(modules=LAYOUT, array_steps=2, array_directions=4,
                           array_shear_levels=1, array_shear_ratio=1.0)
    fake = lambda p, paths, *a, **k: [_answer(p, q) for q in paths]  # noqa: E731
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(array_grid, "solve_paths", fake)
        mp.setattr(wrench, "solve_paths", fake)
        grid = compute_grid(params)
        data = compute_wrench_set(params)
    skin = ArraySkin(grid, 3.0)
    return params, WrenchSkin(skin, wrench_points(params, data), 0.011, 0.011), data


def test_exact_at_every_point_of_the_set(built: Any) -> None:
    params, skin, data = built
    pts = wrench_points(params, data)
    got = skin.state(pts.d, *pts.shear.T, *pts.rotation.T)
    order = [pts.modules.index(f) for f in skin.faces]
    assert np.allclose(got[:, :len(order)], pts.outputs[:, order], atol=1e-12)
    assert np.allclose(got[:, len(order):], pts.wrench, atol=1e-12)
    assert pts.rotation[:, 2].max() == pytest.approx(params.wrench_twist)
    assert pts.rotation[:, 2].min() == pytest.approx(-params.wrench_twist)


def test_zero_rotation_is_the_array_skin(built: Any) -> None:
    _, skin, _ = built
    d = np.linspace(0.0, 0.004, 9)[:, None]
    sx, sy = 0.0017 * np.cos(np.arange(5)), 0.0011 * np.sin(np.arange(5))
    got = skin.state(d, sx, sy)
    assert np.allclose(got[..., :-3], skin.skin.state(d, sx, sy), atol=0)


def test_continuous_and_linear_in_rotation(built: Any) -> None:
    _, skin, _ = built
    r = np.linspace(-0.3, 0.3, 601)
    for axis in range(3):
        rot = [np.zeros_like(r)] * 3
        rot[axis] = r
        w = skin.state(0.0021, 0.0004, -0.0002, *rot)
        # no jump: every step of 1 mrad moves each column by at most ~1/300 of its range
        assert np.all(np.abs(np.diff(w, axis=0)) <= np.ptp(w, axis=0) / 250 + 1e-15)
        # linear on each side of zero: extrapolated beyond the set's rotation
        assert np.allclose(np.diff(w[301:], 2, axis=0), 0, atol=1e-12)
    rest = skin.state(0.0, 0.001, 0.0, 0.05, -0.05, 0.1)
    assert np.allclose(rest, 0.0)


def test_mirror_images_give_the_opposite_rotation(built: Any) -> None:
    """Mirroring y (a map of the block) turns a twist about +z into -z: the skin's answer
    at -rz is the mirrored answer at +rz, module by module and component by component; the
    twist's torque is odd and its normal force even."""
    _, skin, _ = built
    g = np.diag([1.0, -1.0])
    m = len(skin.faces)
    plus = skin.state(0.0025, 0.0, 0.0, 0.0, 0.0, 0.15)
    minus = skin.state(0.0025, 0.0, 0.0, 0.0, 0.0, -0.15)
    image = {f: array_grid.face_image(g, f) for f in skin.faces}
    for i, f in enumerate(skin.faces):
        assert minus[skin.faces.index(image[f])] == pytest.approx(plus[i], abs=1e-12)
    assert np.allclose(minus[m:], map_wrench(g, plus[None, m:])[0], atol=1e-12)
    press = skin.state(0.0025)
    assert minus[m + 5] == pytest.approx(-plus[m + 5])
    assert minus[m + 2] - press[m + 2] == pytest.approx(plus[m + 2] - press[m + 2])


def test_six_axis_bench_follows_the_profile(built: Any) -> None:
    _, skin, _ = built
    profile = WrenchProfile(rest_s=0.5)
    world = WrenchBenchWorld(profile, skin, grid_hz=50.0)
    times, knots = profile.knots()
    mid = times[np.argmax(knots[:, 5])]       # twist +z at its largest
    assert np.allclose(world.stage_m(mid), knots[np.argmax(knots[:, 5])])
    assert np.allclose(world.wrench_n(mid), skin.wrench(*knots[np.argmax(knots[:, 5])]))
    assert world.photoreflector_voltage(mid).shape == (8,)
    assert world.wrench_n(times[-1]) == pytest.approx(np.zeros(6), abs=1e-12)


def test_tilt_that_lifts_the_edge_is_refused(built: Any) -> None:
    _, skin, _ = built
    with pytest.raises(SimError, match="lifts the probe's edge"):
        WrenchBenchWorld(WrenchProfile(depth_m=0.001, shear_m=0.001), skin, grid_hz=10.0)


def test_a_set_from_other_parameters_is_refused(built: Any) -> None:
    params, _, data = built
    with pytest.raises(SimError, match="does not match"):
        wrench_points(params.replace(array_steps=3), data)
