"""Which ADC resolution and reference turn counts into volts: the device's word or ours.

A version-2 device states its resolution, reference, channel count and rate
(docs/serial-frame.md), so by default the driver takes them from the device, and a
configured value that contradicts the device is refused rather than silently used: a
10-bit code read as 12-bit gives forces four times too small. A version-1 device states
nothing, so the configured values (or, unset, what the version-1 reference sketch sent on
every board: 10 bit at 5 V) are used with a warning that they are assumed.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass
from typing import Protocol

from tactile_sensor.sensing.conversion import AdcConversion

# The version-1 reference sketch never switched a board to 12 bit (its
# `#if defined(analogReadResolution)` is never true), so every v1 board sent 10-bit codes.
V1_ASSUMED_BITS = 10
V1_ASSUMED_VREF_V = 5.0
VREF_TOLERANCE_V = 0.0005  # the info frame carries millivolts
RATE_TOLERANCE = 0.01  # relative; a device off by more runs the filters at the wrong rate


class StatedAdc(Protocol):
    """What the settings need of ``hardware.adc_frame.DeviceInfo``."""

    @property
    def version(self) -> int: ...

    @property
    def channels(self) -> int: ...

    @property
    def adc_bits(self) -> int | None: ...

    @property
    def vref_v(self) -> float | None: ...

    @property
    def rate_hz(self) -> float | None: ...


class Source(enum.Enum):
    DEVICE = "device"  # stated by the device (protocol 2)
    CONFIGURED = "configured"  # the device states nothing; the user's values
    ASSUMED = "assumed"  # the device states nothing, nor did the user: V1_ASSUMED_*
    CONTRADICTED = "contradicted"  # configuration and device disagree: nothing is used


@dataclass(frozen=True)
class AdcSettings:
    """The decision: ``conversion`` is None when configuration and device disagree.

    ``problem`` is one sentence naming the values and the fix: an error when
    ``conversion`` is None, otherwise a warning (assumed resolution, rate mismatch) or "".
    """

    conversion: AdcConversion | None
    source: Source
    problem: str = ""

    @property
    def usable(self) -> bool:
        return self.conversion is not None


def resolve_adc(stated: StatedAdc, configured_bits: int | None = None,
                configured_vref_v: float | None = None, channel: int = 0,
                rate_hz: float | None = None) -> AdcSettings:
    """Settings for a device that ``stated`` this; None configured = from the device.

    ``channel`` is the channel the consumer reads, ``rate_hz`` the rate its filters are
    designed for (a device sampling at another rate is a warning).
    """
    if channel >= stated.channels:
        return AdcSettings(None, Source.CONTRADICTED, (
            f"The driver reads channel {channel} but the device sends {stated.channels} "
            f"channel(s); set channel to 0..{stated.channels - 1} or raise CHANNELS in the "
            "firmware."))
    if stated.adc_bits is None or stated.vref_v is None:
        bits = configured_bits if configured_bits is not None else V1_ASSUMED_BITS
        vref = configured_vref_v if configured_vref_v is not None else V1_ASSUMED_VREF_V
        configured = configured_bits is not None and configured_vref_v is not None
        whose = "configured" if configured else "assumed"
        return AdcSettings(AdcConversion(bits, vref),
                           Source.CONFIGURED if configured else Source.ASSUMED, (
            f"The ADC speaks protocol version {stated.version}, which does not state its "
            f"resolution: using the {whose} {bits} bit and {vref:g} V; set adc_bits and "
            "reference_voltage to match the firmware, or flash the version-2 sketch "
            "(firmware/tactile_adc) so the device states them."))
    clashes = []
    if configured_bits is not None and configured_bits != stated.adc_bits:
        clashes.append(f"adc_bits is configured as {configured_bits} bit but the device "
                       f"sends {stated.adc_bits}-bit codes")
    if configured_vref_v is not None and abs(configured_vref_v - stated.vref_v) > \
            VREF_TOLERANCE_V:
        clashes.append(f"reference_voltage is configured as {configured_vref_v:g} V but the "
                       f"device reports {stated.vref_v:g} V")
    if clashes:
        names = " and ".join(c.split(" ", 1)[0] for c in clashes)
        return AdcSettings(None, Source.CONTRADICTED, (
            f"{'; '.join(clashes)}: no force is published; remove {names} from the "
            "configuration (default: from the device) or fix the firmware."))
    warning = ""
    device_rate = stated.rate_hz
    if rate_hz is not None and device_rate is not None and \
            abs(device_rate - rate_hz) > RATE_TOLERANCE * rate_hz:
        warning = (f"The device samples at {device_rate:g} Hz but sample_rate is {rate_hz:g} "
                   f"Hz, so the filters and the tare window run at the wrong rate; set "
                   f"sample_rate to {device_rate:g}.")
    return AdcSettings(AdcConversion(stated.adc_bits, stated.vref_v), Source.DEVICE, warning)
