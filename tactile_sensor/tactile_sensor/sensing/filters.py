"""Streaming filters for the photoreflector signal, selectable by name.

Every filter takes one float per sample (``update``) and returns the filtered value, in
O(1) pure Python, so the chain filters every sample at several kHz even when the node
publishes only a fraction of them.

- ``moving_average`` (window 9): the paper's 9-point average. Delay (window−1)/2 samples;
  among filters with non-negative weights it is the least noisy for its delay.
- ``savgol`` (window 40): causal Savitzky–Golay of degree 1, i.e. the
  least-squares straight line through the last ``window`` samples, evaluated at the newest
  one. Weights go negative at the old end, which cancels the delay on ramps (a press is a
  ramp) while averaging ~4× more samples: noise gain √((4N−2)/(N(N+1))) = 0.31 for N=40,
  below the 9-point average's 1/3 = 0.33, with zero delay on a ramp. Its price is a small
  overshoot where the slope changes abruptly (≈ slope × window / 8).
- ``savgol_quadratic`` (window 100): the least-squares parabola through the last ``window``
  samples, at the newest one. Exact on a parabola, so a turnaround (a finger's bend at its
  deepest) costs it nothing where ``savgol``'s line overshoots by ≈ curvature × window² / 12;
  its price is a higher noise gain for its window, √((9N²−9N+6)/(N(N+1)(N+2))) ≈ 3/√N
  (0.29 at its default 100, ``savgol``'s 0.31 at 40), so it takes a longer window for less noise.
- ``butterworth`` (order 2, cutoff 50 Hz): classic IIR low-pass, SOS form.
- ``one_euro`` (Casiez et al. 2012): adaptive EMA whose cutoff rises with speed.
- ``savgol_mains`` (the default): ``savgol`` behind an average over one period of the
  lamps' flicker, which it finds by itself (``sensing/mains_notch.py``): ambient light's
  100 or 120 Hz and their harmonics, for a module that sees the room (docs/ambient.md).
  Until it finds a flicker (in the dark room, always) it is ``savgol`` sample for sample,
  so its noise, lag and dynamic range there are ``savgol``'s; with a flicker found it
  delays a press by half a flicker period (4.5 ms at 100 Hz and 1 kHz).
- ``savgol_quadratic_mains``: ``savgol_quadratic`` behind the same notch.
- ``none``: pass-through.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from tactile_sensor.sensing.errors import SensingError
from tactile_sensor.sensing.filter_protocol import Filter
from tactile_sensor.sensing.mains_notch import MainsNotch

#: The default is the notch ahead of ``savgol``: a room's lamps are the common case, and in
#: the dark it is ``savgol`` itself (the notch passes the signal until it finds a flicker).
DEFAULT_FILTER = "savgol_mains"


class PassThrough:
    def update(self, x: float) -> float:
        return x

    def reset(self) -> None:
        return None


class MovingAverage:
    """Mean of the last ``window`` samples (fewer while it fills up)."""

    _REFRESH = 1 << 14  # recompute the running sum exactly now and then (float drift)

    def __init__(self, window: int = 9) -> None:
        self.window = _int_param("window", window, 1, 100_000)
        self.reset()

    def reset(self) -> None:
        self._buf: deque[float] = deque(maxlen=self.window)
        self._sum = 0.0
        self._count = 0

    def update(self, x: float) -> float:
        buf = self._buf
        if len(buf) == self.window:
            self._sum += x - buf[0]
        else:
            self._sum += x
        buf.append(x)
        self._count += 1
        if self._count % self._REFRESH == 0:
            self._sum = math.fsum(buf)
        return self._sum / len(buf)


class SavitzkyGolayLinear:
    """Least-squares line through the last ``window`` samples, read at the newest one.

    Running sums S = Σ y_i and T = Σ i·y_i (i = age, 0 = newest) update in O(1):
    T' = T + S − N·y_oldest, S' = S − y_oldest + x.
    """

    _REFRESH = 1 << 14

    def __init__(self, window: int = 40) -> None:
        self.window = _int_param("window", window, 2, 100_000)
        self.reset()

    def reset(self) -> None:
        self._buf: deque[float] = deque(maxlen=self.window)
        self._s = 0.0
        self._t = 0.0
        self._count = 0

    def update(self, x: float) -> float:
        buf = self._buf
        n = len(buf)
        if n == self.window:
            old = buf[0]
            self._t += self._s - n * old
            self._s += x - old
        else:
            self._t += self._s
            self._s += x
            n += 1
        buf.append(x)
        self._count += 1
        if self._count % self._REFRESH == 0:
            self._s = math.fsum(buf)
            self._t = math.fsum(i * y for i, y in enumerate(reversed(buf)))
        if n == 1:
            return x
        si = n * (n - 1) / 2.0
        si2 = (n - 1) * n * (2 * n - 1) / 6.0
        return (si2 * self._s - si * self._t) / (n * si2 - si * si)


class SavitzkyGolayQuadratic:
    """Least-squares parabola through the last ``window`` samples, read at the newest one.

    Running sums S_k = Σ i^k·y_i (k = 0, 1, 2; i = age, 0 = newest) update in O(1): every
    age grows by one and the oldest sample (age N) leaves, S2' = S2 + 2·S1 + S0 − N²·y_old,
    S1' = S1 + S0 − N·y_old, S0' = S0 − y_old + x. The fit's value at age 0 weights sample i
    by (3(3n²−3n+2) − 18(2n−1)·i + 30·i²) / (n(n+1)(n+2)), n the samples held.
    """

    _REFRESH = 1 << 14

    def __init__(self, window: int = 100) -> None:
        self.window = _int_param("window", window, 3, 100_000)
        self.reset()

    def reset(self) -> None:
        self._buf: deque[float] = deque(maxlen=self.window)
        self._s0 = self._s1 = self._s2 = 0.0
        self._count = 0

    def update(self, x: float) -> float:
        buf = self._buf
        n = len(buf)
        s0, s1 = self._s0, self._s1
        if n == self.window:
            old = buf[0]
            self._s2 += 2.0 * s1 + s0 - n * n * old
            self._s1 = s1 + s0 - n * old
            self._s0 = s0 - old + x
        else:
            self._s2 += 2.0 * s1 + s0
            self._s1 = s1 + s0
            self._s0 = s0 + x
            n += 1
        buf.append(x)
        self._count += 1
        if self._count % self._REFRESH == 0:
            ages = list(enumerate(reversed(buf)))
            self._s0 = math.fsum(buf)
            self._s1 = math.fsum(i * y for i, y in ages)
            self._s2 = math.fsum(i * i * y for i, y in ages)
        if n < 3:  # a parabola needs three samples; fewer are read as they come
            return x
        a = 3.0 * (3 * n * n - 3 * n + 2)
        b = 18.0 * (2 * n - 1)
        return (a * self._s0 - b * self._s1 + 30.0 * self._s2) / (n * (n + 1) * (n + 2))


class Butterworth:
    """Butterworth low-pass as second-order sections (transposed direct form II).

    Starts in steady state at the first sample, so there is no start-up transient.
    """

    def __init__(self, rate_hz: float, order: int = 2, cutoff_hz: float = 50.0) -> None:
        from scipy.signal import butter  # design only; the per-sample loop is plain Python

        self.order = _int_param("order", order, 1, 8)
        nyquist = rate_hz / 2.0
        self.cutoff_hz = _float_param("cutoff_hz", cutoff_hz, 1e-6, nyquist * 0.999)
        sos = butter(self.order, self.cutoff_hz, fs=rate_hz, output="sos")
        self._sos = [tuple(float(c) for c in row) for row in sos]
        self.reset()

    def reset(self) -> None:
        self._z: list[list[float]] | None = None

    def _steady(self, x: float) -> list[list[float]]:
        z = []
        for b0, b1, b2, _a0, a1, a2 in self._sos:
            gain = (b0 + b1 + b2) / (1.0 + a1 + a2)
            y = gain * x
            z2 = b2 * x - a2 * y
            z1 = b1 * x - a1 * y + z2
            z.append([z1, z2])
            x = y
        return z

    def update(self, x: float) -> float:
        if self._z is None:
            self._z = self._steady(x)
        for (b0, b1, b2, _a0, a1, a2), z in zip(self._sos, self._z, strict=True):
            y = b0 * x + z[0]
            z[0] = b1 * x - a1 * y + z[1]
            z[1] = b2 * x - a2 * y
            x = y
        return x


class OneEuro:
    """One-euro filter: EMA with cutoff ``min_cutoff_hz + beta·|dx/dt|`` [Hz, V/s]."""

    def __init__(self, rate_hz: float, min_cutoff_hz: float = 10.0, beta: float = 0.5,
                 d_cutoff_hz: float = 1.0) -> None:
        nyquist = rate_hz / 2.0
        self.min_cutoff_hz = _float_param("min_cutoff_hz", min_cutoff_hz, 1e-6, nyquist)
        self.beta = _float_param("beta", beta, 0.0, 1e6)
        self.d_cutoff_hz = _float_param("d_cutoff_hz", d_cutoff_hz, 1e-6, nyquist)
        self._dt = 1.0 / rate_hz
        self._alpha_d = self._alpha(self.d_cutoff_hz)
        self.reset()

    def _alpha(self, cutoff_hz: float) -> float:
        tau = 1.0 / (2.0 * math.pi * cutoff_hz)
        return 1.0 / (1.0 + tau / self._dt)

    def reset(self) -> None:
        self._x: float | None = None
        self._dx = 0.0

    def update(self, x: float) -> float:
        if self._x is None:
            self._x = x
            return x
        self._dx += self._alpha_d * ((x - self._x) / self._dt - self._dx)
        a = self._alpha(self.min_cutoff_hz + self.beta * abs(self._dx))
        self._x += a * (x - self._x)
        return self._x


@dataclass(frozen=True)
class FilterSpec:
    """How to build a filter by name: a factory ``(rate_hz, **params)`` and its defaults."""

    factory: Callable[..., Filter]
    defaults: Mapping[str, float | int]
    description: str


FILTERS: dict[str, FilterSpec] = {
    "savgol": FilterSpec(lambda rate_hz, **p: SavitzkyGolayLinear(**p), {"window": 40},
                         "causal linear Savitzky–Golay: ~zero lag on ramps"),
    "moving_average": FilterSpec(lambda rate_hz, **p: MovingAverage(**p), {"window": 9},
                                 "the paper's N-point moving average"),
    "savgol_quadratic": FilterSpec(
        lambda rate_hz, **p: SavitzkyGolayQuadratic(**p), {"window": 100},
        "causal quadratic Savitzky–Golay: exact on a parabola (a turnaround)"),
    "butterworth": FilterSpec(lambda rate_hz, **p: Butterworth(rate_hz, **p),
                              {"order": 2, "cutoff_hz": 50.0}, "Butterworth IIR low-pass"),
    "one_euro": FilterSpec(lambda rate_hz, **p: OneEuro(rate_hz, **p),
                           {"min_cutoff_hz": 10.0, "beta": 0.5, "d_cutoff_hz": 1.0},
                           "adaptive one-euro filter"),
    "savgol_mains": FilterSpec(
        lambda rate_hz, **p: MainsNotch(rate_hz, SavitzkyGolayLinear(**p)), {"window": 40},
        "savgol behind a notch at the lamps' flicker (100 or 120 Hz, found by itself) and "
        "its harmonics (sensing/mains_notch.py; default)"),
    "savgol_quadratic_mains": FilterSpec(
        lambda rate_hz, **p: MainsNotch(rate_hz, SavitzkyGolayQuadratic(**p)),
        {"window": 100}, "savgol_quadratic behind the notch of savgol_mains"),
    "none": FilterSpec(lambda rate_hz, **p: PassThrough(), {}, "no filtering"),
}


def make_filter(name: str, rate_hz: float, params: Mapping[str, Any] | None = None) -> Filter:
    """Build filter ``name`` for a stream at ``rate_hz``; unknown names/params are errors."""
    spec = FILTERS.get(name)
    if spec is None:
        raise SensingError(f"Unknown filter '{name}'; choose one of {', '.join(FILTERS)}.")
    if isinstance(rate_hz, bool) or not isinstance(rate_hz, int | float) or not (
            0.0 < rate_hz <= 1e6):
        raise SensingError(f"The sample rate must be in (0, 1e6] Hz, got {rate_hz!r}.")
    given = dict(params or {})
    unknown = sorted(set(given) - set(spec.defaults))
    if unknown:
        allowed = ", ".join(spec.defaults) or "none"
        raise SensingError(f"Filter '{name}' has no parameter {', '.join(unknown)}; "
                           f"its parameters are: {allowed}.")
    return spec.factory(float(rate_hz), **{**spec.defaults, **given})


def _int_param(name: str, value: object, lo: int, hi: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int | float) \
            or not math.isfinite(value) or value != int(value) or not lo <= int(value) <= hi:
        raise SensingError(f"Filter parameter {name} must be an integer in {lo}..{hi}, "
                           f"got {value!r}.")
    return int(value)


def _float_param(name: str, value: object, lo: float, hi: float) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not (
            lo <= float(value) <= hi):
        raise SensingError(f"Filter parameter {name} must be in [{lo:g}, {hi:g}], "
                           f"got {value!r}.")
    return float(value)
