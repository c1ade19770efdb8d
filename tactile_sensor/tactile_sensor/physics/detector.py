"""The QTR-1A's detector circuit outside the dark room: light, heat and an ageing emitter.

The module's QRE1113 phototransistor pulls its output down from VIN through a pull-up, so
the output is ``VIN - R_pull-up * (I_skin + I_ambient + I_dark)``, held between the rails.
:mod:`physics.optics` gives the skin's part as a voltage drop at the calibration's
temperature with a new emitter (the paper's dark room); this module adds what the paper
shut out. Every photocurrent is a voltage drop across the pull-up, and ambient light is
stated as a ratio of the emitter's drop at rest (no contact), so a scenario reads the same
whatever the skin.

Sources (docs/ambient.md):

- pull-up 47 kOhm to VIN: Pololu QTR-1A product page and schematic;
- dark current <= 100 nA at VCE = 20 V, 25 C; rise and fall 20 us at RL = 1 kOhm,
  IC = 100 uA; VCE(sat) <= 0.3 V: onsemi QRE1113 datasheet (Rev. 7, 2020);
- emitter -0.6 %/K: an assumption inside the -0.3 to -0.7 %/K that IR LED datasheets give
  for their radiant power (e.g. Vishay VSMY1850ITX01, 850 nm: -0.35 %/K); the QRE1113
  datasheet states none for its 940 nm emitter;
- assumptions, stated as such: a phototransistor's response time grows in proportion to its
  load resistance (the switching-time-against-load curves of phototransistor datasheets);
  its gain rises +0.5 %/K (a silicon transistor's current gain); its dark current doubles
  every 10 K (silicon leakage).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

# A modulated module's detector under its switched emitter: the closed form the driver
# scales the on - off difference with, so the mock and the driver share it.
from tactile_sensor.sensing.modulation import emitter_levels as emitter_levels

from .errors import PhysicsError

PULL_UP_OHM = 47e3  # QTR-1A output pull-up to VIN (Pololu)
DATASHEET_RISE_S = 20e-6  # QRE1113 tr = tf at the test load below
DATASHEET_LOAD_OHM = 1e3
DARK_CURRENT_A = 100e-9  # QRE1113 ICEO, maximum at 25 C
EMITTER_TEMPCO_PER_K = -0.006  # assumption inside IR LEDs' -0.3 to -0.7 %/K
DETECTOR_TEMPCO_PER_K = 0.005  # assumption: silicon transistor gain
DARK_DOUBLING_K = 10.0  # assumption: silicon leakage doubles every 10 K
#: 10 % to 90 % of a first-order step is 2.2 time constants.
RISE_TIME_CONSTANTS = math.log(9.0)


def response_tau_s(pull_up_ohm: float = PULL_UP_OHM) -> float:
    """First-order time constant [s] of the detector on its pull-up: the datasheet's rise
    time scaled to the load (0.43 ms on the QTR-1A's 47 kOhm)."""
    return DATASHEET_RISE_S * pull_up_ohm / DATASHEET_LOAD_OHM / RISE_TIME_CONSTANTS


@dataclass(frozen=True)
class DetectorState:
    """What acts on the detector besides the skin: temperature above the calibration's
    [K] and the emitter's output as a fraction of a new one's."""

    delta_k: float = 0.0
    emitter_ratio: float = 1.0

    def __post_init__(self) -> None:
        if not math.isfinite(self.delta_k) or not -60.0 <= self.delta_k <= 60.0:
            raise PhysicsError(f"temperature.delta_k = {self.delta_k!r} K must be a finite "
                               "number in [-60, 60] (the QRE1113 works from -40 to 85 C).")
        if not math.isfinite(self.emitter_ratio) or not 0.0 <= self.emitter_ratio <= 1.5:
            raise PhysicsError(f"emitter.output_ratio = {self.emitter_ratio!r} must be a "
                               "finite number in [0, 1.5] (1.0 = a new emitter).")

    @property
    def detector_gain(self) -> float:
        """The detector's gain against the calibration's."""
        return 1.0 + DETECTOR_TEMPCO_PER_K * self.delta_k

    @property
    def skin_gain(self) -> float:
        """The skin's photocurrent against the calibration's: emitter times detector."""
        return (self.emitter_ratio * (1.0 + EMITTER_TEMPCO_PER_K * self.delta_k)
                * self.detector_gain)

    @property
    def dark_drop_v(self) -> float:
        """Extra dark-current drop [V] across the pull-up against the calibration's."""
        return DARK_CURRENT_A * PULL_UP_OHM * (2.0 ** (self.delta_k / DARK_DOUBLING_K) - 1.0)

    @property
    def is_calibration(self) -> bool:
        return self.delta_k == 0.0 and self.emitter_ratio == 1.0


def rail_clamp(v: npt.ArrayLike, supply_v: float, sharpness: float = 40.0) -> np.ndarray:
    """The output held between the rails with the optics model's rounded corners."""
    s, x = sharpness, np.asarray(v, dtype=float)
    return (np.logaddexp(0.0, s * x) - np.logaddexp(0.0, s * (x - supply_v))) / s


def module_output_v(dark_room_v: npt.ArrayLike, ambient_ratio: npt.ArrayLike,
                    rest_drop_v: npt.ArrayLike, state: DetectorState, supply_v: float = 5.0
                    ) -> np.ndarray:
    """The module's output [V] under ambient light and ``state``, from its dark-room output
    ``dark_room_v`` (the optics model's, at the calibration's temperature). The ambient
    photocurrent is ``ambient_ratio`` times the emitter's at rest (drop ``rest_drop_v``);
    it passes the same detector gain, not the emitter's."""
    v = np.asarray(dark_room_v, dtype=float)
    ratio = np.asarray(ambient_ratio, dtype=float)
    if state.is_calibration and not np.any(ratio):
        return v  # the paper's dark room: exactly the optics model's output
    drop = (supply_v - v) * state.skin_gain + ratio * rest_drop_v * state.detector_gain
    return rail_clamp(supply_v - drop - state.dark_drop_v, supply_v)


def headroom_ratio(rest_v: float, supply_v: float = 5.0, state: DetectorState | None = None,
                   floor_v: float = 0.0) -> float:
    """The ambient ratio that takes the output at rest (``rest_v``) down to ``floor_v``
    (the lower rail): how much light the detector still has room for."""
    state = state or DetectorState()
    rest_drop = (supply_v - rest_v)
    if rest_drop <= 0:
        raise PhysicsError("The output at rest is at the supply: no emitter light to state "
                           "ambient light against.")
    room = rest_v - floor_v - rest_drop * (state.skin_gain - 1.0) - state.dark_drop_v
    return max(0.0, room / (rest_drop * state.detector_gain))
