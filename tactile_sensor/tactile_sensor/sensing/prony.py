"""A Prony series driven by a force's rate: the one recursion physics and sensing share.

Each term i adds a force h_i with dh_i/dt = g_i dx/dt − h_i/tau_i, x the driving force.
Over a step of dt in which x changes linearly by Δx the exact update is

    h_i ← e^(−dt/tau_i) h_i + g_i Δx (1 − e^(−dt/tau_i)) tau_i / dt

(the gain → 1 as dt → 0, an instant step). Physics uses it for the gauge's true force
(``physics.viscoelastic``), the driver's rate-aware calibration for its estimate
(``sensing.rate_calibration``), so the estimator is exact on what the simulation makes.

Plain floats, not numpy: for 1–3 terms a Python loop over floats costs ~0.5 µs a step
against ~5 µs for small-array numpy operations, and the driver runs at 1 kHz. The two
coefficients depend on dt only, so they are kept while dt repeats (a steady ADC clock;
1e-12 s of float jitter in a difference of stamps counts as a repeat, a relative change
of the coefficients below 1e-11 for tau ≥ 0.1 s).
"""

from __future__ import annotations

import math
from collections.abc import Sequence


def term_coefficients(tau_s: float, dt_s: float) -> tuple[float, float]:
    """(decay, ramp gain) of one term over ``dt_s``: h ← decay·h + g·Δx·gain."""
    if dt_s == 0.0:
        return 1.0, 1.0
    x = dt_s / tau_s
    return math.exp(-x), -math.expm1(-x) / x


DT_SAME_S = 1e-12  # steps this close share coefficients (t_us * 1e-6 differences jitter)


class PronySeries:
    """Streaming sum of the terms, from rest; the first value after ``reset`` only sets
    the reference (no change has happened yet). Callers validate g ≥ 0, tau > 0, dt ≥ 0."""

    __slots__ = ("_decay", "_dt", "_g", "_gain", "_h", "_last", "_tau")

    def __init__(self, g: Sequence[float], tau_s: Sequence[float]) -> None:
        self._g = tuple(float(v) for v in g)
        self._tau = tuple(float(v) for v in tau_s)
        self._dt = -1.0
        self._decay: tuple[float, ...] = ()
        self._gain: tuple[float, ...] = ()
        self.reset()

    @property
    def state(self) -> tuple[tuple[float, ...], float | None]:
        """(terms h_i, last driving value): what ``restore`` puts back."""
        return tuple(self._h), self._last

    def restore(self, state: tuple[tuple[float, ...], float | None]) -> None:
        self._h = list(state[0])
        self._last = state[1]

    def reset(self) -> None:
        self._h = [0.0] * len(self._g)
        self._last: float | None = None

    def step(self, x: float, dt_s: float) -> float:
        """Advance by ``dt_s`` [s] to driving value ``x``; returns sum_i h_i."""
        last = self._last
        self._last = x
        if last is None:
            return 0.0
        if abs(dt_s - self._dt) > DT_SAME_S:
            coefficients = [term_coefficients(tau, dt_s) for tau in self._tau]
            self._decay = tuple(c[0] for c in coefficients)
            self._gain = tuple(c[1] for c in coefficients)
            self._dt = dt_s
        change = x - last
        h = self._h
        total = 0.0
        for i, (decay, gain, g) in enumerate(zip(self._decay, self._gain, self._g,
                                                 strict=True)):
            value = decay * h[i] + g * change * gain
            h[i] = value
            total += value
        return total
