"""Wrench load paths: which of (Fx, Fy, Fz, Tx, Ty, Tz) a module layout can tell apart.

The array calibration grid presses and shears; a probe can also twist about its axis (z) and
tilt about x and y. Here every design solves six paths from rest, each pressing to
``max_indentation`` in ``array_steps`` steps: pure indentation, shear along +x and +y (the
grid's smallest shear level, ``array_shear_ratio / array_shear_levels`` x the indentation:
a linear sensitivity needs no more, and larger shears cut steps on coarse meshes), tilt
about +x and +y (``wrench_tilt``) and twist about +z (``wrench_twist``), on the grid's
mesh. The block's symmetries that leave the windows alone (mirrors about x = 0, y = 0 and,
square with windows on every face, x = y) add the mirrored loads without solving (forces map
as vectors, torques as pseudo-vectors, modules read their image's output): the shear and
tilt along y come from those along x when x = y is a symmetry, and the least-squares
sensitivity matrix sees each load both ways and no quadratic effect (a twist shortens the
skin whichever way it turns) leaks into a linear column. Its metrics:
``physics/observability.py``.
"""

from __future__ import annotations

import hashlib
import json
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .array_grid import LoadPath, face_image, image_tangent, solve_paths, symmetries
from .errors import PhysicsError
from .params import PhysicsParams

WRENCH_FORMAT = "tactile_sensor/wrench_set"
#: Components in matrix order: forces [N] (Fz pressing positive), torques [N m] (right hand).
WRENCH_AXES = ("fx", "fy", "fz", "tx", "ty", "tz")


@dataclass(frozen=True, eq=False)
class WrenchSet:
    """Points (rest included once) of the wrench paths: wrench (points, 6) in
    ``WRENCH_AXES`` order and each module's output [V], with the path index of each point."""

    wrench: np.ndarray
    outputs_v: dict[str, np.ndarray]
    path: np.ndarray
    digest: str
    seconds: float
    paths: int

    @property
    def modules(self) -> tuple[str, ...]:
        return tuple(self.outputs_v)

    def output_matrix(self) -> np.ndarray:
        """(points, modules) outputs [V] in ``modules`` order."""
        return np.stack([self.outputs_v[m] for m in self.modules], axis=1)

    def to_dict(self) -> dict[str, Any]:
        return {"format": WRENCH_FORMAT, "digest": self.digest, "seconds": self.seconds,
                "paths": self.paths, "wrench": self.wrench.tolist(),
                "path": self.path.tolist(),
                "outputs_v": {k: v.tolist() for k, v in self.outputs_v.items()}}

    @classmethod
    def from_dict(cls, data: Any) -> WrenchSet:
        try:
            if data["format"] != WRENCH_FORMAT:
                raise ValueError("format")
            wrench = np.asarray(data["wrench"], float).reshape(-1, len(WRENCH_AXES))
            outputs = {str(k): np.asarray(v, float) for k, v in data["outputs_v"].items()}
            out = cls(wrench, outputs, np.asarray(data["path"], int), str(data["digest"]),
                      float(data["seconds"]), int(data["paths"]))
        except (KeyError, TypeError, ValueError, AttributeError):
            raise PhysicsError("A wrench set file is damaged; delete it or recompute.") \
                from None
        if not outputs or {v.size for v in outputs.values()} != {out.path.size} or \
                out.path.size != wrench.shape[0] or not np.all(np.isfinite(wrench)):
            raise PhysicsError("A wrench set file holds arrays of different lengths or "
                               "non-finite numbers; delete it or recompute.")
        return out


def wrench_digest(params: PhysicsParams) -> str:
    """Hash of everything that shapes the wrench set (the grid's key and the rotations)."""
    text = json.dumps({"grid": params.grid_digest(), "twist": params.wrench_twist,
                       "tilt": params.wrench_tilt}, sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def wrench_paths(params: PhysicsParams) -> list[LoadPath]:
    """Press, shear +x, shear +y, tilt +x, tilt +y, twist +z (each with the indentation);
    those along y only when no symmetry of the layout maps x onto y."""
    s = params.array_shear_ratio / params.array_shear_levels * params.max_indentation
    tilt, twist = params.wrench_tilt, params.wrench_twist
    for name, half in (("x", params.depth / 2), ("y", params.width / 2)):
        if tilt * half > params.max_indentation:
            raise PhysicsError(f"Parameter 'wrench_tilt' ({tilt:g} rad) would lift the "
                               f"probe's edge {tilt * half * 1e3:.3g} mm in the tilt about "
                               f"{name}, more than max_indentation; lower wrench_tilt below "
                               f"{params.max_indentation / half:.3g} rad.")
    swapped = any(abs(g[1, 0]) == 1 for g in symmetries(params))
    paths = [LoadPath(-1, 0, 0.0, 0.0), LoadPath(0, 1, s, 0.0),
             LoadPath(2, 1, 0.0, 0.0, tilt_x_rad=tilt),
             LoadPath(4, 1, 0.0, 0.0, twist_z_rad=twist)]
    if not swapped:
        paths[2:2] = [LoadPath(1, 1, 0.0, s)]
        paths[4:4] = [LoadPath(3, 1, 0.0, 0.0, tilt_y_rad=tilt)]
    return paths


def map_wrench(g: np.ndarray, wrench: np.ndarray) -> np.ndarray:
    """The wrench rows (points, 6) under the orthogonal map g of the (x, y) plane: forces
    as vectors, torques as pseudo-vectors (times det g)."""
    m = np.eye(3)
    m[:2, :2] = g
    out = wrench.copy()
    out[:, :3] = wrench[:, :3] @ m.T
    out[:, 3:] = float(np.linalg.det(m)) * (wrench[:, 3:] @ m.T)
    return out


def compute_wrench_set(params: PhysicsParams, progress: Any = None, workers: int = 1,
                       scheduler: str | None = None) -> WrenchSet:
    """Solve the wrench paths and add their mirror images; outputs of ``params``' modules."""
    from .prediction import module_output

    start = time.perf_counter()
    paths = wrench_paths(params)
    results = solve_paths(params, paths, workers, progress, scheduler)
    wrench, path_index = [], []
    bulges: dict[str, list[np.ndarray]] = {m: [] for m in params.module_faces}
    tangents: dict[str, list[np.ndarray]] = {m: [] for m in params.module_faces}
    maps = symmetries(params)             # the identity first
    for k, res in enumerate(results):
        rows = np.column_stack([res["force_x_n"], res["force_y_n"], res["force_n"],
                                res["torque_nm"]])
        # Fz is force_n, along -z: the maps leave z alone, so it stays as it is
        for j, g in enumerate(maps):
            if j and k == 0:
                continue                  # pure indentation is its own image
            first = 0 if (k == 0 and j == 0) else 1     # rest once
            wrench.append(map_wrench(g, rows)[first:])
            path_index.append(np.full(rows.shape[0] - first, k))
            for m in bulges:              # m reads what the window g maps onto it read
                source = face_image(g.T, m)
                bulges[m].append(res["bulges_m"][source][first:])
                tangents[m].append(image_tangent(g, res["tangents_m"][source][first:]))
    outputs = {m: module_output(params, np.concatenate(b), np.concatenate(tangents[m]))[2]
               for m, b in bulges.items()}
    return WrenchSet(np.concatenate(wrench), outputs, np.concatenate(path_index),
                     wrench_digest(params), time.perf_counter() - start, len(paths))


def wrench_cache_path(params: PhysicsParams, cache_dir: Path | None = None) -> Path:
    from .prediction import cache_file

    return cache_file(cache_dir, f"wrench-{wrench_digest(params)}.json")


def cached_wrench_set(params: PhysicsParams, cache_dir: Path | None = None
                      ) -> WrenchSet | None:
    """The cached set for ``params``, or None (missing or damaged: recompute it)."""
    from .prediction import read_cache

    return read_cache(wrench_cache_path(params, cache_dir), WrenchSet.from_dict)


def store_wrench_set(params: PhysicsParams, data: WrenchSet,
                     cache_dir: Path | None = None) -> None:
    """Cache ``data`` atomically; best effort (a read-only cache only costs time)."""
    from .prediction import write_cache

    write_cache(wrench_cache_path(params, cache_dir), data.to_dict())


def load_or_compute_wrench_set(params: PhysicsParams, cache_dir: Path | None = None,
                               progress: Any = None, workers: int = 1) -> WrenchSet:
    """The cached wrench set for ``params``, or solved now and cached."""
    from .prediction import load_or_compute

    return load_or_compute(
        wrench_cache_path(params, cache_dir), lambda: cached_wrench_set(params, cache_dir),
        lambda: compute_wrench_set(params, progress, workers),
        lambda data: store_wrench_set(params, data, cache_dir), progress,
        f"solving the wrench paths (cache miss: {wrench_cache_path(params, cache_dir).name})")


def off_centre(params: PhysicsParams) -> bool:
    """Whether any module's window sits off its face's centre: centred windows cannot tell
    a torque from a force (docs/array.md, the symmetry argument), so only such a layout is
    worth its wrench paths."""
    return any(offset != 0.0 for _, offset in params.module_windows)
