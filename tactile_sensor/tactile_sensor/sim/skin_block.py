"""A skin block: its modules and how it answers what acts on it.

Every simulated world holds its skin as a ``SkinBlock``, whatever presses it (a bench
stage or a gripper finger): the block names its modules in layout order (``faces``; none
for a skin without a module, as on the gripper's finger B) and answers a load state with
each module's voltage and the true force or wrench, from one response:

- a single-module response (``TabulatedSkin``, the FEM curve) takes the indentation only
  (``axes`` 1) and gives the normal force;
- the array grid (``ArraySkin``) takes indentation and lateral displacement (``axes`` 3)
  and gives (Fx, Fy, Fz);
- the wrench set (``WrenchSkin``) adds tilt and twist (``axes`` 6) and gives the wrench.

A block with a viscoelastic model also gives the rate effect along a record
(:meth:`SkinBlock.rated`); a layout whose response does not take an axis has none.
"""

from __future__ import annotations

import math
from typing import Any, Protocol

import numpy as np
import numpy.typing as npt

from tactile_sensor.sim.errors import SimError

#: The module a single-module response reads: the physics parameters' default face.
SINGLE_MODULE = ("front",)


class ViscoelasticModel(Protocol):
    """Streaming rate effect, as physics' ``RateDependentForce`` provides."""

    def step(self, elastic_force_n: float, dt: float) -> float: ...

    def reset(self) -> None: ...


def rate_force(model: ViscoelasticModel, t: npt.NDArray[np.float64],
               f_el: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """The rate effect along a record from rest, streamed sample by sample (the model's own
    batch when it has one)."""
    batch = getattr(model, "force_history", None)
    if callable(batch):
        return np.asarray(batch(t, f_el), dtype=float)
    model.reset()
    dt = float(t[1] - t[0])
    out = np.empty_like(f_el)
    step = model.step
    for k, f in enumerate(f_el.tolist()):
        out[k] = step(f, dt)
    return out


def filtered_rate_force(model: ViscoelasticModel, t: np.ndarray, f_el: np.ndarray
                        ) -> np.ndarray:
    """The rate effect along a record from rest. A Prony series (``g``, ``tau``) on this
    uniform time grid runs as one linear filter per term: the same recursion as
    ``RateDependentForce.step`` (exact for a force linear over each step), but a
    104 s shear run's three axes take milliseconds instead of seconds in Python."""
    g, tau = getattr(model, "g", None), getattr(model, "tau", None)
    dt = np.diff(t)
    if g is not None and tau is not None and dt.size and np.allclose(dt, dt[0], rtol=1e-9):
        from scipy.signal import lfilter

        step = float(dt[0])
        change = np.diff(f_el)
        out = f_el.astype(float).copy()
        for gi, ti in zip(np.asarray(g, float).tolist(), np.asarray(tau, float).tolist(),
                          strict=True):
            decay = math.exp(-step / ti)
            out[1:] += lfilter([gi * (1.0 - decay) * ti / step], [1.0, -decay], change)
        return out
    return rate_force(model, t, f_el)


class SkinBlock:
    """One skin block: ``faces`` (its modules, layout order), ``axes`` (how many load
    components act on it) and its response to them."""

    def __init__(self, response: Any, faces: tuple[str, ...] | None = None,
                 viscoelastic: ViscoelasticModel | None = None,
                 stiffness_ratio: float = 1.0) -> None:
        own = getattr(response, "faces", None)
        self.axes: int = int(getattr(response, "axes", 1))
        self.faces: tuple[str, ...] = tuple(
            faces if faces is not None else own if own is not None else SINGLE_MODULE)
        if self.axes == 1 and len(self.faces) > 1:
            raise SimError("A single-module response reads one module; an array needs the "
                           "FEM array grid.")
        if own is not None and self.faces != tuple(own):
            raise SimError(f"The response reads modules {', '.join(own)}, not "
                           f"{', '.join(self.faces)}.")
        if not math.isfinite(stiffness_ratio) or not 0.2 <= stiffness_ratio <= 5.0:
            raise SimError(f"skin.stiffness_ratio = {stiffness_ratio!r} must be a finite "
                           "number in [0.2, 5] (1.0 = the skin as the FEM gives it).")
        if stiffness_ratio != 1.0 and self.axes > 1:
            raise SimError("skin.stiffness_ratio applies to a single-module skin (the bench "
                           "or the gripper); set it to 1.0 for a module array.")
        self.response = response
        self.viscoelastic = viscoelastic
        #: A skin whose Mooney-Rivlin moduli all scale by this factor: under the same
        #: indentation its displacement field, so its bulge and the module's voltage, are
        #: the FEM's (the law is homogeneous in its moduli), and its force scales.
        self.stiffness_ratio = float(stiffness_ratio)

    def load(self, *state: Any) -> Any:
        """The true load for ``state`` (indentation [m], then lateral x, y [m] and tilt x, y,
        twist z [rad] up to ``axes``): the normal force [N] (a float for a float) on a
        single-module response, (..., 3) forces or (..., 6) wrench on a grid."""
        if self.axes == 1:
            force = self.response.force_n(*state)
            return force if self.stiffness_ratio == 1.0 else force * self.stiffness_ratio
        return self.response.state(*state)[..., len(self.faces):]

    def module_voltages(self, *state: Any) -> np.ndarray:
        """Each module's noise-free voltage [V] for ``state``, shape (..., modules)."""
        if self.axes > 1:
            return self.response.voltages_v(*state)
        v = np.asarray(self.response.voltage_v(*state), dtype=float)[..., None]
        return v if self.faces else v[..., :0]

    def rated(self, t: np.ndarray, elastic: np.ndarray) -> np.ndarray:
        """The true load along a record from rest at times ``t`` (a regular grid), with the
        rate effect on each component; the elastic load itself without a model."""
        model = self.viscoelastic
        if model is None:
            return elastic
        if elastic.ndim == 1:
            return rate_force(model, t, elastic)
        return np.column_stack([filtered_rate_force(model, t, elastic[:, a])
                                for a in range(elastic.shape[1])])
