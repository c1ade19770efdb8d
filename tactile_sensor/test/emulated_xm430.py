"""What the tests that run the XM430 emulator in their own process share (conftest.py puts
this folder on ``sys.path``)."""

from __future__ import annotations

import sys
from collections.abc import Iterator

import numpy as np
import pytest

from tactile_sensor.sim.skin_response import TabulatedSkin


def linear_skin() -> TabulatedSkin:
    """A 5 mm skin whose force rises linearly to 7 N at 3 mm, its output falling from 2 V."""
    d = np.linspace(0.0, 0.003, 31)
    force = 7.0 * d / 0.003
    return TabulatedSkin(d, force, 2.0 - 0.07 * force, thickness_m=0.005)


@pytest.fixture(autouse=True)
def share_the_gil_fairly() -> Iterator[None]:
    """The stock SDK spins on a zero-timeout read while it waits; with the emulator thread
    in the same process, hand the GIL over often so the emulator answers promptly."""
    before = sys.getswitchinterval()
    sys.setswitchinterval(2e-4)
    yield
    sys.setswitchinterval(before)
