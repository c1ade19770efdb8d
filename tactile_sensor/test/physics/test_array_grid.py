"""The array calibration grid: symmetry reduction, expansion, cache, parallel paths, fit."""

from __future__ import annotations

import json

import numpy as np
import pytest

from tactile_sensor.physics import array_grid
from tactile_sensor.physics.array_grid import (
    ArrayGrid,
    canonical_directions,
    compute_grid,
    face_image,
    load_or_compute_grid,
    load_paths,
)
from tactile_sensor.physics.array_report import fit_grid
from tactile_sensor.physics.errors import PhysicsError
from tactile_sensor.physics.fem import REPRODUCIBLE_RTOL, SkinModel
from tactile_sensor.physics.params import PhysicsParams

TINY = PhysicsParams(mesh_nx=4, mesh_ny=4, mesh_nz=16, array_mesh_scale=1.0, array_steps=3,
                     array_directions=4, array_shear_levels=2, array_shear_ratio=1.0,
                     max_indentation=0.002, modules="front,back,left,right")


@pytest.fixture(scope="module")
def tiny_grid() -> ArrayGrid:
    return compute_grid(TINY)


def solved(params: PhysicsParams) -> list[int]:
    return sorted({j for j, _ in canonical_directions(params)})


def test_symmetry_leaves_two_of_eight_directions_to_solve_on_a_square_array():
    four = PhysicsParams(modules="front,back,left,right")
    assert solved(four) == [0, 1]
    assert solved(PhysicsParams()) == [0, 1, 2]          # front/back windows only
    assert solved(four.replace(depth=0.024)) == [0, 1, 2]
    assert solved(four.replace(array_directions=12)) == [0, 1]     # 60 deg mirrors 30
    paths = load_paths(four)
    assert [(p.direction, p.level) for p in paths] == [(-1, 0), (0, 1), (0, 2), (0, 3),
                                                       (1, 1), (1, 2), (1, 3)]
    assert paths[1].shear_y_m == 0.0 and paths[1].shear_x_m == pytest.approx(0.003)


def test_face_images_follow_the_normals():
    swap = np.array([[0.0, 1.0], [1.0, 0.0]])
    assert face_image(np.diag([-1.0, 1.0]), "right") == "left"
    assert face_image(np.diag([-1.0, 1.0]), "front") == "front"
    assert face_image(swap, "right") == "front" and face_image(swap, "back") == "left"


def test_a_direction_filled_in_by_symmetry_equals_solving_it(tiny_grid):
    """90 deg comes from 0 deg by the x = y mirror; solve it directly and compare."""
    p = TINY.replace(mesh_extrapolation_order_force=0, mesh_extrapolation_order_bulge=0,
                     steps=3, max_shear_y=0.002 * 1.0)
    direct = SkinModel(p).sweep()
    at = (tiny_grid.direction == 1) & (tiny_grid.level == 2)
    np.testing.assert_allclose(tiny_grid.shear_y_m[at], direct.shear_y_m[1:], atol=1e-15)
    np.testing.assert_allclose(tiny_grid.shear_x_m[at], 0.0, atol=1e-15)
    np.testing.assert_allclose(tiny_grid.force_y_n[at], direct.force_y_n[1:], rtol=1e-5)
    np.testing.assert_allclose(tiny_grid.force_n[at], direct.force_n[1:], rtol=1e-5)
    # the torque mapped as a pseudo-vector from the 0 deg path's equals the direct solve's
    assert np.abs(direct.torque_nm[1:, 0]).max() > 1e-3
    np.testing.assert_allclose(tiny_grid.torque_nm[at], direct.torque_nm[1:], rtol=1e-5,
                               atol=1e-9)
    from tactile_sensor.physics.prediction import module_output
    for face in TINY.module_faces:
        np.testing.assert_allclose(tiny_grid.outputs_v[face][at],
                                   module_output(TINY, direct.bulges_m[face][1:])[2],
                                   rtol=1e-5, atol=1e-9)


def test_the_grid_holds_every_direction_and_level_once(tiny_grid):
    g = tiny_grid
    assert g.paths == 3                      # none, and two levels of the one solved direction
    assert g.indentation_m.size == 1 + 3 + 4 * 2 * 3
    assert (g.step == 0).sum() == 1 and g.force_n[g.step == 0] == 0.0
    angles = np.degrees(np.arctan2(g.shear_y_m, g.shear_x_m))[g.level > 0] % 360
    assert sorted(set(np.round(angles, 6))) == [0.0, 90.0, 180.0, 270.0]
    # the probe moving toward a face bulges it most
    edge = (g.level == 2) & (g.step == 3)
    for direction, face in enumerate(("right", "front", "left", "back")):
        row = edge & (g.direction == direction)
        assert max(g.outputs_v, key=lambda f, r=row: g.outputs_v[f][r][0]) == face


def test_held_out_points_are_interior_and_alike_in_every_direction(tiny_grid):
    held = tiny_grid.held_out()
    assert held.sum() == 4                   # step 2 of level 1, in each of 4 directions
    assert set(tiny_grid.direction[held]) == {0, 1, 2, 3}
    assert np.all(tiny_grid.step[held] == 2) and np.all(tiny_grid.level[held] == 1)


def test_the_fit_predicts_held_out_points(tiny_grid):
    calibration, report = fit_grid(tiny_grid, 2)
    assert report["held_out_points"] == 4
    assert report["terms"] == {"x": 3, "y": 3, "z": 8}      # what mirror parity leaves
    for axis in "xyz":
        assert report["held_out_rmse_percent_of_range"][axis] < 2.0, report
    assert 0 < report["max_lateral_over_normal_force"] < 1
    assert calibration.source == f"fem-array:{TINY.grid_digest()}"


def test_grid_round_trips_and_refuses_damage(tiny_grid):
    back = ArrayGrid.from_dict(json.loads(json.dumps(tiny_grid.to_dict())))
    np.testing.assert_array_equal(back.force_matrix(), tiny_grid.force_matrix())
    np.testing.assert_array_equal(back.output_matrix(), tiny_grid.output_matrix())
    bad = tiny_grid.to_dict()
    bad["force_n"] = bad["force_n"][:-1]
    with pytest.raises(PhysicsError, match="different lengths"):
        ArrayGrid.from_dict(bad)
    with pytest.raises(PhysicsError, match="damaged"):
        ArrayGrid.from_dict({"format": "nope"})


def test_grid_torques_round_trip_and_an_older_grid_has_none(tiny_grid):
    data = tiny_grid.to_dict()
    back = ArrayGrid.from_dict(json.loads(json.dumps(data)))
    np.testing.assert_array_equal(back.torque_nm, tiny_grid.torque_nm)
    assert tiny_grid.torque_nm.shape == (tiny_grid.force_n.size, 3)
    del data["torque_nm"]
    assert ArrayGrid.from_dict(data).torque_nm is None
    data["torque_nm"] = tiny_grid.torque_nm[:-1].tolist()
    with pytest.raises(PhysicsError, match="different lengths"):
        ArrayGrid.from_dict(data)


def test_the_grid_is_cached_and_a_damaged_entry_recomputed(tiny_grid, tmp_path, monkeypatch):
    calls: list[int] = []

    def fake(params: PhysicsParams, progress: object = None, workers: int = 1) -> ArrayGrid:
        calls.append(workers)
        return tiny_grid

    monkeypatch.setattr(array_grid, "compute_grid", fake)
    load_or_compute_grid(TINY, tmp_path)
    load_or_compute_grid(TINY, tmp_path)
    assert calls == [1]
    (entry,) = tmp_path.glob("array-grid-*.json")
    assert TINY.grid_digest() in entry.name
    entry.write_text("{broken")
    load_or_compute_grid(TINY, tmp_path, workers=2)
    assert calls == [1, 2]
    load_or_compute_grid(TINY.replace(array_shear_ratio=0.5), tmp_path)
    assert len(calls) == 3
    # a grid cached before grids kept the probe's torque is computed again
    data = json.loads(entry.read_text())
    del data["torque_nm"]
    entry.write_text(json.dumps(data))
    load_or_compute_grid(TINY, tmp_path)
    assert len(calls) == 4


@pytest.mark.slow
def test_two_workers_give_the_same_grid_with_progress(tiny_grid):
    seen: list[float] = []
    parallel = compute_grid(TINY, lambda f, _m: seen.append(f), workers=2)
    # the workers solve in other processes: equal to the solver's tolerance, not to the bit
    np.testing.assert_allclose(parallel.force_matrix(), tiny_grid.force_matrix(),
                               rtol=REPRODUCIBLE_RTOL, atol=1e-12)
    np.testing.assert_allclose(parallel.output_matrix(), tiny_grid.output_matrix(),
                               rtol=REPRODUCIBLE_RTOL, atol=1e-12)
    assert seen == sorted(seen) and seen[-1] == pytest.approx(1.0) and len(seen) >= 9
