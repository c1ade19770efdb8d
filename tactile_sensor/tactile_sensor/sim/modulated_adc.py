"""The mock ADC as a modulated device (protocol version 3): its timing and its source.

A modulated device samples each channel with the emitter on and off in every period
(docs/serial-frame.md); the mock takes both from a source with a ``pair``
(``sim.ambient_light.LitSource``), so the world, the light and the detector's response
act as for every other mock ADC.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from tactile_sensor.hardware.adc_frame import MODULATED_VERSION
from tactile_sensor.physics.detector import DetectorState
from tactile_sensor.sim.ambient_light import LightScene, LitSource
from tactile_sensor.sim.errors import SimError

#: A modulated mock samples each half period this long before its end (the reference
#: firmware's margin for the frame; its conversions take no time here).
MODULATED_MARGIN_US = 100


def modulation_timing(protocol: int, rate_hz: float, source: Any) -> tuple[int, float] | None:
    """(settle_us, period_s) of a modulated mock (protocol 3), else None."""
    if protocol != MODULATED_VERSION:
        return None
    if not callable(getattr(source, "pair", None)):
        raise SimError("A modulated mock ADC (protocol 3) needs a source that gives emitter "
                       "on/off pairs; wrap the world in sim.ambient_light.LitSource.")
    period_us = 1e6 / rate_hz
    settle_us = int(period_us / 2) - MODULATED_MARGIN_US
    if settle_us < MODULATED_MARGIN_US:
        raise SimError(f"A modulated mock ADC at {rate_hz:g} Hz leaves no time to settle "
                       "after each emitter switch; use at most "
                       f"{1e6 / (4 * MODULATED_MARGIN_US):g} Hz.")
    return settle_us, period_us * 1e-6


def dark_room_pairs(world: Any) -> LitSource:
    """The world's voltages as a modulated device samples them in the dark room."""
    rest = np.asarray(world.module_voltages(np.zeros(1)), dtype=float).reshape(-1)
    return LitSource(world.module_voltages, LightScene(), DetectorState(), rest)
