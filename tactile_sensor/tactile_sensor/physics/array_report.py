"""Fit the array calibration to the FEM grid, measure it on held-out points, plot both.

The error reported is the honest one: a fit on the grid without its held-out points
(``ArrayGrid.held_out``), evaluated on them. The calibration handed out is then refitted on
every point (more data, same model), so its error is at most that.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from tactile_sensor.sensing.array_calibration import ArrayCalibration

from .array_grid import ArrayGrid
from .params import PhysicsParams

AXIS_NAMES = ("x", "y", "z")
#: Output noise [V] the grid fit is made robust to (``ArrayCalibration.fit``'s noise_v):
#: about a module's noise after the driver's filter at the paper's 31.5 dB (13 mV) halved,
#: which cost the held-out grid error little (Fz 17 mN) and cut the noise's way into Fz
#: tenfold (1.75 N -> 0.16 N of rmse at 13 mV).
FIT_NOISE_V = 0.005
#: Module output noise [V] at which the report states each force's noise (the paper's
#: resolution, 0.186 N x 0.07 V/N, after its 9-point mean).
PROBE_NOISE_V = 0.013


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


def fit_grid(grid: ArrayGrid, degree: int, noise_v: float = FIT_NOISE_V
             ) -> tuple[ArrayCalibration, dict[str, Any]]:
    """(calibration fitted on all points, report of the held-out test and noise response)."""
    outputs, forces = grid.output_matrix(), grid.force_matrix()
    held = grid.held_out()
    source = f"fem-array:{grid.digest}"
    trial = ArrayCalibration.fit(grid.faces, outputs[~held], forces[~held], degree, source,
                                 noise_v)
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
    full = ArrayCalibration.fit(grid.faces, outputs, forces, degree, source, noise_v)
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
