"""What a study measures of a design: one module's curve, several modules' matrix, and
the wrench observability of a layout.

Single module (from the prediction curve, output against normal force over 0 ..
max_indentation): sensitivity [V/N] = full-scale output / full-scale force (the mean slope
the paper quotes, 0.07 V/N); full scale [N] = force at max_indentation; linearity [% FS] =
largest deviation of the output from the end-point line (0, 0)-(F_fs, V_fs), over V_fs;
dynamic range [dB] = 20 log10(V_fs / noise) (the paper: 31.5 dB at 13 mV).

Several modules (from the array grid's load paths): the sensitivity matrix S (modules x
Fx, Fy, Fz) [V/N], the least-squares linear map from force to outputs over the grid (no
offset: rest reads zero); its singular values, condition number (largest / smallest of
three; infinite when fewer than three modules or a force axis moves no output) and
cross-talk (largest |cosine| between two force axes' output patterns: 0 when each axis moves
the modules its own way, 1 when two axes look alike to the modules).

Wrench: ``physics/observability.py`` (the model's array calibration decides its observed
components with the same metric); this module names its study columns.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from tactile_sensor.physics.errors import PhysicsError
from tactile_sensor.physics.observability import NOISE_BANDWIDTHS_HZ
from tactile_sensor.physics.params import FACES
from tactile_sensor.physics.wrench import WRENCH_AXES

if TYPE_CHECKING:
    from tactile_sensor.physics.array_grid import ArrayGrid
    from tactile_sensor.physics.prediction import PredictionCurve

AXES = ("fx", "fy", "fz")


def curve_metrics(curve: PredictionCurve, noise_v: float) -> dict[str, float]:
    """Sensitivity, full scale, linearity and dynamic range of the first module's curve."""
    force, output = np.asarray(curve.force_n, float), np.asarray(curve.output_v, float)
    f_fs, v_fs = float(force[-1]), float(output[-1])
    if not (f_fs > 0 and v_fs > 0):
        raise PhysicsError("The design's output or force does not grow with indentation, so "
                           "it has no sensitivity; check its window and band.")
    line = v_fs / f_fs * force
    return {"sensitivity_v_per_n": v_fs / f_fs, "full_scale_n": f_fs,
            "linearity_pct_fs": float(np.max(np.abs(output - line)) / v_fs * 100.0),
            "dynamic_range_db": 20.0 * math.log10(v_fs / noise_v)}


def sensitivity_matrix(grid: ArrayGrid) -> np.ndarray:
    """(modules, 3) least-squares S with outputs = S @ (Fx, Fy, Fz) over the grid [V/N]."""
    forces, outputs = grid.force_matrix(), grid.output_matrix()
    solution, *_ = np.linalg.lstsq(forces, outputs, rcond=None)
    return solution.T


def matrix_metrics(grid: ArrayGrid) -> dict[str, float]:
    """S's entries by face and axis (NaN where no module), singular values, condition
    number, cross-talk and shear sensitivity (largest single module's |S| per lateral
    axis, mean of x and y)."""
    s = sensitivity_matrix(grid)
    out: dict[str, float] = {f"s_{face}_{axis}_v_per_n": math.nan for face in FACES
                             for axis in AXES}
    for row, face in zip(s, grid.faces, strict=True):
        for value, axis in zip(row, AXES, strict=True):
            out[f"s_{face}_{axis}_v_per_n"] = float(value)
    singular = np.zeros(3)
    values = np.linalg.svd(s, compute_uv=False)
    singular[:values.size] = values[:3]
    for k, value in enumerate(singular, start=1):
        out[f"singular_value_{k}_v_per_n"] = float(value)
    out["condition_number"] = (float(singular[0] / singular[2])
                               if singular[2] > 1e-12 * max(singular[0], 1e-300) else math.inf)
    norms = np.linalg.norm(s, axis=0)
    cosines = [abs(float(s[:, i] @ s[:, j]) / (norms[i] * norms[j]))
               if norms[i] > 0 and norms[j] > 0 else 1.0
               for i in range(3) for j in range(i + 1, 3)]
    out["crosstalk"] = max(cosines)
    out["shear_sensitivity_v_per_n"] = float(np.mean(np.abs(s[:, :2]).max(axis=0)))
    return out


#: The study table's columns of the metric ``wrench_observability``.
WRENCH_COLUMNS = ("observed_torques", "wrench_rank",
                  *(f"wrench_singular_value_{k}_v" for k in range(1, 7)),
                  *(f"observes_{a}" for a in WRENCH_AXES),
                  *(f"distinct_{a}_v" for a in WRENCH_AXES),
                  *(f"full_scale_{a}_{'n' if a.startswith('f') else 'nm'}"
                    for a in WRENCH_AXES),
                  "output_noise_v",
                  *(f"noise_{a}_pct_fs_{hz}hz" for hz in NOISE_BANDWIDTHS_HZ
                    for a in WRENCH_AXES))
