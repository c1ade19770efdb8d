"""The array calibration grid: module outputs under indentation x shear direction x magnitude.

Each load path runs linearly from rest to (max_indentation, r d cos(theta), r d sin(theta))
for shear level r = ratio * j / levels, so its ``array_steps`` load steps are the grid's
indentation levels d and the shear grows with the indentation: a probe pressed d deep slides
off once its lateral force reaches the friction limit, which the FEM puts at a lateral
displacement proportional to d (``array_shear_ratio``, docs/array.md). The bonded skin is
hyperelastic, so the state at a grid point does not depend on how the probe got there: one
path per (direction, level) serves all indentations.

Fewer solves: the block is mirror-symmetric about x = 0 and y = 0 (and about x = y when it
is square with windows on all four faces), so a direction that a symmetry maps onto one
already solved is not solved again; its outputs are the mirror modules' and its forces the
mirrored ones. With the defaults, 8 directions need 2 (0 and 45 deg). Paths solve in
``workers`` Dask worker processes at once (``physics/batch.py``), each pinned to one BLAS
thread.

Mesh: a half or full model on the curve's mesh took ~5 min a path (graded elements at the
window edges invert under large shear and the steps are cut), so the grid solves a mesh with
``array_mesh_scale`` times the elements per direction, alone (no Richardson half mesh). Its
pure-indentation outputs read lower than the extrapolated curve's; ``ArrayGrid.curve_error``
reports by how much.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .errors import PhysicsError
from .params import FACES, PhysicsParams, label, parse_modules

Progress = Callable[[float, str], None]
GRID_FORMAT = "tactile_sensor/array_grid"
_NORMALS = {face: np.array([sign if axis == 0 else 0, sign if axis == 1 else 0], float)
            for face, (axis, sign) in FACES.items()}


@dataclass(frozen=True)
class LoadPath:
    """One solved path: a canonical direction's index (or -1: pure indentation) and level,
    and the probe's rotation at its end (tilt about x and y, twist about z [rad]; the
    wrench paths of ``physics/wrench.py`` only)."""

    direction: int
    level: int
    shear_x_m: float
    shear_y_m: float
    tilt_x_rad: float = 0.0
    tilt_y_rad: float = 0.0
    twist_z_rad: float = 0.0


@dataclass(frozen=True, eq=False)
class ArrayGrid:
    """Grid points (rest included once): probe position, force on the skin, module outputs.

    Forces follow the sweep's convention: (force_x_n, force_y_n) along +x/+y, force_n along
    -z, each the probe's force on the skin. ``direction`` is the shear direction's index
    (angle 2 pi i / directions from +x toward +y; -1 without shear), ``level`` the shear
    level (0: none), ``step`` the load step along the path (0: rest).
    """

    indentation_m: np.ndarray
    shear_x_m: np.ndarray
    shear_y_m: np.ndarray
    force_x_n: np.ndarray
    force_y_n: np.ndarray
    force_n: np.ndarray
    outputs_v: dict[str, np.ndarray]
    direction: np.ndarray
    level: np.ndarray
    step: np.ndarray
    digest: str
    seconds: float
    paths: int
    #: (points, 3) the probe's torque on the skin [N m] (Tx, Ty, Tz); None in a grid cached
    #: before torques were kept.
    torque_nm: np.ndarray | None = None

    @property
    def faces(self) -> tuple[str, ...]:
        return tuple(self.outputs_v)

    def output_matrix(self) -> np.ndarray:
        """(points, modules) outputs [V] in ``faces`` order."""
        return np.stack([self.outputs_v[f] for f in self.faces], axis=1)

    def force_matrix(self) -> np.ndarray:
        """(points, 3) forces [N]: x, y, z (z = force_n, pressing positive)."""
        return np.stack([self.force_x_n, self.force_y_n, self.force_n], axis=1)

    def held_out(self) -> np.ndarray:
        """Points kept out of the fit: interior steps and levels in a checkerboard, in every
        direction alike (so no mirror image of a held-out point is fitted)."""
        steps, levels = int(self.step.max()), int(self.level.max())
        interior = (self.step > 0) & (self.step < steps) & (self.level > 0) & \
            (self.level < levels)
        return interior & ((self.step + self.level) % 2 == 1)

    def to_dict(self) -> dict[str, Any]:
        arrays = ("indentation_m", "shear_x_m", "shear_y_m", "force_x_n", "force_y_n",
                  "force_n", "direction", "level", "step")
        data: dict[str, Any] = {"format": GRID_FORMAT, "digest": self.digest,
                                "seconds": self.seconds, "paths": self.paths}
        data.update({name: getattr(self, name).tolist() for name in arrays})
        data["outputs_v"] = {k: v.tolist() for k, v in self.outputs_v.items()}
        if self.torque_nm is not None:
            data["torque_nm"] = self.torque_nm.tolist()
        return data

    @classmethod
    def from_dict(cls, data: Any) -> ArrayGrid:
        try:
            if data["format"] != GRID_FORMAT:
                raise ValueError("format")
            floats = {name: np.asarray(data[name], float) for name in (
                "indentation_m", "shear_x_m", "shear_y_m", "force_x_n", "force_y_n",
                "force_n")}
            ints = {name: np.asarray(data[name], int) for name in ("direction", "level",
                                                                    "step")}
            outputs = {str(k): np.asarray(v, float) for k, v in data["outputs_v"].items()}
            torque = None if data.get("torque_nm") is None else np.asarray(
                data["torque_nm"], float).reshape(-1, 3)
            grid = cls(**floats, **ints, outputs_v=outputs, digest=str(data["digest"]),
                       seconds=float(data["seconds"]), paths=int(data["paths"]),
                       torque_nm=torque)
        except (KeyError, TypeError, ValueError, AttributeError):
            raise PhysicsError("An array grid file is damaged; delete it or recompute with "
                               "'tactile-sensor model array-calibration'.") from None
        sizes = {a.size for a in (*floats.values(), *ints.values(), *outputs.values())}
        if torque is not None:
            sizes.add(torque.shape[0])
            if not np.all(np.isfinite(torque)):
                sizes.add(-1)
        if len(sizes) != 1 or not outputs or not all(
                np.all(np.isfinite(a)) for a in (*floats.values(), *outputs.values())):
            raise PhysicsError("An array grid file holds arrays of different lengths or "
                               "non-finite numbers; delete it or recompute.")
        return grid


# -- symmetry ----------------------------------------------------------------------------------


def symmetries(params: PhysicsParams) -> list[np.ndarray]:
    """Orthogonal 2 x 2 maps of the (x, y) plane that leave the block and its windows alone."""
    maps = [np.diag([sx, sy]).astype(float) for sx in (1, -1) for sy in (1, -1)]
    if math.isclose(params.width, params.depth, rel_tol=1e-12):
        swap = np.array([[0.0, 1.0], [1.0, 0.0]])
        maps += [swap @ g for g in maps]
    windows = set(params.window_labels)
    return [g for g in maps if {face_image(g, w) for w in windows} == windows]


def face_image(g: np.ndarray, module: str) -> str:
    """The module (face, or FACE@OFFSET) that ``g`` moves ``module``'s window onto."""
    ((face, offset),) = parse_modules(module)
    axis = FACES[face][0]
    along = np.zeros(2)
    along[1 - axis] = offset
    n = g @ _NORMALS[face]
    image = next(f for f, m in _NORMALS.items() if np.allclose(m, n))
    moved = g @ along
    return label(image, float(moved[1 - FACES[image][0]]) + 0.0)


def image_tangent(g: np.ndarray, tangent_m: np.ndarray) -> np.ndarray:
    """The tangential displacement the image module reads: a mirror (det g = -1) reverses
    the counter-clockwise tangent, a rotation keeps it."""
    return float(round(np.linalg.det(g))) * np.asarray(tangent_m, dtype=float)


def canonical_directions(params: PhysicsParams) -> list[tuple[int, np.ndarray]]:
    """For each direction index: (index of the solved direction, map g onto it from there)."""
    n = params.array_directions
    angles = 2.0 * np.pi * np.arange(n) / n
    units = np.stack([np.cos(angles), np.sin(angles)], axis=1)
    out: list[tuple[int, np.ndarray]] = []
    solved: list[int] = []
    for i in range(n):
        found = next(((j, g) for j in solved for g in symmetries(params)
                      if np.allclose(g @ units[j], units[i], atol=1e-9)), None)
        if found is None:
            solved.append(i)
            found = (i, np.eye(2))
        out.append(found)
    return out


# -- solving -----------------------------------------------------------------------------------


def grid_params(params: PhysicsParams) -> PhysicsParams:
    """The parameters every path shares: the grid's mesh, every window face read."""
    s = params.array_mesh_scale
    return params.replace(mesh_nx=max(1, math.ceil(params.mesh_nx * s)),
                          mesh_ny=max(1, math.ceil(params.mesh_ny * s)),
                          mesh_nz=max(2, math.ceil(params.mesh_nz * s)),
                          mesh_extrapolation_order_force=0.0,
                          mesh_extrapolation_order_bulge=0.0,
                          modules=",".join(params.window_labels), steps=params.array_steps,
                          max_shear_x=0.0, max_shear_y=0.0)


def load_paths(params: PhysicsParams) -> list[LoadPath]:
    """The paths to solve: pure indentation, then each solved direction's shear levels."""
    n, levels = params.array_directions, params.array_shear_levels
    paths = [LoadPath(-1, 0, 0.0, 0.0)]
    solved = sorted({j for j, _ in canonical_directions(params)})
    for i in solved:
        theta = 2.0 * np.pi * i / n
        for level in range(1, levels + 1):
            s = params.array_shear_ratio * level / levels * params.max_indentation
            paths.append(LoadPath(i, level, _clean(s * math.cos(theta)),
                                  _clean(s * math.sin(theta))))
    return paths


def _clean(v: float) -> float:
    """cos(90 deg) is 6e-17, not 0: keep exact zeros so the symmetric model is used."""
    return 0.0 if abs(v) < 1e-15 else v


def _path_cost(path: LoadPath) -> float:
    """Relative solve time, for progress and for starting the longest paths first: the
    model's size (quarter 1, half 2, full 4) to the power 1.5 (sparse factorisation)."""
    twist = path.twist_z_rad != 0
    copies = (2 if path.shear_x_m or path.tilt_y_rad or twist else 1) * \
        (2 if path.shear_y_m or path.tilt_x_rad or twist else 1)
    return float(copies) ** 1.5


def solve_path(params: PhysicsParams, path: LoadPath, progress: Progress | None = None
               ) -> dict[str, Any]:
    """One path's sweep on the grid's mesh, as plain arrays (picklable, for a worker)."""
    from .fem import SkinModel  # scikit-fem only for a cold grid

    p = grid_params(params).replace(max_shear_x=path.shear_x_m, max_shear_y=path.shear_y_m,
                                    max_tilt_x=path.tilt_x_rad, max_tilt_y=path.tilt_y_rad,
                                    max_twist_z=path.twist_z_rad)
    res = SkinModel(p).sweep(progress)
    return {"indentation_m": res.indentation_m, "shear_x_m": res.shear_x_m,
            "shear_y_m": res.shear_y_m, "force_x_n": res.force_x_n,
            "force_y_n": res.force_y_n, "force_n": res.force_n, "bulges_m": res.bulges_m,
            "tangents_m": res.tangents_m, "torque_nm": res.torque_nm,
            "rotation_rad": res.rotation_rad,
            "seconds": res.seconds}


def _solve(values: dict[str, Any], path: LoadPath, progress: Progress | None
           ) -> dict[str, Any]:
    """:func:`solve_path` from plain values, as a batch task."""
    return solve_path(PhysicsParams.from_mapping(values), path, progress)


def solve_paths(params: PhysicsParams, paths: list[LoadPath], workers: int,
                progress: Progress | None, scheduler: str | None = None
                ) -> list[dict[str, Any]]:
    """Every path's arrays, in order, solved as batch tasks (``physics/batch.py``):
    ``workers`` > 1 (or a ``scheduler``) solves that many at once on Dask."""
    from .batch import run

    values = {k: list(v) if isinstance(v, tuple) else v for k, v in params.to_dict().items()}
    results: list[dict[str, Any] | None] = [None] * len(paths)
    for r in run(_solve, [(values, path) for path in paths], scheduler=scheduler,
                 workers=workers, costs=[_path_cost(p) for p in paths],
                 progress=progress, label="path"):
        if r.error is not None:
            raise r.error
        results[r.index] = r.value
    return [r for r in results if r is not None]


def compute_grid(params: PhysicsParams, progress: Progress | None = None,
                 workers: int = 1) -> ArrayGrid:
    """Solve the grid's paths and expand them by symmetry into every requested direction."""
    from .prediction import module_output

    start = time.perf_counter()
    paths = load_paths(params)
    results = solve_paths(params, paths, workers, progress)
    by_path = {(p.direction, p.level): r for p, r in zip(paths, results, strict=True)}
    rows: dict[str, list[np.ndarray]] = {k: [] for k in (
        "indentation_m", "shear_x_m", "shear_y_m", "force_x_n", "force_y_n", "force_n",
        "direction", "level", "step")}
    torques: list[np.ndarray] = []
    bulges: dict[str, list[np.ndarray]] = {f: [] for f in params.module_faces}
    tangents: dict[str, list[np.ndarray]] = {f: [] for f in params.module_faces}

    def add(res: dict[str, Any], g: np.ndarray, direction: int, level: int,
            first: int) -> None:
        steps = np.arange(first, res["indentation_m"].size)
        shear = g @ np.stack([res["shear_x_m"], res["shear_y_m"]])
        force = g @ np.stack([res["force_x_n"], res["force_y_n"]])
        for name, values in (("indentation_m", res["indentation_m"]), ("shear_x_m", shear[0]),
                             ("shear_y_m", shear[1]), ("force_x_n", force[0]),
                             ("force_y_n", force[1]), ("force_n", res["force_n"])):
            rows[name].append(values[steps])
        rows["direction"].append(np.full(steps.size, direction))
        rows["level"].append(np.full(steps.size, level))
        rows["step"].append(steps)
        m = np.eye(3)
        m[:2, :2] = g            # torque is a pseudo-vector: it maps with det(g) too
        torques.append(float(np.linalg.det(m)) * (np.asarray(res["torque_nm"])[steps] @ m.T))
        for face in bulges:   # face reads what the face g maps onto it read in the path
            source = face_image(g.T, face)
            bulges[face].append(res["bulges_m"][source][steps])
            tangents[face].append(image_tangent(g, res["tangents_m"][source][steps]))

    add(by_path[(-1, 0)], np.eye(2), -1, 0, 0)
    for i, (j, g) in enumerate(canonical_directions(params)):
        for level in range(1, params.array_shear_levels + 1):
            add(by_path[(j, level)], g, i, level, 1)
    outputs = {f: module_output(params, np.concatenate(b), np.concatenate(tangents[f]))[2]
               for f, b in bulges.items()}
    return ArrayGrid(**{k: np.concatenate(v) for k, v in rows.items()}, outputs_v=outputs,
                     digest=params.grid_digest(), seconds=time.perf_counter() - start,
                     paths=len(paths), torque_nm=np.concatenate(torques))


def grid_cache_path(params: PhysicsParams, cache_dir: Path | None = None) -> Path:
    from .prediction import cache_file

    return cache_file(cache_dir, f"array-grid-{params.grid_digest()}.json")


def cached_grid(params: PhysicsParams, cache_dir: Path | None = None) -> ArrayGrid | None:
    """The cached grid for ``params``, or None (missing or damaged, or written before grids
    kept the probe's torque, which a six-column fit needs: recompute it)."""
    from .prediction import read_cache

    grid = read_cache(grid_cache_path(params, cache_dir), ArrayGrid.from_dict)
    return None if grid is None or grid.torque_nm is None else grid


def store_grid(params: PhysicsParams, grid: ArrayGrid, cache_dir: Path | None = None) -> None:
    """Cache ``grid`` atomically; best effort (a read-only cache only costs time)."""
    from .prediction import write_cache

    write_cache(grid_cache_path(params, cache_dir), grid.to_dict())


def load_or_compute_grid(params: PhysicsParams, cache_dir: Path | None = None,
                         progress: Progress | None = None, workers: int = 1) -> ArrayGrid:
    """The cached grid for ``params`` (keyed by every parameter that shapes it)."""
    from .prediction import load_or_compute

    return load_or_compute(
        grid_cache_path(params, cache_dir), lambda: cached_grid(params, cache_dir),
        lambda: compute_grid(params, progress, workers),
        lambda grid: store_grid(params, grid, cache_dir), progress,
        "computing the array calibration grid (cache miss: "
        f"{grid_cache_path(params, cache_dir).name})")
