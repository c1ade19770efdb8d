"""Indentation profiles of the bench protocols (paper Sec. III) as plain data.

A ``LoadProfile`` is a piecewise-linear indentation d(t): rest, then for every speed and
cycle a ramp down to ``depth_m``, a hold, a ramp back up to ``preload_m`` and a rest.
The protocols of the paper are parameter sets (``PROTOCOLS``); the CLI option
``--profile`` names one, optionally overriding fields, or describes a ramp::

    compression                       3 mm at 1 mm/s, load and unload
    repeatability                     100 cycles, 1 s hold
    speeds                            0.1, 1 and 10 mm/s, 5 cycles each
    compression:cycles=3,hold=0.5     a protocol with overrides
    ramp:depth=0.003,speed=0.001/0.01,cycles=2,hold=1,rest=1,preload=0

A ``ShearProfile`` adds the probe's lateral path for a skin with modules on several faces
(``sim/array_world.py``): press, sweep out and back along 4 or 8 directions, release.
The array protocols (config/protocols.yaml, section ``array``) are ``ARRAY_PROTOCOLS``;
``array_profile_from_protocol`` turns one into a ``WrenchProfile`` (tilt or twist > 0), a
``ShearProfile`` (shear > 0) or a ``LoadProfile`` (shear 0).

A ``WrenchProfile`` is the wrench protocol's six stage axes (d, sx, sy [m], rx, ry, rz [rad]).
Each move goes out and back; its duration is the longest of its axes' travel at their speed
(lateral and indentation at ``speed_m_s``, rotations at ``angular_speed_rad_s``), so combined
moves end together. Order: rest, press to ``depth_m``, hold; shear +x, -x, +y, -y; tilt +x,
-x, +y, -y; twist +z, -z; shear +x with twist +z, tilt +x with twist +z, tilt +x with tilt
+y; release; rest. Rotations at 0.05 rad/s change the torque slowly enough for the wrench
driver's 3 Hz torque filter (second order: 75 ms lag, 3.8 mrad; its per-excursion gains and
those of the unfiltered torque agree within 0.015, docs/array.md).

Shear and wrench paths share their knots' form (``StagePath``): times and (n, axes) stage
positions, column 0 the indentation and columns 1-2 the lateral displacement.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt
import yaml

from tactile_sensor.sim.errors import SimError

MAX_DEPTH_M = 0.02
MAX_SHEAR_M = 0.05
MAX_ROTATION_RAD = 0.5


@dataclass(frozen=True)
class LoadProfile:
    """Indentation [m] versus time [s] for one bench protocol."""

    depth_m: float = 0.003
    speeds_m_s: tuple[float, ...] = (0.001,)
    cycles: int = 1
    hold_s: float = 0.0  # at depth, between loading and unloading
    rest_s: float = 1.0  # before the first cycle and after each one
    preload_m: float = 0.0  # indentation at rest (0 = probe just touching)
    _knots: tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]] = field(
        init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        speeds = tuple(float(s) for s in self.speeds_m_s)
        object.__setattr__(self, "speeds_m_s", speeds)
        _check("depth", self.depth_m, 0.0, MAX_DEPTH_M, "m")
        _check("preload", self.preload_m, 0.0, self.depth_m, "m (at most the depth)")
        _check("hold", self.hold_s, 0.0, 3600.0, "s")
        _check("rest", self.rest_s, 0.0, 3600.0, "s")
        if not speeds:
            raise SimError("A profile needs at least one speed; give speed=0.001 (m/s).")
        for s in speeds:
            _check("speed", s, 1e-6, 1.0, "m/s")
        _check_cycles(self.cycles)
        times, depths = [0.0, self.rest_s], [self.preload_m, self.preload_m]
        stroke = self.depth_m - self.preload_m
        for speed in speeds:
            ramp = stroke / speed
            for _ in range(self.cycles):
                t = times[-1]
                times += [t + ramp, t + ramp + self.hold_s, t + 2 * ramp + self.hold_s,
                          t + 2 * ramp + self.hold_s + self.rest_s]
                depths += [self.depth_m, self.depth_m, self.preload_m, self.preload_m]
        object.__setattr__(self, "_knots", (np.asarray(times), np.asarray(depths)))

    @property
    def duration_s(self) -> float:
        return float(self._knots[0][-1])

    def indentation(self, t_s: float | npt.ArrayLike) -> Any:
        """d(t) [m]; before 0 and after the end the probe rests at ``preload_m``."""
        times, depths = self._knots
        return np.interp(t_s, times, depths, left=self.preload_m, right=self.preload_m)

    def knots(self) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        """Corner times [s] and indentations [m] (copies)."""
        return self._knots[0].copy(), self._knots[1].copy()


_KEYS = {"depth": "depth_m", "speed": "speeds_m_s", "speeds": "speeds_m_s", "cycles": "cycles",
         "hold": "hold_s", "rest": "rest_s", "preload": "preload_m"}


#: Protocol keys that set the light (sim/ambient_light.py), not the stage's path.
LIGHT_KEYS = ("protocol.scenario",)


def _load_protocols(section: str = "bench", keys: Mapping[str, str] | None = None
                    ) -> dict[str, dict[str, Any]]:
    """A section's protocols of config/protocols.yaml (one definition for the mock CLI, the
    bench node, the launch files and the bringup), as profile keyword arguments."""
    from tactile_sensor.configurations import config_dir

    names = _KEYS if keys is None else keys
    table = yaml.safe_load((config_dir() / "protocols.yaml").read_text())[section]
    return {name: {names[key.removeprefix("protocol.")]:
                   tuple(value) if isinstance(value, list) else value
                   for key, value in (params or {}).items() if key not in LIGHT_KEYS}
            for name, params in table.items()}


PROTOCOLS: dict[str, dict[str, Any]] = _load_protocols()


def profile_from_protocol(name: str, **overrides: Any) -> LoadProfile:
    if name not in PROTOCOLS:
        raise SimError(f"Unknown profile '{name}'; choose one of {', '.join(PROTOCOLS)} "
                       "or 'ramp:depth=...,speed=...'.")
    return LoadProfile(**{**PROTOCOLS[name], **overrides})


def parse_profile(spec: str) -> LoadProfile:
    """Profile from a CLI spec: ``NAME``, ``NAME:key=value,...`` or ``ramp:key=value,...``.

    Keys (SI units): depth [m], speed [m/s, several joined by '/'], cycles, hold [s],
    rest [s], preload [m].
    """
    name, _, rest = spec.strip().partition(":")
    overrides = _parse_overrides(rest, spec) if rest else {}
    if name == "ramp":
        return LoadProfile(**overrides)
    return profile_from_protocol(name, **overrides)


def _parse_overrides(text: str, spec: str) -> Mapping[str, Any]:
    out: dict[str, Any] = {}
    for item in text.split(","):
        key, sep, value = item.partition("=")
        key = key.strip()
        if not sep or key not in _KEYS:
            raise SimError(f"Cannot read '{item}' in profile '{spec}'; use key=value with keys "
                           f"{', '.join(sorted(_KEYS))}.")
        try:
            if key == "cycles":
                out[_KEYS[key]] = int(value)
            elif key in ("speed", "speeds"):
                out[_KEYS[key]] = tuple(float(v) for v in value.split("/"))
            else:
                out[_KEYS[key]] = float(value)
        except ValueError:
            raise SimError(f"Profile value '{item}' in '{spec}' is not a number.") from None
    return out


def _check(name: str, value: object, lo: float, hi: float, unit: str,
           what: str = "Profile") -> None:
    """Refuse a parameter outside its range; ``what`` names it as the user set it (a
    ``--profile`` field or a ``protocol.`` parameter)."""
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(
            value) or not lo <= value <= hi:
        raise SimError(f"{what} {name} must be within [{lo:g}, {hi:g}] {unit}, got {value!r}.")


def _check_cycles(cycles: object, what: str = "Profile") -> None:
    if isinstance(cycles, bool) or not isinstance(cycles, int) or not 1 <= cycles <= 100_000:
        raise SimError(f"{what} cycles must be an integer 1..100000, got {cycles!r}.")


Knots = tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]


class StagePath:
    """A probe path on several stage axes, read from its knots: times [s] and (n, axes)
    positions, column 0 the indentation [m], columns 1-2 the lateral displacement [m];
    before 0 and after the end every axis rests at 0 (the probe just touching)."""

    _knots: Knots

    @property
    def duration_s(self) -> float:
        return float(self._knots[0][-1])

    def _column(self, t_s: float | npt.ArrayLike, c: int) -> Any:
        times, points = self._knots
        return np.interp(t_s, times, points[:, c], left=0.0, right=0.0)

    def indentation(self, t_s: float | npt.ArrayLike) -> Any:
        """d(t) [m]; before 0 and after the end the probe rests just touching."""
        return self._column(t_s, 0)

    def lateral(self, t_s: float | npt.ArrayLike) -> tuple[Any, Any]:
        """(sx(t), sy(t)) [m], the probe's lateral displacement along +x and +y."""
        return self._column(t_s, 1), self._column(t_s, 2)

    def knots(self) -> Knots:
        """Corner times [s] and (n, axes) stage positions (copies)."""
        return self._knots[0].copy(), self._knots[1].copy()


class _KnotTrail:
    """Knots laid move by move from rest: each at the previous one's time plus the move's
    duration."""

    def __init__(self, rest_s: float, start: Any) -> None:
        self.times: list[float] = [0.0, rest_s]
        self.points: list[Any] = [start, start]

    def add(self, dt: float, point: Any) -> None:
        self.times.append(self.times[-1] + dt)
        self.points.append(point)

    def hold(self, dt: float) -> None:
        self.add(dt, self.points[-1])

    def arrays(self) -> Knots:
        return np.asarray(self.times), np.asarray(self.points)


# -- shear (module arrays) ---------------------------------------------------------------------

#: Unit vectors of the sweep directions, in order: +x, -x, +y, -y, then the diagonals.
SHEAR_DIRECTIONS: tuple[tuple[float, float], ...] = (
    (1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (0.0, -1.0),
    (math.sqrt(0.5), math.sqrt(0.5)), (-math.sqrt(0.5), -math.sqrt(0.5)),
    (-math.sqrt(0.5), math.sqrt(0.5)), (math.sqrt(0.5), -math.sqrt(0.5)))


@dataclass(frozen=True)
class ShearProfile(StagePath):
    """Probe path [m] versus time [s] of the shear protocol.

    Per cycle (after an initial rest): press from contact to ``depth_m`` at ``speed_m_s``,
    hold ``hold_s``, then for each of ``directions`` (4: +x, -x, +y, -y; 8: then +x+y,
    -x-y, -x+y, +x-y) move the probe sideways out to ``amplitude_m`` (the distance from
    the centre, diagonals included) and back to the centre at the same speed, holding
    ``hold_s`` after each return; then release at the speed and rest ``rest_s``.
    """

    depth_m: float = 0.003
    speed_m_s: float = 0.001
    amplitude_m: float = 0.006
    directions: int = 8
    cycles: int = 1
    hold_s: float = 0.0
    rest_s: float = 1.0
    _knots: Knots = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        _check("depth", self.depth_m, 1e-6, MAX_DEPTH_M, "m (a shear needs contact)")
        _check("speed", self.speed_m_s, 1e-6, 1.0, "m/s")
        _check("shear amplitude", self.amplitude_m, 0.0, MAX_SHEAR_M, "m")
        _check("hold", self.hold_s, 0.0, 3600.0, "s")
        _check("rest", self.rest_s, 0.0, 3600.0, "s")
        if isinstance(self.directions, bool) or not isinstance(self.directions, int) or \
                self.directions not in (4, 8):
            raise SimError(f"Shear directions must be 4 (+x, -x, +y, -y) or 8 (with the "
                           f"diagonals), got {self.directions!r}.")
        _check_cycles(self.cycles)
        press = self.depth_m / self.speed_m_s
        sweep = self.amplitude_m / self.speed_m_s
        rest = (0.0, 0.0, 0.0)
        trail = _KnotTrail(self.rest_s, rest)
        bottom = (self.depth_m, 0.0, 0.0)
        for _ in range(self.cycles):
            trail.add(press, bottom)
            trail.add(self.hold_s, bottom)
            for ux, uy in SHEAR_DIRECTIONS[:self.directions]:
                trail.add(sweep, (self.depth_m, self.amplitude_m * ux, self.amplitude_m * uy))
                trail.add(sweep, bottom)
                trail.add(self.hold_s, bottom)
            trail.add(press, rest)
            trail.add(self.rest_s, rest)
        object.__setattr__(self, "_knots", trail.arrays())

    @property
    def shear_ratio(self) -> float:
        """The largest lateral displacement per unit indentation along the path."""
        return self.amplitude_m / self.depth_m


# -- wrench (six-axis stage) -------------------------------------------------------------------


@dataclass(frozen=True)
class WrenchProfile(StagePath):
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
    _knots: Knots = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        for name, value, lo, hi, unit in (
                ("depth", self.depth_m, 1e-6, MAX_DEPTH_M, "m (a wrench needs contact)"),
                ("speed", self.speed_m_s, 1e-6, 1.0, "m/s"),
                ("shear", self.shear_m, 0.0, MAX_SHEAR_M, "m"),
                ("tilt", self.tilt_rad, 0.0, MAX_ROTATION_RAD, "rad"),
                ("twist", self.twist_rad, 0.0, MAX_ROTATION_RAD, "rad"),
                ("angular_speed", self.angular_speed_rad_s, 1e-4, 1.0, "rad/s"),
                ("hold", self.hold_s, 0.0, 3600.0, "s"),
                ("rest", self.rest_s, 0.0, 3600.0, "s")):
            _check(name, value, lo, hi, unit, "Protocol")
        _check_cycles(self.cycles, "Protocol")
        rest = np.zeros(6)
        bottom = np.array([self.depth_m, 0, 0, 0, 0, 0], float)
        trail = _KnotTrail(self.rest_s, rest)
        rates = np.array([self.speed_m_s] * 3 + [self.angular_speed_rad_s] * 3)

        def go(point: np.ndarray) -> None:
            trail.add(float(np.max(np.abs(point - trail.points[-1]) / rates)), point)

        s, tl, tw = self.shear_m, self.tilt_rad, self.twist_rad
        moves = [(1, s), (1, -s), (2, s), (2, -s), (3, tl), (3, -tl), (4, tl), (4, -tl),
                 (5, tw), (5, -tw), ((1, 5), (s, tw)), ((3, 5), (tl, tw)),
                 ((3, 4), (tl, tl))]
        for _ in range(self.cycles):
            go(bottom)
            trail.hold(self.hold_s)
            for axes, amounts in moves:
                target = bottom.copy()
                target[list(np.atleast_1d(axes))] = amounts
                if np.array_equal(target, bottom):
                    continue          # a zero amplitude leaves that move out
                go(target)
                go(bottom)
                trail.hold(self.hold_s)
            go(rest)
            trail.add(self.rest_s, rest)
        object.__setattr__(self, "_knots", trail.arrays())

    @property
    def shear_ratio(self) -> float:
        """The largest lateral displacement per unit indentation along the path."""
        return self.shear_m / self.depth_m

    def rotation(self, t_s: float | npt.ArrayLike) -> tuple[Any, Any, Any]:
        """(tilt about x, tilt about y, twist about z)(t) [rad]."""
        return self._column(t_s, 3), self._column(t_s, 4), self._column(t_s, 5)


_ARRAY_KEYS = {**_KEYS, "shear": "shear_m", "shear_directions": "shear_directions",
               "tilt": "tilt_rad", "twist": "twist_rad", "angular_speed": "angular_speed_rad_s"}

#: The array bench's protocols: the ``array`` section and the ``wrench`` configuration's.
ARRAY_PROTOCOLS: dict[str, dict[str, Any]] = {**_load_protocols("array", _ARRAY_KEYS),
                                              **_load_protocols("wrench", _ARRAY_KEYS)}


def array_profile(depth_m: float = 0.003, speeds_m_s: tuple[float, ...] = (0.001,),
                  cycles: int = 1, hold_s: float = 0.0, rest_s: float = 1.0,
                  preload_m: float = 0.0, shear_m: float = 0.0, shear_directions: int = 8,
                  tilt_rad: float = 0.0, twist_rad: float = 0.0,
                  angular_speed_rad_s: float = 0.05) -> LoadProfile | ShearProfile | WrenchProfile:
    """The array bench's profile from the mock rig's protocol parameters: the wrench
    protocol when ``tilt_rad`` or ``twist_rad`` > 0, a shear sweep when ``shear_m`` > 0,
    the plain load profile otherwise."""
    _check("shear", shear_m, 0.0, MAX_SHEAR_M, "m")
    _check("tilt", tilt_rad, 0.0, MAX_ROTATION_RAD, "rad")
    _check("twist", twist_rad, 0.0, MAX_ROTATION_RAD, "rad")
    if tilt_rad or twist_rad:
        if len(tuple(speeds_m_s)) != 1 or preload_m:
            raise SimError("A wrench protocol runs at one speed from contact; give "
                           "protocol.speeds one value and protocol.preload 0.")
        return WrenchProfile(depth_m=depth_m, speed_m_s=next(iter(speeds_m_s)),
                             shear_m=shear_m, tilt_rad=tilt_rad, twist_rad=twist_rad,
                             angular_speed_rad_s=angular_speed_rad_s, cycles=cycles,
                             hold_s=hold_s, rest_s=rest_s)
    if shear_m == 0:
        return LoadProfile(depth_m=depth_m, speeds_m_s=speeds_m_s, cycles=cycles,
                           hold_s=hold_s, rest_s=rest_s, preload_m=preload_m)
    speeds = tuple(speeds_m_s)
    if len(speeds) != 1:
        raise SimError(f"A shear protocol runs at one speed; give protocol.speeds one value, "
                       f"not {len(speeds)}.")
    if preload_m:
        raise SimError("A shear protocol starts from contact; set protocol.preload to 0.")
    return ShearProfile(depth_m=depth_m, speed_m_s=speeds[0], amplitude_m=shear_m,
                        directions=shear_directions, cycles=cycles, hold_s=hold_s,
                        rest_s=rest_s)


def array_profile_from_protocol(name: str, **overrides: Any
                                ) -> LoadProfile | ShearProfile | WrenchProfile:
    """A protocol of the ``array`` or ``wrench`` section of config/protocols.yaml, with
    overrides."""
    if name not in ARRAY_PROTOCOLS:
        raise SimError(f"Unknown array protocol '{name}'; choose one of "
                       f"{', '.join(ARRAY_PROTOCOLS)}.")
    return array_profile(**{**ARRAY_PROTOCOLS[name], **overrides})
