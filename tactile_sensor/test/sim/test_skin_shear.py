"""The skin's tangential stiffness: from the array grid when it is cached, else from the
grid's one +x path at its largest level, solved once and cached."""

from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np
import pytest

from tactile_sensor.physics import array_grid
from tactile_sensor.physics.params import PhysicsParams
from tactile_sensor.sim.errors import SimError
from tactile_sensor.sim.skin_shear import TangentialStiffness, load_or_compute_stiffness

PARAMS = PhysicsParams()


def fake_path(solved: list) -> object:
    def solve(params, path, progress=None):
        solved.append(path)
        d = np.linspace(0.0, 0.003, 7)
        return {"indentation_m": d, "shear_x_m": path.shear_x_m * d / d[-1],
                "force_x_n": 350.0 * path.shear_x_m * d / d[-1] * (1 - 30 * d)}
    return solve


def test_without_a_grid_one_path_is_solved_once_and_cached(tmp_path, monkeypatch):
    solved: list = []
    monkeypatch.setattr(array_grid, "solve_path", fake_path(solved))
    first = load_or_compute_stiffness(PARAMS, tmp_path)
    again = load_or_compute_stiffness(PARAMS, tmp_path)
    (path,) = solved                                           # the second read the cache
    assert path.direction == 0 and path.level == PARAMS.array_shear_levels
    assert path.shear_x_m == pytest.approx(PARAMS.array_shear_ratio * PARAMS.max_indentation)
    assert first(0.001) == again(0.001) == pytest.approx(350.0 * 0.97)
    assert first.source == f"fem-array:{PARAMS.grid_digest()}"


def test_a_damaged_cache_entry_is_solved_again(tmp_path, monkeypatch):
    solved: list = []
    monkeypatch.setattr(array_grid, "solve_path", fake_path(solved))
    (tmp_path / f"shear-path-{PARAMS.grid_digest()}.json").write_text(json.dumps(
        {"format": "tactile_sensor/shear_path", "digest": PARAMS.grid_digest(),
         "indentation_m": [0.001], "shear_x_m": [0.001], "force_x_n": [-1.0]}))
    assert load_or_compute_stiffness(PARAMS, tmp_path)(0.002) > 0 and len(solved) == 1


def test_a_cached_grid_is_read_and_nothing_solved(tmp_path, monkeypatch):
    grid = SimpleNamespace(indentation_m=[0.0, 0.001], level=[0, 1], direction=[-1, 0],
                           shear_x_m=[0.0, 0.003], force_x_n=[0.0, 0.9], digest="g")
    monkeypatch.setattr(array_grid, "cached_grid", lambda params, cache_dir: grid)
    monkeypatch.setattr(array_grid, "solve_path", lambda *a, **k: pytest.fail("solved"))
    assert load_or_compute_stiffness(PARAMS, tmp_path)(0.001) == pytest.approx(300.0)


def test_a_stiffer_skin_scales_and_a_bad_table_is_refused():
    k = TangentialStiffness([0.001, 0.002], [300.0, 280.0])
    assert k.scaled(1.5)(0.0015) == pytest.approx(1.5 * 290.0)
    with pytest.raises(SimError, match="finite stiffnesses > 0"):
        TangentialStiffness([0.001, 0.002], [300.0, 0.0])
    with pytest.raises(SimError, match="increasing indentations"):
        TangentialStiffness([0.002, 0.001], [300.0, 280.0])
