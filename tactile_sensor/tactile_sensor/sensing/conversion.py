"""ADC counts → photoreflector voltage, with the ADC's resolution and reference as data."""

from __future__ import annotations

from dataclasses import dataclass

from tactile_sensor.sensing.errors import SensingError


@dataclass(frozen=True)
class AdcConversion:
    """Ideal ADC transfer: ``volts = counts · vref_v / (2^bits − 1)``.

    The QTR-1A's output spans 0..Vcc, so full scale of a ratiometric ADC reads Vcc.
    """

    bits: int = 12
    vref_v: float = 5.0

    def __post_init__(self) -> None:
        if isinstance(self.bits, bool) or not isinstance(self.bits, int) or not (
                1 <= self.bits <= 16):
            raise SensingError(f"adc_bits must be an integer 1..16 (frames carry 16 bits), "
                               f"got {self.bits!r}.")
        if not isinstance(self.vref_v, int | float) or not 0.0 < self.vref_v <= 100.0:
            raise SensingError(f"vref_v must be a positive voltage ≤ 100 V, got {self.vref_v!r}.")

    @property
    def full_scale_counts(self) -> int:
        return (1 << self.bits) - 1

    @property
    def volts_per_count(self) -> float:
        return self.vref_v / self.full_scale_counts

    def volts(self, counts: int) -> float:
        """Voltage of one reading; counts above full scale mean a misconfigured ADC width."""
        return counts * self.volts_per_count

    def counts(self, volts: float) -> int:
        """Nearest code for ``volts`` (clipped to the rails), as a real ADC would read it."""
        code = round(volts / self.volts_per_count)
        return min(max(code, 0), self.full_scale_counts)
