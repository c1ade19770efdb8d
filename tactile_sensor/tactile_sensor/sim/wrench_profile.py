"""The wrench protocol's probe path: press, shear, tilt, twist and combined moves.

Six stage axes (d, sx, sy [m], rx, ry, rz [rad]) as piecewise-linear knots. Each move goes
out and back; its duration is the longest of its axes' travel at their speed (lateral and
indentation at ``speed_m_s``, rotations at ``angular_speed_rad_s``), so combined moves end
together. Order: rest, press to ``depth_m``, hold; shear +x, -x, +y, -y; tilt +x, -x, +y,
-y; twist +z, -z; shear +x with twist +z, tilt +x with twist +z, tilt +x with tilt +y;
release; rest. Rotations at 0.05 rad/s change the torque slowly enough for a 1 kHz driver
with a 10 Hz torque filter (its lag is 16 ms, 0.8 mrad).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from tactile_sensor.sim.errors import SimError

MAX_ROTATION_RAD = 0.5


def _check(name: str, value: object, lo: float, hi: float, unit: str) -> None:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(
            value) or not lo <= value <= hi:
        raise SimError(f"Protocol {name} must be within [{lo:g}, {hi:g}] {unit}, "
                       f"got {value!r}.")


@dataclass(frozen=True)
class WrenchProfile:
    """Probe path of the wrench protocol (see the module docstring)."""

    depth_m: float = 0.003
    speed_m_s: float = 0.001
    shear_m: float = 0.003
    tilt_rad: float = 0.1
    twist_rad: float = 0.2
    angular_speed_rad_s: float = 0.05
    cycles: int = 1
    hold_s: float = 0.0
    rest_s: float = 1.0
    _knots: tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]] = field(
        init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        _check("depth", self.depth_m, 1e-6, 0.02, "m (a wrench needs contact)")
        _check("speed", self.speed_m_s, 1e-6, 1.0, "m/s")
        _check("shear", self.shear_m, 0.0, 0.05, "m")
        _check("tilt", self.tilt_rad, 0.0, MAX_ROTATION_RAD, "rad")
        _check("twist", self.twist_rad, 0.0, MAX_ROTATION_RAD, "rad")
        _check("angular_speed", self.angular_speed_rad_s, 1e-4, 1.0, "rad/s")
        _check("hold", self.hold_s, 0.0, 3600.0, "s")
        _check("rest", self.rest_s, 0.0, 3600.0, "s")
        if isinstance(self.cycles, bool) or not isinstance(self.cycles, int) or not (
                1 <= self.cycles <= 100_000):
            raise SimError(f"Protocol cycles must be an integer 1..100000, got "
                           f"{self.cycles!r}.")
        rest = np.zeros(6)
        bottom = np.array([self.depth_m, 0, 0, 0, 0, 0], float)
        times, points = [0.0, self.rest_s], [rest, rest]
        rates = np.array([self.speed_m_s] * 3 + [self.angular_speed_rad_s] * 3)

        def go(point: np.ndarray) -> None:
            times.append(times[-1] + float(np.max(np.abs(point - points[-1]) / rates)))
            points.append(point)

        def hold() -> None:
            times.append(times[-1] + self.hold_s)
            points.append(points[-1])

        s, tl, tw = self.shear_m, self.tilt_rad, self.twist_rad
        moves = [(1, s), (1, -s), (2, s), (2, -s), (3, tl), (3, -tl), (4, tl), (4, -tl),
                 (5, tw), (5, -tw), ((1, 5), (s, tw)), ((3, 5), (tl, tw)),
                 ((3, 4), (tl, tl))]
        for _ in range(self.cycles):
            go(bottom)
            hold()
            for axes, amounts in moves:
                target = bottom.copy()
                target[list(np.atleast_1d(axes))] = amounts
                if np.array_equal(target, bottom):
                    continue          # a zero amplitude leaves that move out
                go(target)
                go(bottom)
                hold()
            go(rest)
            times.append(times[-1] + self.rest_s)
            points.append(rest)
        object.__setattr__(self, "_knots", (np.asarray(times), np.asarray(points)))

    @property
    def duration_s(self) -> float:
        return float(self._knots[0][-1])

    @property
    def shear_ratio(self) -> float:
        """The largest lateral displacement per unit indentation along the path."""
        return self.shear_m / self.depth_m

    def _column(self, t_s: float | npt.ArrayLike, c: int) -> Any:
        times, points = self._knots
        return np.interp(t_s, times, points[:, c], left=0.0, right=0.0)

    def indentation(self, t_s: float | npt.ArrayLike) -> Any:
        """d(t) [m]."""
        return self._column(t_s, 0)

    def lateral(self, t_s: float | npt.ArrayLike) -> tuple[Any, Any]:
        """(sx(t), sy(t)) [m]."""
        return self._column(t_s, 1), self._column(t_s, 2)

    def rotation(self, t_s: float | npt.ArrayLike) -> tuple[Any, Any, Any]:
        """(tilt about x, tilt about y, twist about z)(t) [rad]."""
        return self._column(t_s, 3), self._column(t_s, 4), self._column(t_s, 5)

    def knots(self) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        """Corner times [s] and (n, 6) stage positions (copies)."""
        return self._knots[0].copy(), self._knots[1].copy()
