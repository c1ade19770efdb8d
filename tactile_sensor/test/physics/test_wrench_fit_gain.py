"""The six-column fit's gain on held-out points, per load phase: 1 for every component.

A synthetic array stands in for the FEM (fast, and its truth is known): eight modules whose
outputs are linear in the wrench plus the press's quadratic stiffening, the torques a few
millivolts each and nearly in the shear's pattern, the FEM's weak directions. Fitted with
the constants the FEM calibration uses (``physics.array_report``), each phase's held-out
points read their load with a gain of 1; the fit regularised by output noise (10 mV, degree
2, what the calibration did before) reads the tilt and the twist at about half.
"""

from __future__ import annotations

from functools import cache

import numpy as np
import pytest

from tactile_sensor.physics.array_report import (
    TORQUE_FIT_NOISE_V,
    WRENCH_FIT_NOISE_V,
    WRENCH_TORQUE_DEGREE,
    WRENCH_TORQUE_PRESS_SCALED,
)
from tactile_sensor.sensing.array_calibration import ArrayCalibration

FACES = ("front@-0.0055", "front@0.0055", "back@-0.0055", "back@0.0055", "left@-0.0055",
         "left@0.0055", "right@-0.0055", "right@0.0055")
PHASES = ("press", "shear", "tilt", "twist")


def sensitivity() -> np.ndarray:
    """(modules, 6) outputs [V] per N and per N m, with the layout's mirror parities: Fx
    and Ty read on left/right as a difference, Fy and Tx on front/back, Tz as the twist of
    each face's pair; each torque's pattern is the matching shear's plus a small part of
    its own (the tilt's output pattern is the shear's)."""
    s = np.zeros((8, 6))
    s[:, 2] = 0.046                                              # press: every module
    s[[6, 7], 0], s[[4, 5], 0] = 0.115, -0.115                   # Fx: right - left
    s[[0, 1], 1], s[[2, 3], 1] = 0.115, -0.115                   # Fy: front - back
    s[:, 4] = 2.0 * s[:, 0] + np.array([0, 0, 0, 0, -0.6, -0.6, 0.6, 0.6]) * 0.5
    s[:, 3] = -2.0 * s[:, 1] - np.array([0.6, 0.6, -0.6, -0.6, 0, 0, 0, 0]) * 0.5
    s[:, 4] -= np.array([0.1, -0.1, 0.1, -0.1, 0, 0, 0, 0])      # Ty: front/back pairs tilt
    s[:, 3] += np.array([0, 0, 0, 0, 0.1, -0.1, 0.1, -0.1])
    s[:, 5] = np.array([1, -1, -1, 1, 1, -1, -1, 1]) * 0.7       # Tz: each pair's twist
    return s


def load_points() -> tuple[np.ndarray, np.ndarray]:
    """(wrench (points, 6), phase per point): each path pressed to 7 N in 12 steps, its own
    load growing alike: shear in 8 directions at two levels, tilt and twist in both senses
    (the FEM's mirror images); a tilt adds the shear force it pushes with."""
    rows, phases = [], []
    steps = np.arange(1, 13) / 12

    def path(phase: str, load: np.ndarray) -> None:
        w = np.zeros((steps.size, 6))
        w[:, 2] = 7.0 * steps
        w += steps[:, None] * load
        rows.append(w)
        phases.extend([phase] * steps.size)

    path("press", np.zeros(6))
    for level in (0.5, 1.0):
        for a in np.arange(8) * np.pi / 4:
            path("shear", np.array([np.cos(a), np.sin(a), 0, 0, 0, 0]) * level)
    for sense in (1, -1):
        path("tilt", sense * np.array([0, -0.25, 0, 0.04, 0, 0]))
        path("tilt", sense * np.array([0.25, 0, 0, 0, 0.04, 0]))
        path("twist", sense * np.array([0, 0, 0, 0, 0, 0.016]))
    return np.concatenate(rows), np.array(phases)


def outputs_of(wrench: np.ndarray) -> np.ndarray:
    return wrench @ sensitivity().T - 0.002 * wrench[:, 2:3] ** 2


@cache
def held_out_gains(torque_degree: int, torque_noise_v: float) -> dict[str, np.ndarray]:
    """Per phase, per component: the held-out points' gain (NaN where the phase does not
    load that component), the force's tilt part fitted as the FEM calibration fits it."""
    wrench, phase = load_points()
    outputs = outputs_of(wrench)
    held = np.zeros(phase.size, bool)
    held[3::4] = True                                            # interior load steps
    fitted = wrench.copy()
    fitted[np.isin(phase, ("tilt", "twist")), :3] = np.nan       # forces from press/shear
    cal = ArrayCalibration.fit(FACES, outputs[~held], fitted[~held], 3, "synthetic",
                               WRENCH_FIT_NOISE_V, torque_degree, None, torque_noise_v,
                               wrench[~held, :3], WRENCH_TORQUE_PRESS_SCALED)
    estimate = cal.wrenches(outputs[held])
    gains = {}
    for name in PHASES:
        at = phase[held] == name
        truth, read = wrench[held][at], estimate[at]
        loaded = np.abs(truth).max(axis=0) > 0.25 * np.abs(wrench).max(axis=0)
        with np.errstate(invalid="ignore", divide="ignore"):
            g = np.sum(truth * read, axis=0) / np.sum(truth ** 2, axis=0)
        gains[name] = np.where(loaded, g, np.nan)
    return gains


@pytest.mark.parametrize("phase", PHASES)
def test_every_loaded_component_reads_its_load_with_gain_one_on_held_out_points(phase):
    gains = held_out_gains(WRENCH_TORQUE_DEGREE, TORQUE_FIT_NOISE_V)[phase]
    loaded = np.isfinite(gains)
    assert loaded.any()
    assert np.all(np.abs(gains[loaded] - 1.0) < 0.05), gains


def test_a_fit_regularised_by_output_noise_shrinks_the_tilt_and_the_twist():
    gains = held_out_gains(2, 0.010)
    assert gains["tilt"][3] < 0.85 and gains["tilt"][4] < 0.85, gains["tilt"]
    assert gains["twist"][5] < 0.85, gains["twist"]
