"""Fit the array calibration to the FEM grid, measure it on held-out points, plot both.

The error reported is the honest one: a fit on the grid without its held-out points
(``ArrayGrid.held_out``), evaluated on them. The calibration handed out is then refitted on
every point (more data, same model), so its error is at most that.

With the layout's wrench set (``physics/wrench.py``) the calibration gains torque columns:
forces from the grid as without it, torques from the wrench paths (press, shear, tilt,
twist, with their mirror images) and the grid's own torques (``ArrayCalibration.fit`` with
NaN where a set lacks a component). Forces stay off the wrench paths: on a coarse 8-module
grid (degree 2) those paths cut Fx's error under tilt from 80 to 61 mN but tripled its
noise at 13 mV (51 to 148 mN), separating shear from tilt on small output differences.
The wrench set is small, so the torque is a linear polynomial (``WRENCH_TORQUE_DEGREE``)
whose gains follow the press (``WRENCH_TORQUE_PRESS_SCALED``), fitted on the FEM's outputs
as they are (unbiased: the driver's torque low-pass narrows its
noise), and checked twice: on wrench points held out (interior load
steps), and on the grid's held-out points, whose shear directions lie between the wrench
paths' and reach larger shear. Fitted on the wrench set alone, the torque read 12.7 mN m rms
of Tx on a tiny grid where the FEM said far less: the tilt's output pattern is the shear's,
and the wrench set holds only the smallest shear level.
``observed`` is what ``observability.wrench_metrics`` resolves at ``observe_noise_v``, the
module noise left at the driver's torque bandwidth.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from tactile_sensor.sensing.array_calibration import COMPONENTS, ArrayCalibration

from .array_grid import ArrayGrid
from .errors import PhysicsError
from .observability import wrench_metrics
from .output_noise import noise_at_bandwidth
from .params import PhysicsParams
from .wrench import WrenchSet

AXIS_NAMES = ("x", "y", "z")
TORQUE_NAMES = ("tx", "ty", "tz")
#: Output noise [V] the grid fit is made robust to (``ArrayCalibration.fit``'s noise_v):
#: about a module's noise after the driver's filter at the paper's 31.5 dB (13 mV) halved,
#: which cost the held-out grid error little (Fz 17 mN) and cut the noise's way into Fz
#: tenfold (1.75 N -> 0.16 N of rmse at 13 mV).
FIT_NOISE_V = 0.005
#: Module output noise [V] at which the report states each force's noise (the paper's
#: resolution, 0.186 N x 0.07 V/N, after its 9-point mean).
PROBE_NOISE_V = 0.013
#: Output noise [V] the six-column fit's force polynomial is made robust to: the noise it
#: meets, what the driver's force filter leaves (the paper's 13 mV). Eight modules give the
#: degree-3 force polynomial more terms that can amplify a module's noise than four, and at
#: FIT_NOISE_V Fz's rmse on the wrench protocol was 5.0 % of its range (bias -0.31 N, spread
#: 0.18 N); at 8 mV 4.0 %, at 13 mV 3.7 % (spread 0.13 N), the held-out grid error rising
#: from 35 to 45 mN.
WRENCH_FIT_NOISE_V = PROBE_NOISE_V
#: The torque bandwidth [Hz] of the wrench configuration (its driver's ``torque_cutoff_hz``):
#: where the unbiased torque's noise at rest is about 5 % of each torque's range on the
#: wrench protocol (Tx, Ty 0.63 and Tz 0.25 N m per volt of module noise at rest, times the
#: 3.2 mV that a 3 Hz low-pass leaves: 2.0 and 0.8 mN m). At 10 Hz the same torque carries
#: 3.7 and 1.4 mN m: a bandwidth bought with that noise, never with a shrunken gain.
TORQUE_BANDWIDTH_HZ = 3.0
#: Module output noise [V] at which ``observed`` is decided unless told otherwise: what the
#: driver's torque low-pass leaves of the module noise at TORQUE_BANDWIDTH_HZ (3.2 mV;
#: physics/output_noise.py). A driver run at a wider torque bandwidth sees more.
OBSERVE_NOISE_V = noise_at_bandwidth(TORQUE_BANDWIDTH_HZ)
#: Output noise [V] the torque fit (and the force's slow part) is made robust to: none. A
#: fit on noisy copies of the outputs is a ridge that pulls the weak directions toward zero
#: (regression dilution): at 10 mV, degree 2, the tilts' torque read 0.29 and the twist's
#: 0.36 of the FEM's on held-out wrench points, 0.89 and 0.96 even at 1 mV. The noise is
#: traded in the driver's torque low-pass instead (TORQUE_BANDWIDTH_HZ).
TORQUE_FIT_NOISE_V = 0.0
#: Degree of the torque polynomial (and the force's slow part): 1, so that noise cannot
#: bias it. Fitted without noise, degree 2's cancelling quadratic terms turned 1 V of module
#: noise into 10^6 N m; with 0.1 mV of noise in the fit (gains 0.99-1.01) they still turned
#: the 13 mV the polynomial reads into a mean offset (noise squared) of up to 6.5 mN m of Tx
#: (Tx rmse 12 % of range on the wrench protocol). A linear torque has no such term; it reads
#: 0.97-1.07 of the FEM's torque on held-out wrench points in every load phase and 0.93-0.98
#: along the wrench protocol (its curvature left out; the force's slow part 0.91-0.93), at
#: 0.63 N m/V (Tx, Ty) and 0.25 N m/V (Tz) of module noise.
WRENCH_TORQUE_DEGREE = 1
#: Each linear torque term's gain follows the press (``sensing.press_scaled_terms``): the
#: linear torque left its curvature in depth out and read 0.93 of the shear's torque, 0.955
#: of the twist's and 0.92 of the tilt's lateral force along the wrench protocol (noise-free
#: mock outputs against the elastic gauge); with the press gains 0.97-1.03, and no mean
#: offset from noise (its products pair orthogonal features).
WRENCH_TORQUE_PRESS_SCALED = True


def noise_response(cal: ArrayCalibration, outputs: np.ndarray, forces: np.ndarray,
                   sigma_v: float = PROBE_NOISE_V) -> np.ndarray:
    """RMS force error [N] per axis when every module's output carries white noise of
    ``sigma_v``, over the grid points pressed past half the normal range (fixed seed)."""
    pressed = forces[:, 2] >= 0.5 * forces[:, 2].max()
    rng = np.random.default_rng(1)
    noisy = outputs[pressed][None] + rng.normal(0.0, sigma_v, (64, int(pressed.sum()),
                                                               outputs.shape[1]))
    error = cal.forces(noisy.reshape(-1, outputs.shape[1])) - np.tile(forces[pressed], (64, 1))
    return np.sqrt(np.mean(error**2, axis=0))


def fit_grid(grid: ArrayGrid, degree: int, noise_v: float = FIT_NOISE_V,
             observed: Sequence[str] | None = None) -> tuple[ArrayCalibration, dict[str, Any]]:
    """(calibration fitted on all points, report of the held-out test and noise response);
    ``observed``: the force components to fit (default all three)."""
    outputs, forces = grid.output_matrix(), grid.force_matrix()
    held = grid.held_out()
    source = f"fem-array:{grid.digest}"
    trial = ArrayCalibration.fit(grid.faces, outputs[~held], forces[~held], degree, source,
                                 noise_v, observed=observed)
    error = trial.forces(outputs[held]) - forces[held]
    span = forces.max(axis=0) - forces.min(axis=0)
    rmse = np.sqrt(np.mean(error**2, axis=0)) if held.any() else np.full(3, np.nan)
    worst = np.abs(error).max(axis=0) if held.any() else np.full(3, np.nan)
    lateral = np.hypot(grid.force_x_n, grid.force_y_n)
    pressed = grid.force_n > 0
    report = {
        "degree": degree, "faces": list(grid.faces),
        "terms": dict(zip(AXIS_NAMES, np.count_nonzero(trial.coefficients, axis=1).tolist(),
                          strict=True)),
        "points": int(held.size), "fitted_points": int((~held).sum()),
        "held_out_points": int(held.sum()),
        "held_out_rmse_n": dict(zip(AXIS_NAMES, rmse.tolist(), strict=True)),
        "held_out_max_error_n": dict(zip(AXIS_NAMES, worst.tolist(), strict=True)),
        "force_range_n": dict(zip(AXIS_NAMES, span.tolist(), strict=True)),
        "held_out_rmse_percent_of_range": dict(zip(
            AXIS_NAMES, (100 * rmse / np.where(span > 0, span, np.nan)).tolist(),
            strict=True)),
        "max_lateral_over_normal_force": float((lateral[pressed] / grid.force_n[pressed])
                                               .max()) if pressed.any() else 0.0,
        "grid_seconds": grid.seconds, "paths_solved": grid.paths,
        "fit_output_noise_v": noise_v,
    }
    full = ArrayCalibration.fit(grid.faces, outputs, forces, degree, source, noise_v,
                                observed=observed)
    report["noise_rmse_n"] = {"sigma_v": PROBE_NOISE_V, **dict(zip(
        AXIS_NAMES, noise_response(full, outputs, forces).tolist(), strict=True))}
    return full, {**report, "estimate_held_out": trial.forces(outputs[held]).tolist()}


def summary(report: dict[str, Any], params: PhysicsParams, cache: str) -> str:
    rmse, worst = report["held_out_rmse_n"], report["held_out_max_error_n"]
    share = report["held_out_rmse_percent_of_range"]
    lines = [
        f"modules         {', '.join(report['faces'])}",
        f"grid            {report['points']} points: {params.array_steps} indentations "
        f"x {params.array_directions} directions x {params.array_shear_levels} shear levels "
        f"(+ none), shear up to {params.array_shear_ratio:g} x indentation",
        f"paths solved    {report['paths_solved']} (the rest by symmetry), "
        f"{report['grid_seconds']:.1f} s",
        f"friction needed max |F_lateral| / F_normal = "
        f"{report['max_lateral_over_normal_force']:.2f} (the skin slides beyond)",
        f"fit             degree {report['degree']} in pair sums and differences ("
        + ", ".join(f"{k} {v}" for k, v in report["terms"].items()) + " terms) on "
        f"{report['fitted_points']} points, tested on {report['held_out_points']} held out",
    ]
    for axis in AXIS_NAMES:
        lines.append(f"error {axis}         rmse {rmse[axis] * 1e3:.2f} mN "
                     f"({share[axis]:.2f} % of the {report['force_range_n'][axis]:.2f} N "
                     f"range), max {worst[axis] * 1e3:.2f} mN")
    noise = report["noise_rmse_n"]
    lines.append(f"noise           {noise['sigma_v'] * 1e3:.0f} mV on every module's output -> "
                 + ", ".join(f"F{k} {noise[k] * 1e3:.0f} mN" for k in AXIS_NAMES)
                 + f" rmse (the fit saw {report['fit_output_noise_v'] * 1e3:.0f} mV)")
    lines.append(f"cache           {cache}")
    return "\n".join(lines)


def write_plot(grid: ArrayGrid, report: dict[str, Any], path: Path) -> None:
    """Estimated vs FEM force per axis (held-out points marked) and the modules' outputs
    against the shear direction at the deepest indentation and largest shear."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    forces = grid.force_matrix()
    held = grid.held_out()
    estimate = np.asarray(report["estimate_held_out"]).reshape(-1, 3)
    fig, axes = plt.subplots(2, 2, figsize=(10, 8), constrained_layout=True)
    for k, ax in enumerate(axes.flat[:3]):
        ref = forces[held, k]
        ax.plot(forces[:, k], forces[:, k], "-", color="0.7", lw=1, label="ideal")
        ax.plot(ref, estimate[:, k], "o", ms=4, color="tab:blue", label="held-out points")
        rmse = report["held_out_rmse_n"][AXIS_NAMES[k]]
        ax.set(xlabel=f"FEM force {AXIS_NAMES[k]} [N]",
               ylabel=f"calibrated force {AXIS_NAMES[k]} [N]",
               title=f"({'abc'[k]}) F{AXIS_NAMES[k]}: held-out rmse {rmse * 1e3:.1f} mN")
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper left")
    ax = axes.flat[3]
    edge = (grid.step == grid.step.max()) & (grid.level == grid.level.max())
    angle = np.degrees(np.arctan2(grid.shear_y_m[edge], grid.shear_x_m[edge])) % 360
    order = np.argsort(angle)
    for face, values in grid.outputs_v.items():
        ax.plot(angle[order], values[edge][order], "o-", ms=4, label=face)
    ax.set(xlabel="shear direction [deg from +x toward +y]", ylabel="module output [V]",
           title="(d) outputs at the deepest indentation, largest shear")
    ax.set_xticks(range(0, 361, 45))
    ax.grid(True, alpha=0.3)
    ax.legend(loc="center left", bbox_to_anchor=(1.01, 0.5))  # the curves fill the axes
    fig.suptitle(f"Array calibration from the FEM grid (degree {report['degree']}, "
                 f"{report['held_out_points']} of {report['points']} points held out)")
    try:
        fig.savefig(path, dpi=120, format="png")
    finally:
        plt.close(fig)


# -- six columns: forces from the grid, torques from the wrench set ---------------------------


def wrench_held_out(data: WrenchSet) -> np.ndarray:
    """Wrench points kept out of the fit: every path's interior even load steps, in each
    mirror image alike (points are stored per path, image after image, rest once first)."""
    steps = int(np.sum(data.path == 0)) - 1          # the press path: rest + its steps
    held = np.zeros(data.path.size, bool)
    for k in np.unique(data.path):
        where = np.flatnonzero(data.path == k)
        step = np.arange(where.size) if k == 0 else np.arange(where.size) % steps + 1
        held[where] = (step % 2 == 0) & (step > 0) & (step < steps)
    return held


def observed_components(data: WrenchSet, noise_v: float) -> list[str]:
    """The components ``wrench_metrics`` resolves at module noise ``noise_v`` [V]."""
    metrics = wrench_metrics(data, noise_v)
    return [c for c in COMPONENTS if metrics[f"observes_{c}"]]


def _errors(estimate: np.ndarray, truth: np.ndarray) -> tuple[list[float], list[float],
                                                              list[float]]:
    """Per column: rmse, largest |error| and the truth's range (NaN without points)."""
    error = estimate - truth
    if not error.size:
        nan = [float("nan")] * truth.shape[1]
        return nan, nan, nan
    return (np.sqrt(np.mean(error**2, axis=0)).tolist(), np.abs(error).max(axis=0).tolist(),
            (truth.max(axis=0) - truth.min(axis=0)).tolist())


def _wrench_points(grid: ArrayGrid, data: WrenchSet
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The six-column fit's points, the grid's then the wrench paths': outputs, wrench (NaN
    where a point has no known torque), every point's force (for the force's slow part:
    tilt, twist) and which points are held out."""
    n_grid, n_wrench = grid.force_n.size, data.path.size
    outputs = np.concatenate([grid.output_matrix(), data.output_matrix()])
    wrench = np.full((n_grid + n_wrench, 6), np.nan)
    wrench[:n_grid, :3] = grid.force_matrix()
    wrench[n_grid:, 3:] = data.wrench[:, 3:]
    if grid.torque_nm is not None:
        wrench[:n_grid, 3:] = grid.torque_nm
    slow = np.concatenate([grid.force_matrix(), data.wrench[:, :3]])
    held = np.concatenate([grid.held_out(), wrench_held_out(data)])
    return outputs, wrench, slow, held


def _force_held_out(trial: ArrayCalibration, grid: ArrayGrid, report: dict[str, Any]
                    ) -> dict[str, Any]:
    """The force lines of the six-column fit (grid and wrench points), not fit_grid's own."""
    grid_held = grid.held_out()
    forces_held = trial.forces(grid.output_matrix()[grid_held])
    f_rmse, f_worst, _ = _errors(forces_held, grid.force_matrix()[grid_held])
    f_span = np.asarray(list(report["force_range_n"].values()))
    return {
        "held_out_rmse_n": dict(zip(AXIS_NAMES, f_rmse, strict=True)),
        "held_out_max_error_n": dict(zip(AXIS_NAMES, f_worst, strict=True)),
        "held_out_rmse_percent_of_range": dict(zip(AXIS_NAMES, (100 * np.asarray(f_rmse) / np.where(
            f_span > 0, f_span, np.nan)).tolist(), strict=True)),
        "estimate_held_out": forces_held.tolist(),
    }


def _torque_noise(full: ArrayCalibration, data: WrenchSet, noise_v: float) -> np.ndarray:
    """Each torque's estimate error [N m] over 64 noisy copies of the wrench points (module
    noise ``noise_v``), about the noise-free estimate."""
    rng = np.random.default_rng(2)
    outputs = data.output_matrix()
    noisy = outputs[None] + rng.normal(0.0, noise_v, (64, *outputs.shape))
    return full.wrenches(noisy.reshape(-1, outputs.shape[1]))[:, 3:] - np.tile(
        full.wrenches(outputs)[:, 3:], (64, 1))


def fit_wrench(grid: ArrayGrid, data: WrenchSet, degree: int,
               noise_v: float = WRENCH_FIT_NOISE_V,
               observe_noise_v: float = OBSERVE_NOISE_V,
               torque_degree: int = WRENCH_TORQUE_DEGREE,
               torque_noise_v: float | None = None) -> tuple[ArrayCalibration, dict[str, Any]]:
    """(six-column calibration fitted on every point, report): ``fit_grid``'s force report
    plus the torques' held-out errors, the torque read on the shear grid and ``observed``.

    The torque fit sees ``torque_noise_v`` (default ``TORQUE_FIT_NOISE_V``: none) at
    ``torque_degree`` (default ``WRENCH_TORQUE_DEGREE``: linear), so its gain is 1 in every
    load phase; its noise is the driver's low-pass's to narrow (constants above)."""
    if data.modules != grid.faces:
        raise PhysicsError(f"The wrench set's modules ({', '.join(data.modules)}) are not the "
                           f"grid's ({', '.join(grid.faces)}); compute both for one layout.")
    observed = observed_components(data, observe_noise_v)
    torque_noise_v = TORQUE_FIT_NOISE_V if torque_noise_v is None else torque_noise_v
    forces_only = [c for c in observed if not c.startswith("t")]
    _, report = fit_grid(grid, degree, noise_v, forces_only)
    n_wrench = data.path.size
    outputs, wrench, slow, held = _wrench_points(grid, data)
    source = f"fem-array:{grid.digest}+wrench:{data.digest}"
    trial = ArrayCalibration.fit(grid.faces, outputs[~held], wrench[~held], degree, source,
                                 noise_v, torque_degree, observed, torque_noise_v,
                                 slow[~held], WRENCH_TORQUE_PRESS_SCALED)
    test = held[grid.force_n.size:]
    estimate = trial.wrenches(data.output_matrix()[test])
    rmse, worst, _ = _errors(estimate[:, 3:], data.wrench[test, 3:])
    report.update({
        **_force_held_out(trial, grid, report),
        "wrench_held_out_force_rmse_n": dict(zip(AXIS_NAMES, _errors(
            estimate[:, :3], data.wrench[test, :3])[0], strict=True)),
    })
    span = (data.wrench[:, 3:].max(axis=0) - data.wrench[:, 3:].min(axis=0)).tolist()
    grid_held = grid.held_out()
    on_grid = trial.wrenches(grid.output_matrix()[grid_held])[:, 3:] - (
        grid.torque_nm[grid_held] if grid.torque_nm is not None else 0.0)
    full = ArrayCalibration.fit(grid.faces, outputs, wrench, degree, source, noise_v,
                                torque_degree, observed, torque_noise_v, slow,
                                WRENCH_TORQUE_PRESS_SCALED)
    report["terms"] = dict(zip(AXIS_NAMES, np.count_nonzero(full.coefficients, axis=1)
                               .tolist(), strict=True))
    report["noise_rmse_n"] = {"sigma_v": PROBE_NOISE_V, **dict(zip(
        AXIS_NAMES, noise_response(full, grid.output_matrix(), grid.force_matrix()).tolist(),
        strict=True))}
    noise = _torque_noise(full, data, observe_noise_v)

    def per(values: Any) -> dict[str, float]:
        return dict(zip(TORQUE_NAMES, [float(v) for v in values], strict=True))

    report.update({
        "observed": observed, "observe_noise_v": observe_noise_v,
        "torque_fit_output_noise_v": torque_noise_v,
        "torque_degree": min(torque_degree, degree), "wrench_points": int(n_wrench),
        "wrench_held_out_points": int(test.sum()), "wrench_paths_solved": data.paths,
        "wrench_seconds": data.seconds,
        "torque_terms": dict(zip(TORQUE_NAMES, np.count_nonzero(
            full.torque_coefficients, axis=1).tolist(), strict=True)),
        "torque_held_out_rmse_nm": per(rmse), "torque_held_out_max_error_nm": per(worst),
        "torque_range_nm": per(span),
        "torque_held_out_rmse_percent_of_range": per(
            100 * np.asarray(rmse) / np.where(np.asarray(span) > 0, span, np.nan)),
        "torque_on_shear_grid_rmse_nm": per(np.sqrt(np.mean(on_grid**2, axis=0))
                                            if on_grid.size else [np.nan] * 3),
        "grid_torque": "fem" if grid.torque_nm is not None else
        "none (a grid cached before torques; read against 0, recompute with --no-cache)",
        "torque_noise_rmse_nm": {"sigma_v": observe_noise_v,
                                 **per(np.sqrt(np.mean(noise**2, axis=0)))},
    })
    return full, report


def wrench_summary(report: dict[str, Any]) -> str:
    """The torque lines of the summary."""
    under = report["wrench_held_out_force_rmse_n"]
    lines = ["force on wrench rmse " + ", ".join(f"F{k} {under[k] * 1e3:.2f} mN" for k in
                                                AXIS_NAMES)
             + " on held-out wrench points (tilt and twist)",
             f"observed        {', '.join(report['observed'])} (wrench_observability at "
             f"{report['observe_noise_v'] * 1e3:.1f} mV module noise; the rest reads NaN)",
             f"torque fit      degree {report['torque_degree']} ("
             + ", ".join(f"{k} {v}" for k, v in report["torque_terms"].items())
             + f" terms) on {report['wrench_points'] - report['wrench_held_out_points']} "
             f"wrench points ({report['wrench_paths_solved']} paths solved, "
             f"{report['wrench_seconds']:.1f} s), tested on "
             f"{report['wrench_held_out_points']} held out; grid torque "
             f"{report['grid_torque']}"]
    for k in TORQUE_NAMES:
        if k not in report["observed"]:
            lines.append(f"error {k}        not observed")
            continue
        lines.append(
            f"error {k}        rmse {report['torque_held_out_rmse_nm'][k] * 1e3:.3f} mN m "
            f"({report['torque_held_out_rmse_percent_of_range'][k]:.2f} % of the "
            f"{report['torque_range_nm'][k] * 1e3:.2f} mN m range), max "
            f"{report['torque_held_out_max_error_nm'][k] * 1e3:.3f} mN m; grid held out "
            f"{report['torque_on_shear_grid_rmse_nm'][k] * 1e3:.3f} mN m rmse; noise "
            f"{report['torque_noise_rmse_nm'][k] * 1e3:.3f} mN m rms")
    return "\n".join(lines)
