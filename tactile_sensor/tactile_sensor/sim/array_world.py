"""A skin with modules on several faces, and the three-axis bench that presses and shears it.

``ArraySkin`` answers a probe state (indentation d >= 0, lateral displacement sx, sy [m])
with every module's output and voltage and the force on the skin (Fx, Fy, Fz), by
interpolating the FEM's array grid (``physics.array_grid``). The grid is a tensor grid in
(d, r, theta), r = |s| / d the lateral displacement per unit indentation: its load paths
run from rest to (d_max, r d_max cos theta, r d_max sin theta), so every path passes the
same indentation levels. Interpolation is trilinear in (d, r, theta), periodic in theta:

- d = 0 is rest (zero outputs and forces) whatever the lateral position, and r = 0 (pure
  indentation) is the same in every direction, so the map is continuous everywhere,
  including at the centre and at first contact.
- r is clamped at the grid's largest ratio (``array_shear_ratio``): beyond it the skin
  slides on the probe (the friction limit, docs/array.md) and keeps the state it had there.
- Beyond d_max the forces continue with the last indentation interval's slope and the
  outputs hold their d_max values, as the single-module ``TabulatedSkin`` does (the module
  reads what it read at the grid's deepest level, the force keeps rising).

Voltages are ``V_rest - output``, V_rest the photoreflector's voltage at the rest gap (the
single-module curve's voltage at 0).

``ArrayBenchWorld`` is the bench (``BenchRun``) with a three-axis stage and gauge: precomputed
on a 1 kHz grid over the protocol, pure functions of time, safe from any thread.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np
import numpy.typing as npt

from tactile_sensor.sim.bench_world import BenchRun, TimeLike, play
from tactile_sensor.sim.errors import SimError
from tactile_sensor.sim.skin_block import SkinBlock, ViscoelasticModel

if TYPE_CHECKING:
    from tactile_sensor.physics.array_grid import ArrayGrid

Progress = Callable[[float, str], None]


class ArraySkin:
    """The grid as a continuous map (d, sx, sy) -> module outputs and (Fx, Fy, Fz).

    Forces follow the grid's convention (the probe's force on the skin, +z pressing in,
    +x toward the right face, +y toward the front face). Vectorised over states.
    """

    #: What acts on it: indentation and lateral displacement (x, y).
    axes = 3

    def __init__(self, grid: ArrayGrid, rest_voltage_v: float, source: str = "grid"
                 ) -> None:
        if not (isinstance(rest_voltage_v, int | float) and math.isfinite(rest_voltage_v)):
            raise SimError(f"rest_voltage_v must be a finite voltage, got {rest_voltage_v!r}.")
        self.faces: tuple[str, ...] = tuple(grid.outputs_v)
        self.rest_voltage_v = float(rest_voltage_v)
        self.source = source
        step = np.asarray(grid.step, int)
        level = np.asarray(grid.level, int)
        direction = np.asarray(grid.direction, int)
        steps, levels, dirs = int(step.max()), int(level.max()), int(direction.max()) + 1
        if steps < 1 or levels < 1 or dirs < 1 or not self.faces:
            raise SimError("An array grid needs indentation steps, shear levels, directions "
                           "and at least one module; recompute it with 'tactile-sensor model "
                           "array-calibration'.")
        d = np.asarray(grid.indentation_m, float)
        s = np.hypot(np.asarray(grid.shear_x_m, float), np.asarray(grid.shear_y_m, float))
        values = np.column_stack([*(np.asarray(grid.outputs_v[f], float) for f in self.faces),
                                  grid.force_x_n, grid.force_y_n, grid.force_n])
        # table[k, j, i, c]: step k, level j (0 = pure indentation), direction i, channel c
        table = np.full((steps + 1, levels + 1, dirs, values.shape[1]), np.nan)
        d_levels = np.full(steps + 1, np.nan)
        ratios = np.zeros(levels + 1)
        for row in range(d.size):
            k, j, i = step[row], level[row], direction[row]
            d_levels[k] = d[row]
            if k == 0:
                table[0] = values[row]
            elif j == 0:
                table[k, 0] = values[row]
            else:
                table[k, j, i] = values[row]
                if k == steps and d[row] > 0:
                    ratios[j] = s[row] / d[row]
        if np.isnan(table).any() or np.isnan(d_levels).any() or np.any(np.diff(d_levels) <= 0) \
                or np.any(np.diff(ratios) <= 0):
            raise SimError("The array grid is incomplete (a step, level or direction is "
                           "missing); recompute it with 'tactile-sensor model "
                           "array-calibration'.")
        self._table = table
        self._d = d_levels
        self._r = ratios
        self._dirs = dirs
        self._n_modules = len(self.faces)

    @classmethod
    def from_params(cls, params: Any, cache_dir: Path | None = None,
                    progress: Progress | None = None, workers: int = 1) -> ArraySkin:
        """The array skin of ``params`` (a ``PhysicsParams`` naming several ``modules``):
        the cached grid, computed first when missing (``progress(fraction, message)``)."""
        try:
            from tactile_sensor.physics.array_grid import load_or_compute_grid
            from tactile_sensor.physics.errors import PhysicsError
            from tactile_sensor.physics.optics import Photoreflector
        except ImportError as exc:
            raise SimError(f"The physics model is not available ({exc}); install the "
                           "complete tactile_sensor package.") from None
        try:
            grid = load_or_compute_grid(params, cache_dir, progress, workers)
        except PhysicsError as exc:
            raise SimError(f"The array grid failed ({exc}).") from None
        rest = float(Photoreflector(params.pigment_white, params.supply_voltage)
                     .voltage(params.gap))
        return cls(grid, rest, source=f"fem-array:{grid.digest}")

    def press_skin(self) -> Any:
        """The grid's pure press as a one-axis skin (``TabulatedSkin``): normal force and the
        first module's voltage against indentation. A gripper whose fingertip modules come
        from this grid takes its fingers' forces from here, so that they are the forces the
        grid's calibration reads (the grid's mesh reads about 5 % more than the curve's)."""
        from tactile_sensor.sim.skin_response import TabulatedSkin

        press = self._table[:, 0, 0]
        return TabulatedSkin(self._d, press[:, -1], self.rest_voltage_v - press[:, 0],
                             source=f"{self.source}:press")

    # -- domain ------------------------------------------------------------------------------

    @property
    def max_indentation_m(self) -> float:
        return float(self._d[-1])

    @property
    def max_shear_ratio(self) -> float:
        """Lateral displacement per unit indentation at which the skin slides on the probe."""
        return float(self._r[-1])

    @property
    def directions(self) -> int:
        return self._dirs

    # -- evaluation --------------------------------------------------------------------------

    def state(self, indentation_m: npt.ArrayLike, shear_x_m: npt.ArrayLike = 0.0,
              shear_y_m: npt.ArrayLike = 0.0) -> np.ndarray:
        """Outputs [V] of every module (``faces`` order) then Fx, Fy, Fz [N]: shape
        (..., modules + 3) for states broadcast from the three arguments."""
        d, sx, sy = np.broadcast_arrays(np.asarray(indentation_m, float),
                                        np.asarray(shear_x_m, float),
                                        np.asarray(shear_y_m, float))
        shape = d.shape
        d, sx, sy = d.ravel(), sx.ravel(), sy.ravel()
        if not (np.all(np.isfinite(d)) and np.all(np.isfinite(sx)) and np.all(np.isfinite(sy))):
            raise SimError("Probe states must be finite numbers (indentation and lateral "
                           "displacement in m).")
        d = np.maximum(d, 0.0)
        levels = self._d
        deep = np.minimum(d, levels[-1])
        # indentation: interval k0..k0+1 and weight (extrapolated linearly beyond d_max)
        k0 = np.clip(np.searchsorted(levels, deep, side="right") - 1, 0, levels.size - 2)
        wd = (d - levels[k0]) / (levels[k0 + 1] - levels[k0])
        # shear ratio: clamped at the slip limit; no contact (d = 0) gives r = 0
        s = np.hypot(sx, sy)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            r = np.where(d > 0, s / np.where(d > 0, d, 1.0), 0.0)
        r = np.minimum(r, self._r[-1])
        j0 = np.clip(np.searchsorted(self._r, r, side="right") - 1, 0, self._r.size - 2)
        wr = (r - self._r[j0]) / (self._r[j0 + 1] - self._r[j0])
        # direction: periodic
        u = np.mod(np.arctan2(sy, sx) / (2.0 * np.pi) * self._dirs, self._dirs)
        i0 = np.floor(u).astype(int) % self._dirs
        i1 = (i0 + 1) % self._dirs
        wt = (u - np.floor(u))[:, None]

        t = self._table

        def at(k: np.ndarray) -> np.ndarray:
            a = t[k, j0, i0] * (1 - wt) + t[k, j0, i1] * wt
            b = t[k, j0 + 1, i0] * (1 - wt) + t[k, j0 + 1, i1] * wt
            return a * (1 - wr[:, None]) + b * wr[:, None]

        lo, hi = at(k0), at(k0 + 1)
        out = lo + (hi - lo) * wd[:, None]
        beyond = d > levels[-1]
        if np.any(beyond):  # outputs hold their d_max values; forces keep the last slope
            m = self._n_modules
            out[beyond, :m] = hi[beyond, :m]
        return out.reshape(*shape, -1)

    def outputs_v(self, indentation_m: npt.ArrayLike, shear_x_m: npt.ArrayLike = 0.0,
                  shear_y_m: npt.ArrayLike = 0.0) -> np.ndarray:
        """Module outputs [V], shape (..., modules): V_rest - V, positive as the face bulges
        toward its photoreflector."""
        return self.state(indentation_m, shear_x_m, shear_y_m)[..., :self._n_modules]

    def voltages_v(self, indentation_m: npt.ArrayLike, shear_x_m: npt.ArrayLike = 0.0,
                   shear_y_m: npt.ArrayLike = 0.0) -> np.ndarray:
        """Photoreflector voltages [V], shape (..., modules)."""
        return self.rest_voltage_v - self.outputs_v(indentation_m, shear_x_m, shear_y_m)

    def force_n(self, indentation_m: npt.ArrayLike, shear_x_m: npt.ArrayLike = 0.0,
                shear_y_m: npt.ArrayLike = 0.0) -> np.ndarray:
        """(Fx, Fy, Fz) [N], shape (..., 3)."""
        return self.state(indentation_m, shear_x_m, shear_y_m)[..., self._n_modules:]


class StageProfile(Protocol):
    """A protocol's probe path; ``lateral`` is optional (none: pure indentation)."""

    @property
    def duration_s(self) -> float: ...

    def indentation(self, t_s: float | npt.ArrayLike) -> Any: ...


def stage_path(profile: StageProfile, t_s: npt.ArrayLike) -> np.ndarray:
    """(n, 3) stage positions [m]: indentation, lateral x, lateral y."""
    t = np.asarray(t_s, float)
    d = np.asarray(profile.indentation(t), float)
    lateral = getattr(profile, "lateral", None)
    if lateral is None:
        return np.stack([d, np.zeros_like(d), np.zeros_like(d)], axis=-1)
    sx, sy = lateral(t)
    return np.stack([d, np.asarray(sx, float), np.asarray(sy, float)], axis=-1)


class ArrayBenchWorld(BenchRun):
    """The array bench: a three-axis stage (d, sx, sy) and gauge (Fx, Fy, Fz) from the
    profile and the skin; the gauge carries the viscoelastic rate effect on each component
    (the Prony series is linear in the elastic force history, so it applies per axis). The
    modules see the indentation through the output play, as in ``BenchWorld``.

    A layout with more stage axes (``WrenchBenchWorld``) changes ``_stage_path``; the
    skin block's load follows the skin's axes, its first three columns always the force.
    """

    #: The protocol as a refusal names it.
    _protocol = "shear"
    _stage_path = staticmethod(stage_path)

    def __init__(self, profile: StageProfile, skin: ArraySkin,
                 viscoelastic: ViscoelasticModel | None = None, grid_hz: float = 1000.0,
                 loop: bool = False, output_play_m: float = 0.0) -> None:
        block = SkinBlock(skin, viscoelastic=viscoelastic)
        super().__init__(profile, block, grid_hz, loop, output_play_m)
        self._refuse_path(profile, skin)
        self.skin = skin
        self._stage = self._stage_path(profile, self._t)
        cols = self._stage.T
        self._w_el = np.asarray(block.load(*cols))
        self._v = block.module_voltages(play(cols[0], output_play_m), *cols[1:])
        self._w = block.rated(self._t, self._w_el)
        self._f_el, self._f = self._w_el[:, :3], self._w[:, :3]

    def _refuse_path(self, profile: StageProfile, skin: ArraySkin) -> None:
        ratio = getattr(profile, "shear_ratio", 0.0)
        if ratio > skin.max_shear_ratio * (1 + 1e-9):
            raise SimError(
                f"The {self._protocol} protocol moves the probe {ratio:g} x its depth sideways,"
                f" beyond the grid's slip limit of {skin.max_shear_ratio:g} x (the skin would "
                "slide on the probe); lower protocol.shear or raise array_shear_ratio.")

    def _at(self, t: TimeLike, values: np.ndarray) -> Any:
        times = self._time(t)
        # one index and weight for every channel (the ADC asks ~1000 times a second)
        flat = np.clip(times.ravel(), 0.0, self.duration_s)
        pos = flat * ((self._t.size - 1) / self.duration_s) if self.duration_s > 0 else \
            np.zeros_like(flat)
        i0 = np.minimum(pos.astype(np.intp), self._t.size - 2)
        w = (pos - i0)[:, None]
        out = values[i0] * (1.0 - w) + values[i0 + 1] * w
        return out.reshape(*times.shape, values.shape[1])

    def stage_m(self, t: TimeLike) -> Any:
        """Stage positions [m] (indentation, lateral x, lateral y), shape (..., 3); the
        six-axis stage adds its rotations [rad], shape (..., 6)."""
        return self._at(t, self._stage)

    def indentation_m(self, t: TimeLike) -> Any:
        """Stage indentation [m] (as ``BenchWorld``: float for a scalar time)."""
        out = self._at(t, self._stage[:, :1])[..., 0]
        return float(out) if np.ndim(out) == 0 else out

    def stage_and_gauge(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return np.asarray(self.stage_m(t), float), np.asarray(self.force_n(t), float)
