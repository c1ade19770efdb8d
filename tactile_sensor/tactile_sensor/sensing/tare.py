"""Tare: the baseline voltage is the mean over a window taken while the sensor is at rest.

"At rest" is checked, not assumed: the window is cut into blocks and the spread of the
block means (max − min) must stay under a bound. Block means average the white noise
away (σ/√(n/blocks)) but keep any slow trend, so a press in progress (a ramp) is refused
while a noisy idle signal is accepted.
"""

from __future__ import annotations

import math
from collections import deque
from typing import NamedTuple

from tactile_sensor.sensing.errors import SensingError, TareError

TARE_BLOCKS = 10


class TareResult(NamedTuple):
    baseline_v: float
    spread_v: float
    samples: int

    def describe(self) -> str:
        return f"baseline {self.baseline_v:.4f} V (spread {self.spread_v * 1e3:.1f} mV)"


class TareWindow:
    """Keeps the last ``window_s`` of voltages so a tare can be answered at once."""

    def __init__(self, rate_hz: float, window_s: float = 0.5, max_spread_v: float = 0.05) -> None:
        if not isinstance(window_s, int | float) or not 0.0 < window_s <= 60.0:
            raise SensingError(f"tare_window_s must be in (0, 60] s, got {window_s!r}.")
        if not isinstance(max_spread_v, int | float) or not 0.0 < max_spread_v <= 10.0:
            raise SensingError(f"tare_max_spread_v must be in (0, 10] V, got {max_spread_v!r}.")
        self.window_s = float(window_s)
        self.max_spread_v = float(max_spread_v)
        self.size = max(TARE_BLOCKS, round(window_s * rate_hz))
        self._buf: deque[float] = deque(maxlen=self.size)

    def add(self, voltage_v: float) -> None:
        self._buf.append(voltage_v)

    def clear(self) -> None:
        self._buf.clear()

    @property
    def ready(self) -> bool:
        return len(self._buf) == self.size

    def evaluate(self) -> TareResult:
        """Baseline from the current window, or ``TareError`` saying why not."""
        values = list(self._buf)
        if len(values) < self.size:
            raise TareError(
                f"Tare needs {self.window_s:g} s of samples at rest ({self.size}), only "
                f"{len(values)} so far; wait for the stream and try again."
            )
        block = len(values) // TARE_BLOCKS
        means = [math.fsum(values[k * block:(k + 1) * block]) / block
                 for k in range(TARE_BLOCKS)]
        spread = max(means) - min(means)
        if not spread <= self.max_spread_v:  # also refuses NaN
            raise TareError(
                f"Tare refused: the signal is not at rest (its level moved {spread * 1e3:.1f} mV "
                f"within {self.window_s:g} s, the bound is {self.max_spread_v * 1e3:.1f} mV); "
                "release the sensor and try again."
            )
        return TareResult(math.fsum(values) / len(values), spread, len(values))
