"""Run a design study: every design of a spec solved once, as batch tasks, and measured.

A design's solves are cached where ``model sweep`` and ``model array-calibration`` cache
theirs (``prediction-<digest>.json``, ``array-grid-<digest>.json``), written by this process
as each result arrives: a remote worker needs no shared disk, Ctrl-C keeps every finished
design, and a rerun or a widened study computes only the designs it has not seen. A design
that fails (rejected parameter, mesh error, no convergence) is a row with its error; a
model error is cached too (``study-error-<digest>.json``), so it is not retried in vain.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .batch import run
from .design_metrics import curve_metrics, matrix_metrics, wrench_metrics
from .errors import PhysicsError
from .params import PhysicsParams
from .study_spec import (
    BOARD,
    MATRIX_METRIC,
    SINGLE_METRICS,
    WRENCH_METRIC,
    StudySpec,
    board_refusal,
)

Progress = Callable[[float, str], None]
REFERENCE = "paper"
#: Relative cost of a design's solves, for ordering and the time estimate: a grid's two
#: shear paths on the half-scale mesh took ~14 s, the extrapolated sweep ~6 s.
#: The wrench set's six paths, twist on the full model, took ~4x the grid's two.
CURVE_COST, GRID_COST, WRENCH_COST = 1.0, 2.5, 10.0


@dataclass
class DesignRow:
    """One design: its varied values, metrics, solve time, where it ran, or its error."""

    design: str
    values: dict[str, Any]
    digest: str = ""
    metrics: dict[str, float] = field(default_factory=dict)
    seconds: float = 0.0
    worker: str = ""
    error: str = ""

    @property
    def ok(self) -> bool:
        return not self.error


def design_task(values: dict[str, Any], needs_curve: bool, needs_grid: bool,
                needs_wrench: bool, progress: Progress | None) -> dict[str, Any]:
    """A design's solves on a worker, as plain data (the client caches and measures)."""
    from .array_grid import compute_grid
    from .prediction import compute_curve
    from .wrench import compute_wrench_set

    params = PhysicsParams.from_mapping(values)
    parts = [name for name, needed in (("curve", needs_curve), ("grid", needs_grid),
                                       ("wrench", needs_wrench)) if needed]
    out: dict[str, Any] = {}
    for k, name in enumerate(parts):
        def stage(f: float, message: str, k: int = k, name: str = name) -> None:
            if progress is not None:
                progress((k + f) / len(parts), f"{name}: {message}")

        if name == "curve":
            out["curve"] = compute_curve(params, stage).to_dict()
        elif name == "grid":
            out["grid"] = compute_grid(params, stage, workers=1).to_dict()
        else:
            out["wrench"] = compute_wrench_set(params, stage, workers=1).to_dict()
    return out


def _error_path(cache_dir: Path | None, digest: str) -> Path:
    from .prediction import default_cache_dir

    return (Path(cache_dir) if cache_dir is not None else default_cache_dir()) / \
        f"study-error-{digest}.json"


def _one_sentence(err: BaseException) -> str:
    text = " ".join(str(err).split())
    return text if isinstance(err, PhysicsError) else f"{type(err).__name__}: {text}"


def run_study(spec: StudySpec, *, scheduler: str | None = None, workers: int | None = None,
              cache_dir: Path | None = None, progress: Progress | None = None
              ) -> list[DesignRow]:
    """Every design's row (the paper's first), computing only what the cache lacks."""
    from .array_grid import cached_grid, store_grid
    from .prediction import PredictionCurve, cached_curve, store_curve
    from .wrench import WrenchSet, cached_wrench_set, store_wrench_set, wrench_digest

    needs_curve = any(m in SINGLE_METRICS for m in spec.metrics)
    needs_grid = MATRIX_METRIC in spec.metrics
    needs_wrench = WRENCH_METRIC in spec.metrics
    designs = [(REFERENCE, {})] + [(str(i), d) for i, d in enumerate(spec.designs())]
    rows = [DesignRow(name, values) for name, values in designs]
    params: dict[int, PhysicsParams] = {}
    for i, row in enumerate(rows):
        physical = {k: v for k, v in row.values.items() if k != BOARD}
        try:
            p = PhysicsParams.from_mapping({**spec.fixed, **physical})
        except PhysicsError as err:
            row.error = f"rejected: {_one_sentence(err)}"
            continue
        refusal = board_refusal(row.values.get(BOARD, spec.board), p)
        if refusal:                       # refused before solving: it cannot be wired
            row.error = f"rejected: {refusal}"
            continue
        params[i] = p
        row.digest = (wrench_digest(params[i]) if needs_wrench else params[i].grid_digest()
                      if needs_grid else params[i].digest())
    rows[0].values = {name: getattr(params[0], name) for name in spec.varied if name != BOARD}

    noise_v = spec.output_noise_v

    def measure(row: DesignRow, curve: Any, grid: Any, wrench: Any) -> None:
        try:
            if needs_curve:
                row.metrics.update(curve_metrics(curve, noise_v))
            if needs_grid:
                row.metrics.update(matrix_metrics(grid))
            if needs_wrench:
                row.metrics.update(wrench_metrics(wrench, noise_v, spec.sample_noise_v,
                                                  spec.sample_rate_hz))
        except PhysicsError as err:
            row.error = _one_sentence(err)

    todo: dict[str, list[int]] = {}       # digest -> rows (equal designs solve once)
    for i, p in params.items():
        row = rows[i]
        error_file = _error_path(cache_dir, row.digest)
        if error_file.is_file():
            try:
                row.error = str(json.loads(error_file.read_text())["error"])
                row.worker = "cache"
                continue
            except (ValueError, KeyError, OSError, TypeError):
                pass
        curve = cached_curve(p, cache_dir) if needs_curve else None
        grid = cached_grid(p, cache_dir) if needs_grid else None
        wrench = cached_wrench_set(p, cache_dir) if needs_wrench else None
        if (curve is None and needs_curve) or (grid is None and needs_grid) or (
                wrench is None and needs_wrench):
            todo.setdefault(row.digest, []).append(i)
            continue
        row.worker = "cache"
        row.seconds = sum(part.seconds for part in (curve, grid, wrench) if part is not None)
        measure(row, curve, grid, wrench)

    keys = list(todo)
    if progress is not None:
        progress(0.0, f"{len(rows)} designs: {len(rows) - sum(map(len, todo.values()))} "
                 f"done before (cache or rejected), {len(keys)} to solve")
    cost = (CURVE_COST if needs_curve else 0.0) + (GRID_COST if needs_grid else 0.0) + \
        (WRENCH_COST if needs_wrench else 0.0)
    args = [({k: list(v) if isinstance(v, tuple) else v
              for k, v in params[todo[key][0]].to_dict().items()}, needs_curve, needs_grid,
             needs_wrench) for key in keys]
    for result in run(design_task, args, scheduler=scheduler, workers=workers,
                      costs=[cost] * len(args), progress=progress, label="design"):
        key = keys[result.index]
        p = params[todo[key][0]]
        curve = grid = wrench = None
        error = ""
        if result.error is not None:
            error = _one_sentence(result.error)
            if isinstance(result.error, PhysicsError):
                _store_error(cache_dir, key, error)
        else:
            if needs_curve:
                curve = PredictionCurve.from_dict(result.value["curve"])
                store_curve(p, curve, cache_dir)
            if needs_grid:
                from .array_grid import ArrayGrid

                grid = ArrayGrid.from_dict(result.value["grid"])
                store_grid(p, grid, cache_dir)
            if needs_wrench:
                wrench = WrenchSet.from_dict(result.value["wrench"])
                store_wrench_set(p, wrench, cache_dir)
        for i in todo[key]:
            row = rows[i]
            row.seconds, row.worker, row.error = result.seconds, result.worker, error
            if not error:
                measure(row, curve, grid, wrench)
    return rows


def _store_error(cache_dir: Path | None, digest: str, error: str) -> None:
    path = _error_path(cache_dir, digest)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps({"error": error}) + "\n", encoding="utf-8")
    except OSError:
        pass


def metric_value(row: DesignRow, column: str) -> float:
    """The row's metric, NaN for a failed design or a metric it lacks."""
    return float(row.metrics.get(column, math.nan)) if row.ok else math.nan
