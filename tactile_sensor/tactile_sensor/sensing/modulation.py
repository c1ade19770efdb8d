"""A modulated module's on/off pair as one signal: the emitter's light alone.

A modulated device (protocol version 3) switches the emitters apart from the detectors'
pull-ups and samples each channel with the emitter on and off in every period. Ambient
light and dark current are in both samples, the emitter's light only in the on one, so
``off - on`` is the emitter's drop across the pull-up, whatever the room's light.

The detector follows a switch with its time constant ``tau`` (the QRE1113 on the QTR-1A's
47 kOhm pull-up: 0.43 ms, ``physics.detector.response_tau_s``). With the emitter on for
the first half of a period ``P`` and off for the second, each sampled ``s`` after its switch,
the periodic steady state of a first-order response gives the levels, as shares of the
emitter's full drop::

    on  = 1 - e^(-s/tau) / (1 + e^(-P/(2 tau)))
    off = e^(-s/tau) / (1 + e^(-P/(2 tau)))

so the difference keeps ``on - off`` of it; the chain divides by that share. The off
sample is the mean of the one before and the one after the on sample (half a period each
way), so ambient light that changes linearly over a period cancels too.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from tactile_sensor.hardware.adc_frame import DeviceInfo
from tactile_sensor.sensing.errors import SensingError

#: The QRE1113's time constant on the QTR-1A's 47 kOhm pull-up [s]: the datasheet's 20 us
#: rise at 1 kOhm scaled to the load, over ln 9 (physics.detector.response_tau_s; a test
#: holds the two equal).
DETECTOR_TAU_S = 20e-6 * 47.0 / math.log(9.0)
#: Below this share of the emitter's drop the difference is mostly noise scaled up: a
#: timing that keeps less is refused.
MIN_SHARE = 0.1


def emitter_levels(settle_s: float, period_s: float, tau_s: float = DETECTOR_TAU_S
                   ) -> tuple[float, float]:
    """(on, off): the emitter's drop the detector shows ``settle_s`` after switching the
    emitter on and off, as shares of its full drop, in the periodic steady state of a
    half-on, half-off period ``period_s``."""
    if not (0 < settle_s <= period_s / 2 and tau_s > 0):
        raise SensingError(f"A settle time of {settle_s!r} s must be within half the period "
                           f"({period_s!r} s), and the detector's time constant positive.")
    left = math.exp(-settle_s / tau_s) / (1.0 + math.exp(-period_s / (2.0 * tau_s)))
    return 1.0 - left, left


@dataclass(frozen=True)
class Modulation:
    """How a modulated device samples (from its info frame) and what share of the emitter's
    drop the on - off difference keeps for one channel."""

    period_us: int
    settle_us: int
    read_us: int
    channel: int
    channels: int
    tau_s: float = DETECTOR_TAU_S

    @property
    def levels(self) -> tuple[float, float]:
        """(on, off): the shares of the emitter's drop in this channel's on and off
        samples (taken ``settle_us + channel * read_us`` after each switch)."""
        settle_s = (self.settle_us + self.channel * self.read_us) * 1e-6
        return emitter_levels(settle_s, self.period_us * 1e-6, self.tau_s)

    @property
    def share(self) -> float:
        """The share of the emitter's drop in ``off - on`` for this channel."""
        on, off = self.levels
        return on - off


def modulation_of(info: DeviceInfo, channel: int) -> Modulation | None:
    """How a device samples ``channel``: None unless it says modulation is on;
    ``SensingError`` if its timing cannot be read as a half-on, half-off period."""
    if not info.modulated:
        return None
    modulation = Modulation(info.period_us or 0, info.settle_us or 0, info.read_us or 0,
                            channel, info.channels)
    share = modulation.share
    if share < MIN_SHARE:
        raise SensingError(f"Sampling {modulation.settle_us} us after each emitter switch "
                           f"in a {modulation.period_us} us period keeps "
                           f"{share * 100:.0f} % of the emitter's light (the detector has "
                           "not followed the switch); the firmware must wait longer before "
                           "sampling.")
    return modulation


class PairSignal:
    """Per sample, the emitter's light as the output a dark room would give:
    ``vref - (off - on) / share``, with ``off`` the mean of the off samples around ``on``.
    Feed samples in order; ``reset`` after a gap in the stream."""

    def __init__(self, modulation: Modulation, vref_v: float) -> None:
        self.modulation = modulation
        self._gain = 1.0 / modulation.share
        self._off_share = modulation.levels[1]
        self._vref = vref_v
        self._off_index = modulation.channels + modulation.channel
        self._last_off: float | None = None

    @property
    def off_index(self) -> int:
        """Where the chain's channel's off code sits in a frame's codes."""
        return self._off_index

    def reset(self) -> None:
        self._last_off = None

    def ambient_drop(self, on_v: float, off_v: float) -> float:
        """The room's light (and dark current) as a drop below ``vref`` [V]: the off
        sample's drop less the emitter's light the detector still shows in it."""
        return self._vref - off_v - (off_v - on_v) * self._gain * self._off_share

    def signal(self, on_v: float, off_v: float) -> float:
        last, self._last_off = self._last_off, off_v
        off = off_v if last is None else 0.5 * (last + off_v)
        return self._vref - (off - on_v) * self._gain
