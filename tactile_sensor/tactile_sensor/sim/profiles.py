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
        if isinstance(self.cycles, bool) or not isinstance(self.cycles, int) or not (
                1 <= self.cycles <= 100_000):
            raise SimError(f"Profile cycles must be an integer 1..100000, got {self.cycles!r}.")
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


def _load_protocols() -> dict[str, dict[str, Any]]:
    """The bench protocols of config/protocols.yaml (one definition for the mock CLI, the
    bench node, the launch files and the bringup), as LoadProfile keyword arguments."""
    from tactile_sensor.configurations import config_dir

    table = yaml.safe_load((config_dir() / "protocols.yaml").read_text())["bench"]
    return {name: {_KEYS[key.removeprefix("protocol.")]:
                   tuple(value) if isinstance(value, list) else value
                   for key, value in (params or {}).items()}
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


def _check(name: str, value: object, lo: float, hi: float, unit: str) -> None:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(
            value) or not lo <= value <= hi:
        raise SimError(f"Profile {name} must be within [{lo:g}, {hi:g}] {unit}, got {value!r}.")
