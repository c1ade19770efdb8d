"""Light outside the dark room, as the module's detector sees it, for every mock world.

A scene is the ambient photocurrent as a ratio of the emitter's at rest (docs/ambient.md):
a steady level (``dc_ratio``), a lamp on the mains (``flicker_ratio``: its mean, flickering
fully at ``flicker_hz``, 100 or 120 Hz, with the harmonics of a full-wave rectified supply)
and switching steps (``steps``: from ``time`` [s] on, the level changes by ``ratio``; a
passing shadow or a slow daylight change is a series of them). The detector follows with
its response time (``physics.detector.response_tau_s``), evaluated in closed form so any
time may be asked in any order, as the mock ADC does.

:class:`LitSource` wraps a world's ``module_voltages`` for the mock ADC, so the light, the
temperature and the emitter act once, on whatever world the ADC samples. For a modulated
device it also gives the emitter-on and emitter-off samples of a period (``pair``): the
same world and light, with the emitter's part at the share the detector shows after its
switch (``physics.detector.emitter_levels``, which the driver shares).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from tactile_sensor.physics.detector import (
    DetectorState,
    emitter_levels,
    module_output_v,
    response_tau_s,
)
from tactile_sensor.sim.errors import SimError

#: Harmonics of the rectified lamp kept: the k-th has 2/(4k^2 - 1) of its mean, so the 10th
#: 0.5 % before the detector's response attenuates it further.
FLICKER_HARMONICS = 10


def parse_steps(items: Sequence[str]) -> tuple[tuple[float, float], ...]:
    """``["5:0.3", "15:-0.3"]`` -> ((5.0, 0.3), (15.0, -0.3)), in time order."""
    steps = []
    for item in items:
        time_text, sep, ratio_text = str(item).partition(":")
        try:
            if not sep:
                raise ValueError
            step = (float(time_text), float(ratio_text))
        except ValueError:
            raise SimError(f"ambient.steps entry {item!r} is not 'time:ratio' (seconds and a "
                           "ratio of the emitter's light at rest), e.g. '5:0.3'.") from None
        steps.append(step)
    return tuple(sorted(steps))


@dataclass(frozen=True)
class LightScene:
    """Ambient light on the detector; ``sample_rate_hz`` is the ADC's (flicker must stay
    under its Nyquist rate to be a flicker it can see and not an alias)."""

    dc_ratio: float = 0.0
    flicker_ratio: float = 0.0
    flicker_hz: float = 100.0
    steps: tuple[tuple[float, float], ...] = ()
    sample_rate_hz: float = 1000.0
    tau_s: float = field(default_factory=response_tau_s)

    def __post_init__(self) -> None:
        numbers = {"ambient.dc_ratio": self.dc_ratio, "ambient.flicker_ratio":
                   self.flicker_ratio, "ambient.flicker_hz": self.flicker_hz}
        numbers.update({f"ambient.steps ({t:g} s)": r for t, r in self.steps})
        numbers.update({f"ambient.steps time {t!r}": t for t, _ in self.steps})
        for name, value in numbers.items():
            if not math.isfinite(value):
                raise SimError(f"{name} = {value!r} must be a finite number.")
        for name in ("ambient.dc_ratio", "ambient.flicker_ratio"):
            if numbers[name] < 0:
                raise SimError(f"{name} = {numbers[name]!r} is negative; light adds "
                               "photocurrent, so give a ratio >= 0.")
        nyquist = self.sample_rate_hz / 2.0
        if self.flicker_ratio > 0 and not 0 < self.flicker_hz < nyquist:
            raise SimError(f"ambient.flicker_hz = {self.flicker_hz:g} Hz is not between 0 "
                           f"and the ADC's Nyquist rate {nyquist:g} Hz; lower it or raise "
                           "adc_rate.")
        level = self.dc_ratio
        for t, ratio in self.steps:
            level += ratio
            if level < -1e-12:
                raise SimError(f"ambient.steps take the light to a negative ratio "
                               f"({level:g}) at {t:g} s; a step may remove only light "
                               "that is there.")

    @property
    def is_dark(self) -> bool:
        return self.dc_ratio == 0 and self.flicker_ratio == 0 and not self.steps

    def ratio(self, t: npt.ArrayLike, origin_s: float = 0.0) -> np.ndarray:
        """The ambient photocurrent the detector passes at times ``t`` [s], as a ratio of
        the emitter's at rest; step times count from ``origin_s`` (inf: none yet)."""
        t = np.asarray(t, dtype=float)
        out = np.full(t.shape, self.dc_ratio)
        since = t - origin_s
        for start, ratio in self.steps:
            after = np.maximum(since - start, 0.0)
            out += np.where(since >= start, ratio * -np.expm1(-after / self.tau_s), 0.0)
        if self.flicker_ratio > 0:
            out += self.flicker_ratio * self._flicker(t)
        return out

    def _flicker(self, t: np.ndarray) -> np.ndarray:
        """A full-wave rectified lamp of mean 1 flickering at ``flicker_hz``: (pi/2)|sin|
        = 1 - 2 sum cos(k w t)/(4k^2 - 1), each harmonic through the detector's response."""
        out = np.ones_like(t)
        for k in range(1, FLICKER_HARMONICS + 1):
            w = 2.0 * math.pi * k * self.flicker_hz
            gain, lag = 1.0 / math.hypot(1.0, w * self.tau_s), math.atan(w * self.tau_s)
            out -= 2.0 * gain * np.cos(w * t - lag) / (4 * k * k - 1)
        return out


class LitSource:
    """A world's voltage source as the module outputs it under ``scene`` and ``state``:
    what the mock ADC samples. ``rest_v`` is each module's dark-room output at rest. The
    scene's steps count from ``origin_s`` [s of the source's clock]; by default from the
    source's protocol start (``start_device_s``: none before it) when it has one, else
    from 0."""

    def __init__(self, source: Callable[[Any], Any], scene: LightScene, state: DetectorState,
                 rest_v: npt.ArrayLike, supply_v: float = 5.0,
                 origin_s: float | None = None) -> None:
        self.source = source
        self.origin_s = origin_s
        self.scene = scene
        self.state = state
        self.rest_drop_v = supply_v - np.asarray(rest_v, dtype=float)
        self.supply_v = supply_v

    def __getattr__(self, name: str) -> Any:  # revision, start_device_s of the wrapped source
        return getattr(self.source, name)

    def __call__(self, t: Any) -> Any:
        return self._lit(self.source(t), t)

    def pair(self, t: Any, settle_s: float, period_s: float) -> tuple[Any, Any]:
        """(on, off): the module's output ``settle_s`` after the emitter is switched on at
        ``t - settle_s``, and ``settle_s`` after it is switched off half a period later;
        the emitter is on for the first half of each ``period_s``."""
        on_share, off_share = emitter_levels(settle_s, period_s, self.scene.tau_s)
        t_off = np.asarray(t, dtype=float) + period_s / 2.0
        return (self._lit(self.source(t), t, on_share),
                self._lit(self.source(t_off), t_off, off_share))

    def _lit(self, v: Any, t: Any, emitter_share: float = 1.0) -> Any:
        """The world's dark-room output ``v`` at ``t`` with the emitter's part at
        ``emitter_share`` of its own, under the scene's light and the detector's state."""
        if emitter_share != 1.0:
            v = self.supply_v - (self.supply_v - np.asarray(v, dtype=float)) * emitter_share
        if self.scene.is_dark and self.state.is_calibration:
            return v
        origin = self.origin_s
        if origin is None:
            start = getattr(self.source, "start_device_s", 0.0)
            origin = math.inf if start is None else start
        ratio = self.scene.ratio(t, origin)
        ratio = np.asarray(ratio)[..., None] if np.ndim(v) > np.ndim(ratio) else ratio
        return module_output_v(v, ratio, self.rest_drop_v, self.state, self.supply_v)


#: The ``ambient`` protocol's scenarios (``protocol.scenario``), in protocol seconds; the
#: protocol (config/protocols.yaml) rests 1 s, then presses 3 mm at 1 mm/s and releases
#: (3 s each way, 1 s rest) four times: loading 1-4 s, 8-11 s, 15-18 s, 22-25 s.
SCENARIOS = ("dark", "office", "sunlight", "shadow")
#: Office light: a lamp flickering at 100 Hz (0.2 of the emitter's light), another
#: switched on while the first press loads and off while the second unloads.
OFFICE = {"flicker_ratio": 0.2, "flicker_hz": 100.0, "steps": ((2.5, 0.3), (12.5, -0.3))}
#: Sunlight using this share of the detector's headroom at rest, there from the start.
SUNLIGHT_HEADROOM = 0.6
#: A hand's shadow takes this share of the office's steady light during the third press.
SHADOW = {"dc_ratio": 0.3, "steps": ((16.0, -0.2), (16.8, 0.2))}


def scenario_scene(name: str, headroom: float, sample_rate_hz: float) -> LightScene:
    """The named scenario's scene, its steps in protocol seconds; ``headroom`` is the
    ambient ratio that saturates the detector at rest."""
    if name not in SCENARIOS:
        raise SimError(f"Unknown ambient scenario '{name}'; choose one of "
                       f"{', '.join(SCENARIOS)}.")
    values: dict[str, Any] = {"dark": {}, "office": OFFICE, "shadow": SHADOW,
                              "sunlight": {"dc_ratio": SUNLIGHT_HEADROOM * headroom}}[name]
    return LightScene(values.get("dc_ratio", 0.0), values.get("flicker_ratio", 0.0),
                      values.get("flicker_hz", 100.0), values.get("steps", ()), sample_rate_hz)
