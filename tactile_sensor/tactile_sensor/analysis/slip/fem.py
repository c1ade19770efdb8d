"""The study's skin from the FEM, as the gripper world and the array bench have it: the
normal curve (grip -> indentation, the last slope beyond the table as ``TabulatedSkin``
continues it), the tangential stiffness of ``sim/skin_shear.py``, the array grid of a
module layout (its sensitivity and shear coupling) and the silicone's rate effect."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from tactile_sensor.analysis.slip.resolution import local_sensitivity
from tactile_sensor.analysis.slip.signature import shear_coupling
from tactile_sensor.analysis.slip.study import Skin
from tactile_sensor.physics.array_grid import ArrayGrid, load_or_compute_grid
from tactile_sensor.physics.params import PhysicsParams
from tactile_sensor.physics.viscoelastic import RateDependentForce
from tactile_sensor.sim.skin_response import TabulatedSkin, default_skin
from tactile_sensor.sim.skin_shear import load_or_compute_stiffness

#: The layout that observes tangential force: a module on each side face (docs/array.md).
ARRAY_MODULES = "front,back,left,right"


def indentation_for(skin: TabulatedSkin, force_n: float) -> float:
    """The indentation [m] at which ``skin`` carries ``force_n``: its table inverted, the
    last slope beyond it."""
    d, f, _ = skin.table()
    if force_n <= f[-1]:
        return float(np.interp(force_n, f, d))
    slope = (f[-1] - f[-2]) / (d[-1] - d[-2])
    return float(d[-1] + (force_n - f[-1]) / slope)


def layout_grid(modules: str, cache_dir: Path | None = None) -> ArrayGrid:
    """The FEM array grid of ``modules`` on the default skin (cached; solved on a miss)."""
    return load_or_compute_grid(PhysicsParams(modules=modules), cache_dir)


def fem_skin(modules: str = ARRAY_MODULES, cache_dir: Path | None = None) -> Skin:
    """The default skin with ``modules`` on it, for ``study.evaluate``."""
    params = PhysicsParams()
    curve = default_skin()
    grid = layout_grid(modules, cache_dir)
    return Skin(load_or_compute_stiffness(params, cache_dir),
                lambda f: indentation_for(curve, f),
                lambda d: local_sensitivity(grid, d),
                lambda d: shear_coupling(grid, d),
                lambda: RateDependentForce.from_params(params))
