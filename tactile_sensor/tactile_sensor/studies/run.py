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

from tactile_sensor.physics.batch import run
from tactile_sensor.physics.errors import PhysicsError
from tactile_sensor.physics.observability import wrench_metrics
from tactile_sensor.physics.params import PhysicsParams

from .metrics import curve_metrics, matrix_metrics
from .spec import (
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
    from tactile_sensor.physics.array_grid import compute_grid
    from tactile_sensor.physics.prediction import compute_curve
    from tactile_sensor.physics.wrench import compute_wrench_set

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
    from tactile_sensor.physics.prediction import cache_file

    return cache_file(cache_dir, f"study-error-{digest}.json")


def _one_sentence(err: BaseException) -> str:
    text = " ".join(str(err).split())
    return text if isinstance(err, PhysicsError) else f"{type(err).__name__}: {text}"


@dataclass(frozen=True)
class _Needs:
    """Which solves a study's metrics need: the curve, the array grid, the wrench set."""

    curve: bool
    grid: bool
    wrench: bool

    @classmethod
    def of(cls, spec: StudySpec) -> _Needs:
        return cls(any(m in SINGLE_METRICS for m in spec.metrics), MATRIX_METRIC in spec.metrics,
                   WRENCH_METRIC in spec.metrics)

    def digest(self, params: PhysicsParams) -> str:
        """The key of everything the design solves: designs equal in it solve once."""
        from tactile_sensor.physics.wrench import wrench_digest

        return (wrench_digest(params) if self.wrench else params.grid_digest() if self.grid
                else params.digest())

    def cost(self) -> float:
        return (CURVE_COST if self.curve else 0.0) + (GRID_COST if self.grid else 0.0) + \
            (WRENCH_COST if self.wrench else 0.0)


def run_study(spec: StudySpec, *, scheduler: str | None = None, workers: int | None = None,
              cache_dir: Path | None = None, progress: Progress | None = None
              ) -> list[DesignRow]:
    """Every design's row (the paper's first), computing only what the cache lacks."""
    needs = _Needs.of(spec)
    designs = [(REFERENCE, {})] + [(str(i), d) for i, d in enumerate(spec.designs())]
    rows = [DesignRow(name, values) for name, values in designs]
    params = _checked_params(spec, needs, rows)
    todo = _measure_cached(spec, needs, rows, params, cache_dir)
    if progress is not None:
        progress(0.0, f"{len(rows)} designs: {len(rows) - sum(map(len, todo.values()))} "
                 f"done before (cache or rejected), {len(todo)} to solve")
    _solve_and_measure(spec, needs, rows, params, todo, cache_dir, scheduler, workers,
                       progress)
    return rows


def _checked_params(spec: StudySpec, needs: _Needs, rows: list[DesignRow]
                    ) -> dict[int, PhysicsParams]:
    """Each design's parameters by row; a design the model or the board refuses is a row
    with its error and no parameters."""
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
        row.digest = needs.digest(p)
    rows[0].values = {name: getattr(params[0], name) for name in spec.varied if name != BOARD}
    return params


def _measure(spec: StudySpec, needs: _Needs, row: DesignRow, curve: Any, grid: Any,
             wrench: Any) -> None:
    try:
        if needs.curve:
            row.metrics.update(curve_metrics(curve, spec.output_noise_v))
        if needs.grid:
            row.metrics.update(matrix_metrics(grid))
        if needs.wrench:
            row.metrics.update(wrench_metrics(wrench, spec.output_noise_v, spec.sample_noise_v,
                                              spec.sample_rate_hz))
    except PhysicsError as err:
        row.error = _one_sentence(err)


def _measure_cached(spec: StudySpec, needs: _Needs, rows: list[DesignRow],
                    params: dict[int, PhysicsParams], cache_dir: Path | None
                    ) -> dict[str, list[int]]:
    """Measure every design the cache holds (or whose model error it holds); the rest by
    digest (equal designs solve once)."""
    from tactile_sensor.physics.array_grid import cached_grid
    from tactile_sensor.physics.prediction import cached_curve
    from tactile_sensor.physics.wrench import cached_wrench_set

    todo: dict[str, list[int]] = {}
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
        curve = cached_curve(p, cache_dir) if needs.curve else None
        grid = cached_grid(p, cache_dir) if needs.grid else None
        wrench = cached_wrench_set(p, cache_dir) if needs.wrench else None
        if (curve is None and needs.curve) or (grid is None and needs.grid) or (
                wrench is None and needs.wrench):
            todo.setdefault(row.digest, []).append(i)
            continue
        row.worker = "cache"
        row.seconds = sum(part.seconds for part in (curve, grid, wrench) if part is not None)
        _measure(spec, needs, row, curve, grid, wrench)
    return todo


def _solve_and_measure(spec: StudySpec, needs: _Needs, rows: list[DesignRow],
                       params: dict[int, PhysicsParams], todo: dict[str, list[int]],
                       cache_dir: Path | None, scheduler: str | None, workers: int | None,
                       progress: Progress | None) -> None:
    """Solve each digest of ``todo`` as a batch task, cache what arrives and measure it."""
    keys = list(todo)
    args = [({k: list(v) if isinstance(v, tuple) else v
              for k, v in params[todo[key][0]].to_dict().items()}, needs.curve, needs.grid,
             needs.wrench) for key in keys]
    for result in run(design_task, args, scheduler=scheduler, workers=workers,
                      costs=[needs.cost()] * len(args), progress=progress, label="design"):
        key = keys[result.index]
        parts: tuple[Any, Any, Any] = (None, None, None)
        error = ""
        if result.error is not None:
            error = _one_sentence(result.error)
            if isinstance(result.error, PhysicsError):
                _store_error(cache_dir, key, error)
        else:
            parts = _store_parts(needs, params[todo[key][0]], result.value, cache_dir)
        for i in todo[key]:
            row = rows[i]
            row.seconds, row.worker, row.error = result.seconds, result.worker, error
            if not error:
                _measure(spec, needs, row, *parts)


def _store_parts(needs: _Needs, p: PhysicsParams, value: dict[str, Any],
                 cache_dir: Path | None) -> tuple[Any, Any, Any]:
    """A design task's curve, grid and wrench set (None where not needed), each cached."""
    from tactile_sensor.physics.array_grid import ArrayGrid, store_grid
    from tactile_sensor.physics.prediction import PredictionCurve, store_curve
    from tactile_sensor.physics.wrench import WrenchSet, store_wrench_set

    curve = grid = wrench = None
    if needs.curve:
        curve = PredictionCurve.from_dict(value["curve"])
        store_curve(p, curve, cache_dir)
    if needs.grid:
        grid = ArrayGrid.from_dict(value["grid"])
        store_grid(p, grid, cache_dir)
    if needs.wrench:
        wrench = WrenchSet.from_dict(value["wrench"])
        store_wrench_set(p, wrench, cache_dir)
    return curve, grid, wrench


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
