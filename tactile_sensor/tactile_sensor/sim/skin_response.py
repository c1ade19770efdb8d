"""How the skin under the module answers an indentation: elastic force and sensor voltage.

The simulators depend on this small protocol, not on the FEM code, so a world can run on
any monotone curve; ``default_skin`` builds the real one from physics' prediction curve
(the same curve the model node serves, so mock data and predictions agree).
"""

from __future__ import annotations

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


class TabulatedSkin:
    """A skin response from tabulated points, linear in between, clamped at both ends."""

    def __init__(self, indentation_m: npt.ArrayLike, force_n: npt.ArrayLike,
                 voltage_v: npt.ArrayLike, source: str = "table") -> None:
        d = np.asarray(indentation_m, dtype=float)
        f = np.asarray(force_n, dtype=float)
        v = np.asarray(voltage_v, dtype=float)
        if d.ndim != 1 or d.size < 2 or f.shape != d.shape or v.shape != d.shape:
            raise SimError("A skin table needs three 1-D arrays of equal length ≥ 2 "
                           "(indentation_m, force_n, voltage_v).")
        if not (np.all(np.isfinite(d)) and np.all(np.isfinite(f)) and np.all(np.isfinite(v))):
            raise SimError("A skin table must not contain NaN or infinite values.")
        if np.any(np.diff(d) <= 0):
            raise SimError("Skin table indentations must be strictly increasing.")
        self._d, self._f, self._v = d, f, v
        self.source = source

    @property
    def max_indentation_m(self) -> float:
        return float(self._d[-1])

    def force_n(self, indentation_m: ArrayLike) -> Any:
        return np.interp(indentation_m, self._d, self._f)

    def voltage_v(self, indentation_m: ArrayLike) -> Any:
        return np.interp(indentation_m, self._d, self._v)

    @classmethod
    def from_prediction_curve(cls, curve: PredictionCurveLike) -> TabulatedSkin:
        """Adapter from ``physics.prediction.PredictionCurve``."""
        return cls(curve.indentation_m, curve.force_n, curve.voltage_v,
                   source=f"fem:{curve.digest}")


def default_skin(progress: Callable[[float, str], None] | None = None) -> TabulatedSkin:
    """The FEM prediction for the default physics parameters (cached after the first run;
    a cold sweep takes a while and reports ``progress(fraction, message)``)."""
    try:
        from tactile_sensor.physics.params import PhysicsParams
        from tactile_sensor.physics.prediction import load_or_compute_curve
    except ImportError as exc:
        raise SimError(f"The physics model is not available ({exc}); install the complete "
                       "tactile_sensor package.") from None
    curve = load_or_compute_curve(PhysicsParams(), progress=progress)
    return TabulatedSkin.from_prediction_curve(curve)
