"""A smooth stand-in for the FEM's bend table (joint and fingertip module outputs over
angle x tip force), shared by the bend calibration and chain tests."""

from __future__ import annotations

import math

import numpy as np

ANGLES = np.linspace(0.0, math.pi / 2, 19)
FORCES = np.linspace(0.0, 2.0, 9)


def table(joint_force_gain: float = 0.02, tip_bend_gain: float = 0.05,
          alike: bool = False) -> np.ndarray:
    """A smooth table: the joint module saturating with the bend and a little force, the tip
    reading the force and a little bend (or, ``alike``, both reading one mix)."""
    a, f = np.meshgrid(ANGLES, FORCES, indexing="ij")
    joint = 0.4 * np.sin(0.9 * a) + joint_force_gain * f
    tip = 0.05 * f + 0.01 * f ** 2 + tip_bend_gain * a
    if alike:
        tip = 0.5 * joint
    return np.stack([joint, tip], axis=-1)
