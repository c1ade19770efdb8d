"""A notch at the lamps' flicker and its harmonics, at a frequency it finds by itself.

Lamps on the mains flicker at twice its frequency, 100 or 120 Hz, with harmonics at every
multiple (docs/ambient.md); a press has its content below ~5 Hz. An average over exactly
one flicker period nulls the flicker and every harmonic at once (a comb), and delays a
ramp by half a period (5 ms at 100 Hz). The flicker is found by Goertzel filters at 100
and 120 Hz over half-second blocks: the comb follows the one that carries at least
``MIN_SHARE`` of a block's variance, twice in a row; until one does, it passes the signal
through. A period that is not a whole number of samples (120 Hz at 1 kHz: 8.33) weights
its oldest sample by the fraction, which leaves a small residue of the harmonics.

It is the default filter's first stage, so it must not refuse a rate a driver may run at:
at or below twice the highest flicker (240 Hz) the ADC cannot see a flicker (it aliases),
and the notch never looks for one: it passes the signal through (``can_see_flicker``).
"""

from __future__ import annotations

import math
from collections import deque

from tactile_sensor.sensing.errors import SensingError
from tactile_sensor.sensing.filter_protocol import Filter

FLICKERS_HZ = (100.0, 120.0)
BLOCK_S = 0.5
#: A flicker must carry this share of a block's variance to be taken for one.
MIN_SHARE = 0.25


class _Goertzel:
    """The power of one frequency over a block, one sample at a time."""

    def __init__(self, frequency_hz: float, rate_hz: float) -> None:
        self.coeff = 2.0 * math.cos(2.0 * math.pi * frequency_hz / rate_hz)
        self.s1 = self.s2 = 0.0

    def update(self, x: float) -> None:
        self.s1, self.s2 = x + self.coeff * self.s1 - self.s2, self.s1

    def power(self, n: int) -> float:
        """Mean-square amplitude of the frequency's sinusoid over the last block of ``n``."""
        s1, s2 = self.s1, self.s2
        self.s1 = self.s2 = 0.0
        return 2.0 * (s1 * s1 + s2 * s2 - self.coeff * s1 * s2) / (n * n)


class MainsNotch:
    """The comb at the flicker it found, ahead of the filter ``then`` (any ``Filter``)."""

    def __init__(self, rate_hz: float, then: Filter) -> None:
        if not rate_hz > 0.0:
            raise SensingError(f"A mains notch needs a positive sample rate, got {rate_hz!r}.")
        self.rate_hz = rate_hz
        self.then = then
        #: Whether the rate is above twice every flicker's: below, the notch passes through.
        self.can_see_flicker = rate_hz > 2.0 * max(FLICKERS_HZ)
        comb = math.ceil(rate_hz / min(FLICKERS_HZ)) if self.can_see_flicker else 0
        # samples until no rail sample is left: the comb's period and the filter's window
        self.window = getattr(then, "window", 1) + comb
        self._block = max(1, round(BLOCK_S * rate_hz))
        self.flicker_hz: float | None = None
        self.reset()

    def reset(self) -> None:
        self._goertzel = [_Goertzel(f, self.rate_hz) for f in FLICKERS_HZ]
        self._n = 0
        self._sum = self._sum_sq = 0.0
        self._candidate: float | None = None
        self._buf: deque[float] = deque()
        self.then.reset()

    def update(self, x: float) -> float:
        if not self.can_see_flicker:
            return self.then.update(x)
        for g in self._goertzel:
            g.update(x)
        self._n += 1
        self._sum += x
        self._sum_sq += x * x
        if self._n == self._block:
            self._judge()
        return self.then.update(self._comb(x))

    def _judge(self) -> None:
        n = self._n
        variance = max(self._sum_sq / n - (self._sum / n) ** 2, 1e-18)
        powers = [g.power(n) for g in self._goertzel]
        self._n, self._sum, self._sum_sq = 0, 0.0, 0.0
        best = max(range(len(powers)), key=powers.__getitem__)
        found = FLICKERS_HZ[best] if powers[best] >= MIN_SHARE * variance else None
        if found is not None and found == self._candidate and found != self.flicker_hz:
            self.flicker_hz = found
            self._buf.clear()
        self._candidate = found

    def _comb(self, x: float) -> float:
        if self.flicker_hz is None:
            return x
        period = self.rate_hz / self.flicker_hz
        whole = int(period)
        frac = period - whole
        buf = self._buf
        buf.append(x)
        if len(buf) > whole + 1:
            buf.popleft()
        if len(buf) <= whole:
            return sum(buf) / len(buf)
        oldest = buf[0]
        return (sum(buf) - oldest + frac * oldest) / period
