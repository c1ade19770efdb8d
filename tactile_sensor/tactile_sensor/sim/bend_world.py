"""A soft bending finger with modules clipped on its skin: the bend world of ``sim/``.

The finger is driven by its actuator (a chamber pressure [Pa] or a tendon [N], as
physics/bend.py models it); a contact may press on its fingertip. Everything the world
gives comes from the FEM through physics/bend.py: the actuator's input -> the joint angle,
and (angle, tip force) -> each module's output. Like the bench it is precomputed on a
regular time grid (1 kHz) over the protocol and interpolated, so the mock ADC (in the
ADC's thread) and the ground truth (in the gauge's) read the same pure function of time.

What drives it:

- a ``BendPath`` (config/protocols.yaml, section ``bend``): bends of the finger from
  straight to ``angle_rad`` and back, one raised-cosine cycle per period, ``cycles`` at each
  frequency, and with ``tip_force_n`` > 0 the same cycles again while a contact at the
  fingertip rises to that force and falls back (one raised cosine over the block). The
  actuator's input that holds each angle under each tip force comes from the actuator's
  own inverse (the FEM prescribes the angle and solves for the tendon's tension) or its
  map tabulated, so the protocol is written in angles a user reads;
- or an ``ActuationProfile`` a user gives (``bend.actuation_profile``): the actuator's input
  itself, 'time:value' points, linear in between; a non-finite or negative value is refused.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
import numpy.typing as npt

from tactile_sensor.sim.errors import SimError

TimeLike = float | npt.ArrayLike
#: The finger's joint, as the ground truth and the driver name it.
JOINT_NAME = "finger_joint"
#: Frequencies a bend protocol may ask for [Hz]: a soft pneumatic finger bends at a few Hz
#: at most.
MAX_FREQUENCY_HZ = 5.0
MAX_TIP_FORCE_N = 10.0
#: How far past the FEM's angle range a protocol may reach and be held at its end [rad]
#: (a protocol's 1.5708 for 90 deg).
ANGLE_TOLERANCE_RAD = 1e-3


class BendResponseLike(Protocol):
    """What the world reads of physics/bend.py's ``BendResponse``."""

    @property
    def angle_range_rad(self) -> tuple[float, float]: ...

    def output_v(self, angle_rad: npt.ArrayLike, tip_force_n: npt.ArrayLike) -> Any:
        """Every module's output [V], shape (..., modules)."""


class ActuatorLike(Protocol):
    """The actuator's map, input (pressure [Pa] or tendon force [N]) -> joint angle [rad]."""

    def angle_rad(self, actuation: npt.ArrayLike, tip_force_n: npt.ArrayLike) -> Any: ...


@dataclass(frozen=True)
class ActuationProfile:
    """The actuator's input against time: ``times_s`` increasing from >= 0, ``values`` >= 0
    in ``unit`` (Pa or N), linear in between, the first before and the last after."""

    times_s: tuple[float, ...]
    values: tuple[float, ...]
    name: str = "bend.actuation_profile"
    unit: str = "Pa"

    def __post_init__(self) -> None:
        if not self.times_s or len(self.times_s) != len(self.values):
            raise SimError(f"{self.name} needs one or more 'time:value' points, as many times "
                           "as values.")
        if not all(math.isfinite(v) for v in (*self.times_s, *self.values)):
            raise SimError(f"{self.name} holds a non-finite value; give every point as finite "
                           f"'seconds:{self.unit}', e.g. '1.0:20000'.")
        if any(v < 0 for v in self.values):
            raise SimError(f"{self.name} holds a negative value ({min(self.values):g} "
                           f"{self.unit}); the actuator only pushes or pulls, give values "
                           ">= 0.")
        if self.times_s[0] < 0 or any(b <= a for a, b in zip(self.times_s, self.times_s[1:],
                                                             strict=False)):
            raise SimError(f"{self.name} times must be >= 0 s and strictly increasing; sort "
                           "the points and drop repeated times.")

    @property
    def duration_s(self) -> float:
        return float(self.times_s[-1])

    def at(self, t_s: TimeLike) -> Any:
        return np.interp(np.asarray(t_s, float), self.times_s, self.values)


def parse_actuation_profile(items: Sequence[str], unit: str = "Pa",
                            name: str = "bend.actuation_profile") -> ActuationProfile | None:
    """``["0:0", "2:30000", "4:0"]`` (seconds : actuator input) -> the profile; [] -> None."""
    if not items:
        return None
    points = []
    for item in items:
        time_text, sep, value_text = str(item).partition(":")
        try:
            if not sep:
                raise ValueError
            points.append((float(time_text), float(value_text)))
        except ValueError:
            raise SimError(f"{name} entry {item!r} is not 'seconds:{unit}', e.g. "
                           "'1.0:20000'.") from None
    return ActuationProfile(tuple(p[0] for p in points), tuple(p[1] for p in points), name,
                            unit)


@dataclass(frozen=True)
class BendPath:
    """A bend protocol: rest, then per frequency ``cycles`` bends 0 -> ``angle_rad`` -> 0
    (raised cosine), and with ``tip_force_n`` > 0 as many again under a fingertip contact
    rising to it and falling back over them; a rest after each block."""

    angle_rad: float = math.pi / 2
    frequencies_hz: tuple[float, ...] = (0.5,)
    cycles: int = 1
    tip_force_n: float = 0.0
    rest_s: float = 1.0

    def __post_init__(self) -> None:
        freqs = tuple(float(f) for f in self.frequencies_hz)
        object.__setattr__(self, "frequencies_hz", freqs)
        if not (math.isfinite(self.angle_rad) and 0.0 < self.angle_rad <= math.pi):
            raise SimError(f"protocol.angle = {self.angle_rad!r} must be a bend in (0, pi] "
                           "rad, e.g. 1.5708 for 90 deg.")
        if not freqs or not all(math.isfinite(f) and 0 < f <= MAX_FREQUENCY_HZ
                                for f in freqs):
            raise SimError(f"protocol.frequencies must be one or more bend rates in (0, "
                           f"{MAX_FREQUENCY_HZ:g}] Hz, got {list(freqs)}.")
        if isinstance(self.cycles, bool) or not isinstance(self.cycles, int) or \
                not 1 <= self.cycles <= 10_000:
            raise SimError(f"protocol.cycles = {self.cycles!r} must be a whole number of "
                           "bends from 1 to 10000.")
        if not (math.isfinite(self.tip_force_n) and 0 <= self.tip_force_n <= MAX_TIP_FORCE_N):
            raise SimError(f"protocol.tip_force = {self.tip_force_n!r} must be a contact "
                           f"force from 0 to {MAX_TIP_FORCE_N:g} N.")
        if not (math.isfinite(self.rest_s) and 0 <= self.rest_s <= 3600):
            raise SimError(f"protocol.rest = {self.rest_s!r} must be from 0 to 3600 s.")

    def blocks(self) -> list[tuple[float, float, float, bool]]:
        """(start [s], end [s], frequency [Hz], with contact) of every block of bends."""
        out, t = [], self.rest_s
        for f in self.frequencies_hz:
            for contact in (False, True) if self.tip_force_n > 0 else (False,):
                end = t + self.cycles / f
                out.append((t, end, f, contact))
                t = end + self.rest_s
        return out

    @property
    def duration_s(self) -> float:
        return self.blocks()[-1][1] + self.rest_s

    def angle(self, t_s: TimeLike) -> Any:
        """Target joint angle [rad]."""
        t = np.asarray(t_s, float)
        out = np.zeros_like(t)
        for start, end, f, _ in self.blocks():
            on = (t >= start) & (t < end)
            out = np.where(on, 0.5 * self.angle_rad * (1 - np.cos(2 * np.pi * f * (t - start))),
                           out)
        return out

    def tip_force(self, t_s: TimeLike) -> Any:
        """Contact force on the fingertip [N]."""
        t = np.asarray(t_s, float)
        out = np.zeros_like(t)
        for start, end, _, contact in self.blocks():
            if contact:
                on = (t >= start) & (t < end)
                phase = (t - start) / (end - start)
                out = np.where(on, 0.5 * self.tip_force_n * (1 - np.cos(2 * np.pi * phase)),
                               out)
        return out


class BendWorld:
    """Ground truth of one run of the finger: joint angle [rad], its rate [rad/s], the tip
    force [N] and the actuator's input, and the modules' noise-free voltages, on a regular
    ``grid_hz`` grid from the protocol's start; ``loop`` repeats it."""

    def __init__(self, path: BendPath, response: BendResponseLike, actuator: ActuatorLike,
                 rest_voltage_v: float | Sequence[float], faces: Sequence[str],
                 actuation: ActuationProfile | None = None, grid_hz: float = 1000.0,
                 loop: bool = False) -> None:
        if not 1.0 <= grid_hz <= 100_000.0:
            raise SimError(f"grid_hz must be in [1, 100000] Hz, got {grid_hz!r}.")
        self.faces = tuple(faces)
        self.path = path
        self.loop = loop
        self.duration_s = (path.duration_s if actuation is None
                           else actuation.duration_s + path.rest_s)
        n = max(2, int(np.ceil(self.duration_s * grid_hz)) + 1)
        self._t = np.linspace(0.0, self.duration_s, n)
        tip = np.asarray(path.tip_force(self._t), float)
        lo, hi = (float(v) for v in response.angle_range_rad)
        if actuation is None:
            target = np.asarray(path.angle(self._t), float)
            if target.max() > hi + ANGLE_TOLERANCE_RAD:
                peak = math.degrees(path.angle_rad)
                raise SimError(f"The protocol bends the finger to {peak:.1f} deg, beyond "
                               f"the FEM's {math.degrees(hi):.1f} deg; lower protocol.angle.")
            # the input that holds each angle: the finger bends as the protocol says
            angle = np.minimum(target, hi)  # 1.5708 for a pi / 2 range
            u = actuation_for(actuator, angle, tip, hi)
        else:
            u = np.asarray(actuation.at(self._t), float)
            angle = np.asarray(actuator.angle_rad(u, tip), float)
        if not np.all(np.isfinite(angle)) or not np.all(np.isfinite(u)):
            raise SimError(f"The actuation bends the finger beyond the FEM's "
                           f"{math.degrees(hi):.0f} deg (or under a tip force beyond its "
                           "range); give a smaller actuation or protocol.tip_force.")
        if angle.max() > hi + ANGLE_TOLERANCE_RAD or angle.min() < lo - ANGLE_TOLERANCE_RAD:
            raise SimError(f"The actuation bends the finger to {math.degrees(angle.max()):.1f}"
                           f" deg, outside the FEM's {math.degrees(lo):.0f}-"
                           f"{math.degrees(hi):.0f} deg; give a smaller actuation.")
        self._u, self._angle, self._tip = u, angle, tip
        self._rate = np.gradient(angle, self._t)
        outputs = np.asarray(response.output_v(angle, tip), float).reshape(n, -1)
        if outputs.shape[1] != len(self.faces):
            raise SimError(f"The bend response reads {outputs.shape[1]} modules, the world "
                           f"names {len(self.faces)} ({', '.join(self.faces)}).")
        self._v = np.asarray(rest_voltage_v, float) - outputs

    def _time(self, t: TimeLike) -> Any:
        t = np.asarray(t, dtype=float)
        if self.loop and self.duration_s > 0:
            t = np.mod(t, self.duration_s)
        return t

    def _at(self, t: TimeLike, values: np.ndarray) -> Any:
        times = np.clip(self._time(t), 0.0, self.duration_s)
        pos = times * ((self._t.size - 1) / self.duration_s)
        i0 = np.minimum(pos.astype(np.intp), self._t.size - 2)
        w = pos - i0
        if values.ndim == 2:
            w = w[..., None]
        return values[i0] * (1.0 - w) + values[i0 + 1] * w

    def angle_rad(self, t: TimeLike) -> Any:
        """True joint angle [rad] (0 straight, positive bending toward the palm)."""
        return self._at(t, self._angle)

    def tip_force_n(self, t: TimeLike) -> Any:
        return self._at(t, self._tip)

    def actuation(self, t: TimeLike) -> Any:
        """The actuator's input (pressure [Pa] or tendon force [N])."""
        return self._at(t, self._u)

    def module_voltages(self, t: TimeLike) -> np.ndarray:
        """Noise-free voltages [V], shape (..., modules) in ``faces`` order."""
        return np.asarray(self._at(t, self._v), float).reshape(*np.shape(t), len(self.faces))

    def stage_and_gauge(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """What the mock publishes as ground truth: (angle [rad]) per time, shape (n, 1), and
        the fingertip's contact force (0, 0, F) [N], shape (n, 3)."""
        t = np.asarray(t, float)
        tip = np.asarray(self.tip_force_n(t), float)
        zero = np.zeros_like(tip)
        return (np.asarray(self.angle_rad(t), float)[:, None],
                np.stack([zero, zero, tip], axis=-1))


#: Actuation samples tabulated to invert the actuator's map, and the contact forces it is
#: tabulated at (linear in between).
INVERSE_POINTS = 400
FORCE_LEVELS = 11


def actuation_for(actuator: Any, angle_rad: np.ndarray, tip_force_n: np.ndarray,
                  max_angle_rad: float) -> np.ndarray:
    """The actuator's input that gives each angle under each tip force: the actuator's own
    inverse when it has one (``actuation_for``), else its map tabulated up to the input
    that reaches ``max_angle_rad`` and inverted (monotone in the input)."""
    own = getattr(actuator, "actuation_for", None)
    if callable(own):
        return np.asarray(own(angle_rad, tip_force_n), float)
    top = float(getattr(actuator, "max_actuation", 0.0)) or _reach(actuator, max_angle_rad)
    u = np.linspace(0.0, top, INVERSE_POINTS)
    f_lo, f_hi = float(tip_force_n.min()), float(tip_force_n.max())
    levels = np.linspace(f_lo, f_hi, FORCE_LEVELS if f_hi > f_lo else 1)
    inputs = []
    for f in levels.tolist():  # the input for every angle at each contact level ...
        a = np.asarray(actuator.angle_rad(u, np.full_like(u, f)), float)
        if np.any(np.diff(a) <= 0):
            raise SimError("The actuator's angle does not rise with its input; it cannot be "
                           "driven to a protocol's angles.")
        inputs.append(np.interp(angle_rad, a, u))
    if levels.size == 1:
        return inputs[0]
    table = np.stack(inputs)  # ... then linear between the levels
    pos = (tip_force_n - f_lo) / (f_hi - f_lo) * (levels.size - 1)
    k = np.minimum(pos.astype(np.intp), levels.size - 2)
    w = pos - k
    cols = np.arange(angle_rad.size)
    return table[k, cols] * (1 - w) + table[k + 1, cols] * w


def _reach(actuator: Any, angle_rad: float) -> float:
    """An input that bends the finger to at least ``angle_rad`` without contact."""
    u = 1.0
    for _ in range(80):
        if float(np.asarray(actuator.angle_rad(u, 0.0))) >= angle_rad:
            return u * 1.2
        u *= 2.0
    raise SimError(f"The actuator cannot bend the finger to {math.degrees(angle_rad):.0f} "
                   "deg at any input; check the physics parameters of the finger.")
