"""Where to clip the joint module on a bending finger: a placement study on Dask.

SPEC (``config/studies/bend_placement.yaml``)::

    kind: bend_placement
    name: joint module placement
    geometry: {mesh_size: 0.004}       # BendGeometry fields (SI); defaults otherwise
    clip_position_m: -0.005            # the joint module's clip, on the proximal phalanx
    window_positions_m: [0.002, 0.005, 0.008, 0.012]   # where its photoreflector looks
    around: [0.015]                    # windows inside a clip around the bending skin
    forces_n: [0.0, 1.1, 2.2]          # tip forces of each design's grid
    noise_v: 0.013                     # [V] output noise (the paper's, after its mean)

Each design is the joint module at one place with the fingertip module of
``bend.default_modules``; its response is the cached ``BendResponse`` (one per design
digest, shared with ``bend.load_or_compute_response``), solved as one batch task
(``physics/batch.py``) where the cache lacks it. Measured per design: the joint module's
mean sensitivity over 0-90 deg [V/rad], its swing, the condition number of the
two-module Jacobian d(outputs)/d(angle, force) with the angle in units of 90 deg and the
force of 2 N (1: both seen alike; large: the two cannot be told apart), at half the
grid's largest force, the angle's standard deviation from the two-module inverse at the
output noise [deg] there, and the angle error a single joint module makes under an
unknown contact of the grid's largest force [deg].
"""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from tactile_sensor.physics.batch import run
from tactile_sensor.physics.bend import (
    DEFAULT_ANGLES,
    BendGeometry,
    BendModule,
    BendResponse,
    cached_response,
    compute_response,
    default_modules,
    response_path,
)
from tactile_sensor.physics.errors import PhysicsError
from tactile_sensor.physics.prediction import write_cache
from tactile_sensor.physics.yaml_file import read_yaml

from .spec import StudySpecError

Progress = Callable[[float, str], None]
KIND = "bend_placement"
KEYS = ("kind", "name", "geometry", "clip_position_m", "window_positions_m", "around",
        "forces_n", "noise_v")
#: The range the metrics cover: the issue's 0-90 deg and 0-2 N.
SPAN_RAD, SPAN_N = math.pi / 2, 2.0


@dataclass(frozen=True)
class BendStudySpec:
    """A parsed placement study."""

    name: str
    geometry: BendGeometry
    designs: tuple[BendModule, ...]
    forces_n: tuple[float, ...]
    noise_v: float

    def layouts(self) -> list[tuple[BendModule, BendModule]]:
        tip = default_modules(self.geometry)[1]
        return [(m, tip) for m in self.designs]


@dataclass
class PlacementRow:
    """One design's joint module, metrics, and its error if its solve failed."""

    module: BendModule
    metrics: dict[str, float] = field(default_factory=dict)
    curve_v: list[float] = field(default_factory=list)
    sigma_deg: list[float] = field(default_factory=list)
    error: str = ""
    worker: str = ""


def is_bend_spec(data: Any) -> bool:
    return isinstance(data, Mapping) and data.get("kind") == KIND


def load_bend_spec(path: Path) -> BendStudySpec:
    data = read_yaml(path, "the study spec", StudySpecError,
                     ", e.g. config/studies/bend_placement.yaml")
    return parse_bend_spec(data, path.stem)


def _numbers(data: Mapping[str, Any], key: str, default: Any) -> list[float]:
    value = data.get(key, default)
    if not isinstance(value, list) or any(isinstance(v, bool) or not isinstance(
            v, int | float) or not math.isfinite(v) for v in value):
        raise StudySpecError(f"'{key}' must be a list of numbers in SI units; fix it.")
    return [float(v) for v in value]


def parse_bend_spec(data: Any, name: str = "bend study") -> BendStudySpec:
    """A placement study from its YAML mapping (one sentence on any problem)."""
    if not is_bend_spec(data):
        raise StudySpecError(f"a placement study needs 'kind: {KIND}'.")
    unknown = [str(k) for k in data if k not in KEYS]
    if unknown:
        raise StudySpecError(f"the study spec has unknown key {unknown[0]!r}; use "
                             f"{', '.join(KEYS)}.")
    geometry_data = data.get("geometry") or {}
    if not isinstance(geometry_data, Mapping):
        raise StudySpecError("'geometry' must map finger parameters to values.")
    try:
        geometry = BendGeometry(**geometry_data)
    except TypeError as err:
        raise StudySpecError(f"'geometry' names an unknown finger parameter ({err}); see "
                             "BendGeometry.") from None
    except PhysicsError as err:
        raise StudySpecError(f"'geometry' is rejected: {err}") from None
    clip = data.get("clip_position_m", -0.005)
    if isinstance(clip, bool) or not isinstance(clip, int | float) or not math.isfinite(clip):
        raise StudySpecError("'clip_position_m' must be a number of metres.")
    windows = _numbers(data, "window_positions_m", [])
    around = _numbers(data, "around", [])
    if not windows and not around:
        raise StudySpecError("the study needs 'window_positions_m' or 'around': where the "
                             "joint module looks.")
    forces = _numbers(data, "forces_n", [0.0, 1.1, 2.2])
    if len(forces) < 2 or forces[0] != 0.0 or np.any(np.diff(forces) <= 0):
        raise StudySpecError("'forces_n' must rise from 0 through at least two values.")
    noise = data.get("noise_v", 0.013)
    if isinstance(noise, bool) or not isinstance(noise, int | float) or not \
            math.isfinite(noise) or noise <= 0:
        raise StudySpecError(f"'noise_v' is {noise!r}; give a positive number of volts.")
    designs = []
    try:
        for s in windows:
            designs.append(BendModule(s, "dorsal", clip_position_m=float(clip)))
        designs += [BendModule(s, "dorsal") for s in around]
        for m in designs:
            m.check(geometry)
    except PhysicsError as err:
        raise StudySpecError(f"a placement is rejected: {err}") from None
    return BendStudySpec(str(data.get("name") or name), geometry, tuple(designs),
                         tuple(forces), float(noise))


def design_task(geometry: dict[str, Any], modules: list[dict[str, Any]],
                forces: list[float], progress: Progress | None) -> dict[str, Any]:
    """One design's grid on a worker, as plain data (the client caches it)."""
    g = BendGeometry(**geometry)
    return compute_response(g, [BendModule(**m) for m in modules], DEFAULT_ANGLES, forces,
                            progress=progress).to_dict()


def measure(response: BendResponse, noise_v: float) -> tuple[dict[str, float], list[float],
                                                             list[float]]:
    """The metrics of the module docstring, the joint module's output at 0 N over the
    study's angles [V] and the two-module angle deviation there [deg]."""
    angles = np.linspace(0.0, SPAN_RAD, 19)
    top = response.force_range_n[1]
    out0 = response.output_v(angles, 0.0)[:, 0]
    out2 = response.output_v(angles, top)[:, 0]
    jac = response.output_jacobian(angles, top / 2) * np.array([SPAN_RAD, SPAN_N])
    cond = np.linalg.cond(jac)
    sigma = []
    for k in range(angles.size):
        raw = response.output_jacobian(angles[k], top / 2)
        inv = np.linalg.pinv(raw)
        sigma.append(math.degrees(noise_v * float(np.linalg.norm(inv[0]))))
    sens = np.gradient(out0, angles)
    single = np.full(angles.size, math.nan)
    ok = np.abs(sens) > 1e-9
    single[ok] = np.abs((out2 - out0)[ok] / sens[ok])
    return ({"sensitivity_v_per_rad": float((out0[-1] - out0[0]) / SPAN_RAD),
             "min_sensitivity_v_per_rad": float(np.min(np.abs(sens))),
             "swing_v": float(np.ptp(out0)),
             "jacobian_condition": float(np.nanmedian(cond)),
             "angle_sigma_deg": float(np.nanmedian(sigma)),
             "one_module_contact_error_deg": float(math.degrees(np.nanmedian(single)))},
            out0.tolist(), sigma)


def run_bend_study(spec: BendStudySpec, *, scheduler: str | None = None,
                   workers: int | None = None, cache_dir: Path | None = None,
                   progress: Progress | None = None) -> list[PlacementRow]:
    """Every placement measured, solving (as batch tasks) only what the cache lacks."""
    layouts = spec.layouts()
    rows = [PlacementRow(layout[0]) for layout in layouts]
    todo = []
    for i, layout in enumerate(layouts):
        cached = cached_response(spec.geometry, layout, DEFAULT_ANGLES, spec.forces_n,
                                 cache_dir)
        if cached is None:
            todo.append(i)
        else:
            rows[i].worker = "cache"
            rows[i].metrics, rows[i].curve_v, rows[i].sigma_deg = measure(cached,
                                                                          spec.noise_v)
    args = [(spec.geometry.to_dict(), [m.to_dict() for m in layouts[i]],
             list(spec.forces_n)) for i in todo]
    for result in run(design_task, args, scheduler=scheduler, workers=workers,
                      progress=progress, label="placement"):
        i = todo[result.index]
        row = rows[i]
        row.worker = result.worker
        if result.error is not None:
            row.error = " ".join(str(result.error).split())
            continue
        response = BendResponse.from_dict(result.value)
        write_cache(response_path(spec.geometry, layouts[i], DEFAULT_ANGLES, spec.forces_n,
                                  cache_dir), response.to_dict())
        row.metrics, row.curve_v, row.sigma_deg = measure(response, spec.noise_v)
    return rows


COLUMNS = ("sensitivity_v_per_rad", "min_sensitivity_v_per_rad", "swing_v",
           "jacobian_condition", "angle_sigma_deg", "one_module_contact_error_deg")


def write_bend_results(rows: list[PlacementRow], spec: BendStudySpec, out: Path
                       ) -> dict[str, Path]:
    """results.csv, summary.json and placement.png in ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    paths = {"results": out / "results.csv", "summary": out / "summary.json",
             "figure": out / "placement.png"}
    with paths["results"].open("w", newline="") as handle:
        w = csv.writer(handle)
        w.writerow(["window_position_m", "clip", *COLUMNS, "error"])
        for r in rows:
            w.writerow([r.module.arc_position_m, "around" if r.module.clip_position_m is None
                        else f"{r.module.clip_position_m}",
                        *(f"{r.metrics.get(c, math.nan):.6g}" for c in COLUMNS), r.error])
    good = [r for r in rows if not r.error]
    best = min(good, key=lambda r: r.metrics["angle_sigma_deg"]) if good else None
    paths["summary"].write_text(json.dumps({
        "name": spec.name, "noise_v": spec.noise_v,
        "best": None if best is None else {"window_position_m": best.module.arc_position_m,
                                           **best.metrics},
        "rows": [{"module": r.module.label, **r.metrics, "error": r.error} for r in rows]},
        indent=1) + "\n")
    plot_placement(rows, spec, paths["figure"])
    return paths


def plot_placement(rows: list[PlacementRow], spec: BendStudySpec, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    angles = np.degrees(np.linspace(0.0, SPAN_RAD, 19))
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 4))
    for r in rows:
        if r.error:
            continue
        curve = np.array(r.curve_v)
        line, = ax1.plot(angles, curve, label=r.module.label)
        ax1.fill_between(angles, curve - spec.noise_v, curve + spec.noise_v,
                         color=line.get_color(), alpha=0.2)
        ax2.plot(angles, r.sigma_deg, color=line.get_color(), label=r.module.label)
    ax1.set_xlabel("joint angle [deg]")
    ax1.set_ylabel("joint module output [V] (no contact; band: ±noise)")
    ax1.legend(fontsize=7)
    ax2.set_xlabel("joint angle [deg]")
    ax2.set_ylabel("angle std from both modules [deg]")
    ax2.set_yscale("log")
    ax2.axhline(2.0, color="grey", ls="--", lw=0.8)
    fig.suptitle(spec.name)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
