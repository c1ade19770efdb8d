"""The silicone's small rate effect: a Prony series on the probe force.

The FEM curve is the relaxed (long-term) response F_el(d). Pressing faster adds, per
Prony term i, a force h_i that grows with dF_el/dt and relaxes with time constant tau_i:

    F(t) = F_el(t) + sum_i h_i(t),   dh_i/dt = g_i dF_el/dt - h_i / tau_i

so at 10 mm/s (a 0.3 s ramp, shorter than the taus) the force exceeds the relaxed one by
almost sum(g_i), while at 0.1 mm/s it barely does (paper Fig. 9). The bulge, and with it
the module's output, follows the indentation quasi-statically: the mocks feed this force
to the gauge only.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from tactile_sensor.sensing.prony import PronySeries

from .errors import PhysicsError

if TYPE_CHECKING:
    from .params import PhysicsParams


class RateDependentForce:
    """Streaming (``step``) and batch (``force_history``) forms of the same Prony series;
    the recursion is ``sensing.prony``'s, which the driver's rate-aware calibration runs."""

    def __init__(self, g: Sequence[float], tau_s: Sequence[float]) -> None:
        g_arr, tau_arr = np.asarray(g, dtype=float), np.asarray(tau_s, dtype=float)
        if g_arr.shape != tau_arr.shape or g_arr.ndim != 1:
            raise PhysicsError("Prony moduli and times must be two lists of equal length.")
        if not (np.all(np.isfinite(g_arr)) and np.all(np.isfinite(tau_arr))
                and np.all(g_arr >= 0) and np.all(tau_arr > 0)):
            raise PhysicsError("Prony moduli must be >= 0 and relaxation times > 0 s.")
        self.g, self.tau = g_arr, tau_arr
        self._series = PronySeries(g_arr.tolist(), tau_arr.tolist())

    @classmethod
    def from_params(cls, params: PhysicsParams) -> RateDependentForce:
        return cls(params.prony_g, params.prony_tau)

    def reset(self) -> None:
        self._series.reset()

    def step(self, elastic_force_n: float, dt: float) -> float:
        """Advance by ``dt`` [s] to a relaxed force ``elastic_force_n``; returns the force
        (exact for a force changing linearly over the step)."""
        if not (math.isfinite(dt) and dt >= 0):
            raise PhysicsError(f"Time step {dt!r} s must be finite and >= 0.")
        return float(elastic_force_n + self._series.step(elastic_force_n, dt))

    def force_history(self, t: npt.ArrayLike, elastic_force_n: npt.ArrayLike) -> np.ndarray:
        """The force along a whole record (``t`` increasing), from rest."""
        times = np.asarray(t, dtype=float)
        forces = np.asarray(elastic_force_n, dtype=float)
        if times.shape != forces.shape or times.ndim != 1:
            raise PhysicsError("force_history needs equal-length 1-D time and force arrays.")
        if times.size and np.any(np.diff(times) < 0):
            raise PhysicsError("force_history needs increasing times.")
        saved = self._series.state  # a streaming user's state survives the batch
        self.reset()
        out = np.empty_like(forces)
        previous = times[0] if times.size else 0.0
        for k, (now, force) in enumerate(zip(times.tolist(), forces.tolist(), strict=True)):
            out[k] = self.step(force, now - previous)
            previous = now
        self._series.restore(saved)
        return out
