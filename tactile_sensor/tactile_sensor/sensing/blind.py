"""A detector blinded by light, and the headroom it has left before it is.

The QTR-1A's phototransistor pulls its output toward 0 V as light grows; at saturation the
output sits at the lower rail whatever the skin does, so a force read there is a guess.
A sample at or below ``SATURATION_V`` is **blind**: the chain gives NaN force, no contact,
and refuses to tare. It sees again once the voltage has stayed above the rail (plus a
hysteresis) for ``settle_samples``: the filter's window, so no rail sample is left in the
filtered voltage when force comes back (docs/ambient.md).
"""

from __future__ import annotations

from dataclasses import dataclass

from tactile_sensor.sensing.errors import SensingError

#: QRE1113 collector-emitter saturation voltage, at most 0.3 V (onsemi datasheet): below
#: it the phototransistor is saturated.
SATURATION_V = 0.3
#: Above the rail by this much before a sample counts as seeing again (ADC noise).
HYSTERESIS_V = 0.05
BLIND_MESSAGE = ("ambient light saturates the detector: force is NaN until the light goes "
                 "(shade the module from the lamp or the window)")


@dataclass
class BlindDetector:
    """Per-sample blindness with hysteresis; ``settle_samples`` >= 1."""

    settle_samples: int = 1
    saturation_v: float = SATURATION_V
    hysteresis_v: float = HYSTERESIS_V

    def __post_init__(self) -> None:
        if not isinstance(self.settle_samples, int) or self.settle_samples < 1:
            raise SensingError(f"settle_samples must be an integer >= 1, got "
                               f"{self.settle_samples!r}.")
        self.blind = False
        self.blind_samples = 0  # how many samples were blind since start
        self._seeing = 0

    def update(self, volts: float) -> bool:
        """Whether this sample is blind."""
        if volts <= self.saturation_v:
            self.blind, self._seeing = True, 0
        elif self.blind:
            self._seeing = self._seeing + 1 if volts > self.saturation_v + self.hysteresis_v \
                else 0
            self.blind = self._seeing < self.settle_samples
        if self.blind:
            self.blind_samples += 1
        return self.blind

    def reset(self) -> None:
        self.blind, self._seeing = False, 0


def headroom(volts: float, baseline_v: float | None, supply_v: float
             ) -> tuple[float, float | None]:
    """(volts left above saturation [V], that as a ratio of the emitter's drop at rest):
    the ambient light, in the ratio docs/ambient.md states scenes in, the detector still
    has room for; the ratio is None before a tare (no rest drop known)."""
    if volts != volts:  # no sample yet
        return volts, None
    left = max(0.0, volts - SATURATION_V)
    if baseline_v is None or supply_v - baseline_v <= 0:
        return left, None
    return left, left / (supply_v - baseline_v)
