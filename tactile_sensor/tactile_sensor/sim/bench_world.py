"""The bench rig as a pure function of time: stage indentation, gauge force, sensor voltage.

``BenchRun`` is what every bench layout shares (the time grid, the gauge with its rate
effect, the modules' voltages, the stage and gauge the rig publishes); ``BenchWorld`` is
the single-module layout, ``sim/array_world.py`` and ``sim/wrench_world.py`` the others.

Everything is precomputed on a regular grid (1 kHz by default) over the protocol and
linearly interpolated, so any thread may ask for any time (or array of times) without
shared state: the bench node reads stage and gauge from it, and the mock ADC in the same
process streams ``photoreflector_voltage`` from the same object. The gauge force
includes the viscoelastic rate effect (faster pressing → more force at the same
indentation); the voltage follows the skin's bulge, which is quasi-static, so the peak
output does not depend on speed (paper Sec. III-D).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from tactile_sensor.sim.errors import SimError
from tactile_sensor.sim.profiles import LoadProfile
from tactile_sensor.sim.skin_block import SkinBlock, ViscoelasticModel
from tactile_sensor.sim.skin_response import SkinResponse

TimeLike = float | npt.ArrayLike


def play(indentation_m: npt.NDArray[np.float64], width_m: float) -> npt.NDArray[np.float64]:
    """The play (backlash) operator: the output trails a rising input by ``width_m`` and
    follows a falling one at once, so its delay is ``width / speed`` on every loading edge
    (the paper's lags shrink ten-fold per ten-fold speed, as a fixed play predicts)."""
    if width_m <= 0:
        return indentation_m
    out = np.empty_like(indentation_m)
    y = float(indentation_m[0]) if indentation_m.size else 0.0
    for k, d in enumerate(indentation_m.tolist()):
        y = max(d - width_m, min(d, y))
        out[k] = y
    return out


class BenchRun:
    """What every bench layout shares: the protocol precomputed on a regular ``grid_hz``
    time grid, so any thread may ask for any time (or array of times) without shared state;
    the gauge with the viscoelastic rate effect (``_f``) and without (``_f_el``), the
    modules' voltages (``_v``) seen through the output play. Time ``t`` [s] counts from the
    protocol's start; ``loop`` repeats the protocol."""

    _f: npt.NDArray[np.float64]
    _f_el: npt.NDArray[np.float64]
    _v: npt.NDArray[np.float64]

    def __init__(self, profile: Any, block: SkinBlock, grid_hz: float, loop: bool,
                 output_play_m: float) -> None:
        if not 1.0 <= grid_hz <= 100_000.0:
            raise SimError(f"grid_hz must be in [1, 100000] Hz, got {grid_hz!r}.")
        if not 0.0 <= output_play_m <= 0.001:
            raise SimError(f"output_play_m must be in [0, 0.001] m, got {output_play_m!r}.")
        self.profile = profile
        self.block = block
        #: The modules in layout order: ADC channel i carries ``faces[i]``.
        self.faces = block.faces
        self.loop = loop
        self.duration_s = float(profile.duration_s)
        n = max(2, int(np.ceil(self.duration_s * grid_hz)) + 1)
        self._t = np.linspace(0.0, self.duration_s, n)

    def _time(self, t: TimeLike) -> Any:
        t = np.asarray(t, dtype=float)
        if self.loop and self.duration_s > 0:
            t = np.mod(t, self.duration_s)
        return t

    def _at(self, t: TimeLike, values: npt.NDArray[np.float64]) -> Any:
        raise NotImplementedError

    def stage_and_gauge(self, t: npt.NDArray[np.float64]
                        ) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        """Stage positions and gauge at every time of ``t``, shapes (n, 3) each (d, sx, sy
        [m]; Fx, Fy, Fz [N]) or (n, 6) on the six-axis bench (rotations [rad], torques
        [N m] after): what the mock rig publishes, whatever the layout."""
        raise NotImplementedError

    def force_n(self, t: TimeLike) -> Any:
        """Force-gauge reading [N], including the viscoelastic rate effect."""
        return self._at(t, self._f)

    def elastic_force_n(self, t: TimeLike) -> Any:
        """Quasi-static (hyperelastic) force [N] at the same stage position."""
        return self._at(t, self._f_el)

    def photoreflector_voltage(self, t: TimeLike) -> Any:
        """Noise-free photoreflector voltage [V] (one per module on an array, ADC channel i
        carrying ``faces[i]``); the mock ADC adds noise and quantisation."""
        return self._at(t, self._v)

    def module_voltages(self, t: TimeLike) -> npt.NDArray[np.float64]:
        """Noise-free voltages [V], shape (..., modules) in ``faces`` order: what the mock
        ADC samples, whatever the layout."""
        return np.asarray(self.photoreflector_voltage(t), dtype=float).reshape(
            *np.shape(t), len(self.faces))


class BenchWorld(BenchRun):
    """The single-module bench: an indentation stage and a normal-force gauge; ``faces``
    names the module (the physics default's when None)."""

    def __init__(self, profile: LoadProfile, skin: SkinResponse,
                 viscoelastic: ViscoelasticModel | None = None, grid_hz: float = 1000.0,
                 loop: bool = False, output_play_m: float = 0.0,
                 faces: tuple[str, ...] | None = None, stiffness_ratio: float = 1.0) -> None:
        block = SkinBlock(skin, faces, viscoelastic, stiffness_ratio)
        super().__init__(profile, block, grid_hz, loop, output_play_m)
        self._d = np.asarray(profile.indentation(self._t), dtype=float)
        self._f_el = np.asarray(block.load(self._d), dtype=float)
        self._v = block.module_voltages(play(self._d, output_play_m))[:, 0]
        self._f = block.rated(self._t, self._f_el)

    def _at(self, t: TimeLike, values: npt.NDArray[np.float64]) -> Any:
        out = np.interp(self._time(t), self._t, values)
        return float(out) if np.ndim(out) == 0 else out

    def indentation_m(self, t: TimeLike) -> Any:
        """Stage indentation [m] (0 = probe just touching)."""
        return self._at(t, self._d)

    def stage_and_gauge(self, t: npt.NDArray[np.float64]
                        ) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        """A single-module bench has no lateral axis and no lateral force (0)."""
        d, zero = np.asarray(self.indentation_m(t), float), np.zeros(len(t))
        return (np.stack([d, zero, zero], axis=-1),
                np.stack([zero, zero, np.asarray(self.force_n(t), float)], axis=-1))
