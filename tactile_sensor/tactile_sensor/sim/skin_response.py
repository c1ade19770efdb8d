"""How the skin under the module answers an indentation: elastic force and sensor voltage.

The simulators depend on this small protocol, not on the FEM code, so a world can run on
any monotone curve; ``default_skin`` builds the real one from physics' prediction curve
(the same curve the model node serves, so mock data and predictions agree).
"""

from __future__ import annotations

import bisect
from collections.abc import Callable
from typing import Any, Protocol

import numpy as np
import numpy.typing as npt

from tactile_sensor.sim.errors import SimError

ArrayLike = float | npt.ArrayLike


class SkinResponse(Protocol):
    """Quasi-static response to an indentation [m] (vectorised)."""

    def force_n(self, indentation_m: ArrayLike) -> Any: ...

    def voltage_v(self, indentation_m: ArrayLike) -> Any: ...


class PredictionCurveLike(Protocol):
    indentation_m: npt.NDArray[np.float64]
    force_n: npt.NDArray[np.float64]
    voltage_v: npt.NDArray[np.float64]
    digest: str


#: Stiffness of the resin frame under the skin once the skin is used up [N/m].
RIGID_STIFFNESS_N_PER_M = 2.0e5


class TabulatedSkin:
    """A skin response from tabulated points, linear in between.

    Beyond the table the force continues with the last slope, and past ``thickness_m``
    (default 1.5 x the table) the skin bottoms out on the resin frame, a stiff spring; the
    voltage holds its end values (the module saturates). Scalars take a pure-Python path:
    the servo emulator looks the skin up in its inner loop, where numpy's call overhead
    dominates. Arrays (the bench world's precomputed grid) take numpy's.
    """

    def __init__(self, indentation_m: npt.ArrayLike, force_n: npt.ArrayLike,
                 voltage_v: npt.ArrayLike, source: str = "table",
                 thickness_m: float | None = None) -> None:
        d = np.asarray(indentation_m, dtype=float)
        f = np.asarray(force_n, dtype=float)
        v = np.asarray(voltage_v, dtype=float)
        if d.ndim != 1 or d.size < 2 or f.shape != d.shape or v.shape != d.shape:
            raise SimError("A skin table needs three 1-D arrays of equal length ≥ 2 "
                           "(indentation_m, force_n, voltage_v).")
        if not (np.all(np.isfinite(d)) and np.all(np.isfinite(f)) and np.all(np.isfinite(v))):
            raise SimError("A skin table must not contain NaN or infinite values.")
        if np.any(np.diff(d) <= 0) or d[0] < 0:
            raise SimError("Skin table indentations must start at >= 0 and be strictly increasing.")
        if np.any(np.diff(f) < 0):
            raise SimError("Skin table forces must not decrease with indentation.")
        self._d, self._f, self._v = d, f, v
        self._dl, self._fl, self._vl = d.tolist(), f.tolist(), v.tolist()
        self._slope = float((f[-1] - f[-2]) / (d[-1] - d[-2]))
        self.thickness_m = float(thickness_m) if thickness_m is not None else 1.5 * float(d[-1])
        self.source = source

    @property
    def max_indentation_m(self) -> float:
        return float(self._d[-1])

    def table(self) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64],
                             npt.NDArray[np.float64]]:
        """Copies of the tabulated indentations [m], forces [N] and voltages [V]: what an
        exact inverse of the skin needs."""
        return self._d.copy(), self._f.copy(), self._v.copy()

    def force_n(self, indentation_m: ArrayLike) -> Any:
        if isinstance(indentation_m, float | int):
            d = max(0.0, float(indentation_m))
            if d <= self._dl[-1]:
                force = self._interp(d, self._fl)
            else:
                force = self._fl[-1] + self._slope * (d - self._dl[-1])
            if d > self.thickness_m:
                force += RIGID_STIFFNESS_N_PER_M * (d - self.thickness_m)
            return force
        d = np.maximum(np.asarray(indentation_m, dtype=float), 0.0)
        force = np.interp(d, self._d, self._f)
        beyond = d > self._d[-1]
        force = np.where(beyond, self._f[-1] + self._slope * (d - self._d[-1]), force)
        return force + RIGID_STIFFNESS_N_PER_M * np.maximum(d - self.thickness_m, 0.0)

    def voltage_v(self, indentation_m: ArrayLike) -> Any:
        if isinstance(indentation_m, float | int):
            return self._interp(min(max(0.0, float(indentation_m)), self._dl[-1]), self._vl)
        return np.interp(indentation_m, self._d, self._v)

    def _interp(self, d: float, values: list[float]) -> float:
        xs = self._dl
        if d <= xs[0]:
            return values[0]
        i = min(bisect.bisect_right(xs, d), len(xs) - 1)
        x0, x1 = xs[i - 1], xs[i]
        return values[i - 1] + (values[i] - values[i - 1]) * (d - x0) / (x1 - x0)

    @classmethod
    def from_prediction_curve(cls, curve: PredictionCurveLike,
                              thickness_m: float | None = None) -> TabulatedSkin:
        """Adapter from ``physics.prediction.PredictionCurve``."""
        return cls(curve.indentation_m, curve.force_n, curve.voltage_v,
                   source=f"fem:{curve.digest}", thickness_m=thickness_m)


def default_skin(progress: Callable[[float, str], None] | None = None) -> TabulatedSkin:
    """The FEM prediction for the default physics parameters (cached after the first run;
    a cold sweep takes a while and reports ``progress(fraction, message)``)."""
    try:
        from tactile_sensor.physics.errors import PhysicsError
        from tactile_sensor.physics.params import PhysicsParams
        from tactile_sensor.physics.prediction import load_or_compute_curve
    except ImportError as exc:
        raise SimError(f"The physics model is not available ({exc}); install the complete "
                       "tactile_sensor package.") from None
    try:
        curve = load_or_compute_curve(PhysicsParams(), progress=progress)
    except PhysicsError as exc:
        raise SimError(f"The FEM prediction failed ({exc}); pass a measured skin table "
                       "instead (--skin-table).") from None
    return TabulatedSkin.from_prediction_curve(curve)
