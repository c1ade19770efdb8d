"""The six-column FEM fit's bookkeeping: which wrench points are held out, and a wrench set
of another layout refused (the fit itself: test_cli_array.py, on a tiny mesh)."""

from __future__ import annotations

import numpy as np
import pytest

from tactile_sensor.physics.array_grid import ArrayGrid
from tactile_sensor.physics.array_report import fit_wrench, wrench_held_out
from tactile_sensor.physics.errors import PhysicsError
from tactile_sensor.physics.wrench import WrenchSet


def wrench_set(steps: int = 4, modules=("front", "back")) -> WrenchSet:
    """Press (rest + steps), then two paths with two mirror images each (steps points)."""
    path = np.concatenate([np.zeros(steps + 1, int), np.full(2 * steps, 1),
                           np.full(2 * steps, 2)])
    n = path.size
    return WrenchSet(np.zeros((n, 6)), {m: np.zeros(n) for m in modules}, path, "d", 0.0, 3)


def test_held_out_wrench_points_are_interior_even_steps_of_every_image():
    held = wrench_held_out(wrench_set(steps=4))
    press = held[:5]                       # steps 0..4: 2 is the only interior even one
    assert press.tolist() == [False, False, True, False, False]
    image = [False, True, False, False]    # steps 1..4 of one image
    assert held[5:].tolist() == image * 4


def test_a_wrench_set_of_other_modules_is_refused_naming_both():
    n = 3
    grid = ArrayGrid(*(np.zeros(n) for _ in range(6)), {"left": np.zeros(n)},
                     np.zeros(n, int), np.zeros(n, int), np.arange(n), "g", 0.0, 1)
    with pytest.raises(PhysicsError, match=r"wrench set's modules \(front, back\) are not "
                                           r"the grid's \(left\)"):
        fit_wrench(grid, wrench_set(), 1)
