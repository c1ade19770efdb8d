"""The fingertip skin's tangential stiffness, from the FEM array grid.

The array grid (``physics/array_grid.py``) solves load paths that shear the skin as they
press it; its paths along +x at the largest shear level give, at each indentation level d,
the lateral force over the lateral displacement: the skin's tangential stiffness k(d), the
secant over the whole range a sticking contact spans. When the gripper's grid is cached, it
is read from there; else only that one path is solved (the grid's own mesh and solver, so
the same numbers, about 6 s instead of the whole grid's 40 s) and cached on its own.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from tactile_sensor.sim.errors import SimError

Progress = Callable[[float, str], None]
SHEAR_PATH_FORMAT = "tactile_sensor/shear_path"


class TangentialStiffness:
    """The skin's tangential stiffness k(d) [N/m] against indentation d [m]: the grid's
    lateral force over lateral displacement along +x at its largest shear level (the secant
    over the whole range a sticking contact spans), linear between its indentation levels,
    the end values beyond them."""

    def __init__(self, indentation_m: Sequence[float], stiffness_n_per_m: Sequence[float],
                 source: str = "table") -> None:
        d = np.asarray(indentation_m, float)
        k = np.asarray(stiffness_n_per_m, float)
        if d.ndim != 1 or d.size < 1 or k.shape != d.shape or not (
                np.all(np.isfinite(d)) and np.all(np.isfinite(k))) or np.any(k <= 0) or \
                np.any(np.diff(d) <= 0):
            raise SimError("A tangential stiffness table needs increasing indentations and "
                           "finite stiffnesses > 0.")
        self._d, self._k = d.tolist(), k.tolist()
        self.source = source

    def __call__(self, indentation_m: float) -> float:
        return float(np.interp(indentation_m, self._d, self._k))

    def scaled(self, ratio: float) -> TangentialStiffness:
        """The same skin with all its moduli scaled by ``ratio`` (``skin.stiffness_ratio``:
        the hyperelastic law is homogeneous in its moduli, so every force scales)."""
        return TangentialStiffness(self._d, [ratio * k for k in self._k], self.source)

    @classmethod
    def from_grid(cls, grid: Any) -> TangentialStiffness:
        """From a ``physics.array_grid.ArrayGrid``: its direction 0 (+x), largest level."""
        direction = np.asarray(grid.direction, int)
        level = np.asarray(grid.level, int)
        sx = np.asarray(grid.shear_x_m, float)
        fx = np.asarray(grid.force_x_n, float)
        d = np.asarray(grid.indentation_m, float)
        rows = (direction == 0) & (level == level.max()) & (sx > 0)
        if not np.any(rows):
            raise SimError("The array grid has no shear along +x; recompute it with "
                           "'tactile-sensor model array-calibration'.")
        order = np.argsort(d[rows])
        return cls(d[rows][order], (fx[rows] / sx[rows])[order],
                   source=f"fem-array:{getattr(grid, 'digest', '?')}")


def load_or_compute_stiffness(params: Any, cache_dir: Path | None = None,
                              progress: Progress | None = None) -> TangentialStiffness:
    """The tangential stiffness of ``params``' skin (a ``PhysicsParams``): from its cached
    array grid, else from the grid's +x path at the largest level (cached, solved on a miss)."""
    try:
        from tactile_sensor.physics.array_grid import cached_grid, load_paths, solve_path
        from tactile_sensor.physics.errors import PhysicsError
        from tactile_sensor.physics.prediction import (
            cache_file,
            load_or_compute,
            read_cache,
            write_cache,
        )
    except ImportError as exc:
        raise SimError(f"The physics model is not available ({exc}); install the complete "
                       "tactile_sensor package.") from None
    grid = cached_grid(params, cache_dir)
    if grid is not None:
        return TangentialStiffness.from_grid(grid)
    digest = params.grid_digest()
    path = cache_file(cache_dir, f"shear-path-{digest}.json")
    top = max(p.level for p in load_paths(params))
    along = next(p for p in load_paths(params) if p.direction == 0 and p.level == top)

    def parse(data: Any) -> dict[str, Any]:
        """The cached path, or ValueError (missing, another's or damaged: recompute)."""
        if not isinstance(data, dict) or data.get("format") != SHEAR_PATH_FORMAT or \
                data.get("digest") != digest:
            raise ValueError("not this path")
        try:
            shear_path_stiffness(data, digest)
        except SimError as exc:
            raise ValueError(str(exc)) from None
        return data

    def compute() -> dict[str, Any]:
        result = solve_path(params, along, progress)
        return {"format": SHEAR_PATH_FORMAT, "digest": digest,
                **{k: np.asarray(result[k], float).tolist()
                   for k in ("indentation_m", "shear_x_m", "force_x_n")}}

    try:
        data = load_or_compute(path, lambda: read_cache(path, parse), compute,
                               lambda d: write_cache(path, d), progress,
                               f"computing the skin's shear path (cache miss: {path.name})")
    except (PhysicsError, SimError) as exc:
        raise SimError(f"The skin's shear path failed ({exc}).") from None
    return shear_path_stiffness(data, digest)


def shear_path_stiffness(data: dict[str, Any], digest: str) -> TangentialStiffness:
    """k(d) from one shear path's arrays (its loaded steps: lateral displacement > 0)."""
    try:
        d, sx, fx = (np.asarray(data[k], float) for k in ("indentation_m", "shear_x_m",
                                                           "force_x_n"))
        loaded = sx > 0
        return TangentialStiffness(d[loaded], fx[loaded] / sx[loaded],
                                   source=f"fem-array:{digest}")
    except (KeyError, TypeError, ValueError):
        raise SimError("A cached shear path is damaged; delete it to recompute.") from None
