"""Proprioception: a finger's joint angle read by modules clipped onto its skin.

The paper (Discussion) suggests that "measuring skin deformations near the joints could
enable estimation of joint angles" and warns that its boneless finger showed no skin
deformation under contact. This module is that chain for a tendon-driven finger whose two
rigid phalanges meet at a soft silicone joint (``BendGeometry``; the structure of the SDM
Hand's fingers, Dollar and Howe, IJRR 29(5), 2010: rigid links cast in one piece with
elastomer joints, a cable through them). The FEM (``fem/finger.py``) gives, over a grid of
joint angle and fingertip contact force, each module's photoreflector-skin gap and the
tendon tension that holds the angle; the optics (``optics.py``) turn a gap into the
module's voltage and the paper's inverted output, exactly as for the force module.

For the world, the driver and the bringup (all pure, no rclpy)::

    from tactile_sensor.physics.bend import (
        BendGeometry, BendModule, BendResponse, BendInputError, DEFAULT_MODULES,
        load_or_compute_response)

    response = load_or_compute_response(BendGeometry(), DEFAULT_MODULES)  # cached
    response.angle_range_rad            # (0, max) the calibration covers [rad]
    response.force_range_n              # (0, max) fingertip contact force [N]
    response.gap_m(angle, force)        # (..., n_modules) photoreflector-skin gap [m]
    response.output_v(angle, force)     # (..., n_modules) module output [V] (inverted)
    response.voltage_v(angle, force)    # (..., n_modules) photoreflector voltage [V]
    response.output_jacobian(angle, force)  # (..., n_modules, 2) d output / d(angle, force)
    response.tension_n(angle, force)    # tendon tension that holds the angle [N]
    response.angle_from_tension(tension, force)  # the drive: tension [N] -> angle [rad]
    check_tension_profile(values)       # refuses a non-finite or negative tension

Angles are the joint's flexion [rad], positive curling the tip toward the palm (REP 103:
a positive rotation about the joint's axis); 0 is the straight finger. Arrays broadcast;
an angle or force outside the calibrated range gives NaN (never an extrapolation). The
interpolation is a bicubic spline of the FEM grid: smooth in both arguments, so a Newton
or least-squares inverse of the outputs converges.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from .errors import PhysicsError
from .optics import Photoreflector
from .params import PhysicsParams

Progress = Callable[[float, str], None]

#: Bump when the finger model changes its results, so old cache entries are ignored.
BEND_MODEL_VERSION = 1
#: Module faces a clip can carry its window on (the palm is the grasp surface and the
#: tendon's path, so the clip is open there).
BEND_FACES = ("dorsal", "lateral")
_SILICONE = PhysicsParams()


class BendInputError(PhysicsError, ValueError):
    """A drive profile or a query the finger model cannot take (one sentence: cause, fix)."""


def _field(default: Any, unit: str, doc: str) -> Any:
    return field(default=default, metadata={"unit": unit, "doc": doc})


def _check_number(what: str, value: Any, unit: str, *, positive: bool) -> None:
    """Refuse a parameter that is no finite number (or, ``positive``, not above 0) in one
    sentence naming it and its unit; the finger and its modules share the rule."""
    if isinstance(value, bool) or not isinstance(value, int | float) or \
            not math.isfinite(value):
        raise PhysicsError(f"{what} is {value!r}; give a finite number in {unit}.")
    if positive and value <= 0:
        raise PhysicsError(f"{what} is {value!r}; give a positive number in {unit}.")


@dataclass(frozen=True)
class BendGeometry:
    """The finger: two rigid phalanges joined by a soft silicone joint, covered by skin.

    Axes of the straight finger: z along it from the joint's proximal end (the proximal
    phalanx at z < 0), x through it toward the palm, y across it. Structure: the SDM Hand's
    finger (Dollar and Howe, IJRR 29(5), 2010; the Soft Robotics Toolkit's "SDM Fingers"
    build), with the paper's Ecoflex 00-30 (Table I) for the joint and skin and the paper's
    22 mm body width, so the paper's module clips across it. The other dimensions are
    assumptions, named as such: the 90 deg the issue asks for needs a joint long enough
    that its palmar side is not crushed (palmar strain ~ angle x half thickness / length).
    """

    thickness: float = _field(0.016, "m", "finger thickness palm to back, the bending "
                              "direction (assumption: an adult index finger's ~16 mm)")
    width: float = _field(0.022, "m", "finger width across, where the module clips (paper "
                          "Sec. II-C: the 22 mm skin body the module fits)")
    proximal_length: float = _field(0.015, "m", "skin-covered length of the proximal "
                                    "phalanx modelled before the joint (its cut is fixed)")
    joint_length: float = _field(0.030, "m", "length of the soft joint between the bones "
                                 "(assumption: palmar strain ~40 % at 90 deg)")
    distal_length: float = _field(0.025, "m", "distal phalanx from the joint to the tip "
                                  "(assumption: an adult index finger's distal segment)")
    skin_thickness: float = _field(0.003, "m", "silicone over the bone cores (assumption)")
    tendon_clearance: float = _field(0.001, "m", "tendon's guide and anchor eyelets above "
                                     "the palmar skin (assumption)")
    tendon_guide: float = _field(0.004, "m", "guide's distance before the joint, on the "
                                 "proximal phalanx")
    tendon_anchor: float = _field(0.004, "m", "anchor's distance past the joint, on the "
                                  "distal phalanx")
    contact_from_tip: float = _field(0.006, "m", "fingertip contact patch centre's distance "
                                     "from the tip, on the palmar face")
    contact_length: float = _field(0.006, "m", "contact patch length along the finger (the "
                                   "whole width across it)")
    c10: float = _field(_SILICONE.c10, "Pa", "Mooney-Rivlin C10 (paper Table I)")
    c01: float = _field(_SILICONE.c01, "Pa", "Mooney-Rivlin C01 (paper Table I)")
    bulk_ratio: float = _field(100.0, "1", "bulk / shear modulus of the volumetric "
                               "penalty (Poisson's ratio 0.495; the skin block's 1000 "
                               "stalls Newton under the joint's large rotations, and "
                               "docs/bend.md measures what 100 changes)")
    mesh_size: float = _field(0.004, "m", "largest element edge (coarse: the convergence "
                              "check halves it, docs/bend.md)")
    source: str = _field("SDM Hand finger structure (Dollar & Howe, IJRR 29(5) 2010); "
                         "paper Table I silicone and Sec. II-C width", "-",
                         "where the geometry comes from")

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            if f.name != "source":
                _check_number(f"Finger parameter {f.name!r}", getattr(self, f.name),
                              f.metadata["unit"], positive=f.name != "c10")
        if 2 * self.skin_thickness >= min(self.thickness, self.width):
            raise PhysicsError("The skin is as thick as the finger leaves no bone; give "
                               "skin_thickness below half the thickness and width.")
        if self.contact_from_tip + self.contact_length / 2 > self.distal_length:
            raise PhysicsError("The fingertip contact patch runs past the distal phalanx; "
                               "lower contact_from_tip or contact_length.")
        if self.c10 + self.c01 <= 0:
            raise PhysicsError("C10 + C01 must be positive (the initial shear modulus); "
                               "use the paper's Table I values.")

    @property
    def tip_position(self) -> float:
        """Arc position of the fingertip [m] (the joint's proximal end is 0)."""
        return self.joint_length + self.distal_length

    def to_dict(self) -> dict[str, Any]:
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}


@dataclass(frozen=True)
class BendModule:
    """A module clipped onto the finger: a rigid U-clip around the dorsal and lateral faces
    over ``clip_length_m``, open on the palm, with one window on ``face``.

    ``arc_position_m``: where the photoreflector's axis meets the skin, along the
    straight finger from the joint's proximal end [m] (negative: over the proximal
    phalanx; past ``joint_length``: over the distal one). ``clip_position_m``: the clip's
    centre (default: around the window, as the paper's module sits in its skin); a clip
    beside the window holds the photoreflector out over free skin, e.g. a clip on the
    proximal phalanx looking over the joint. ``standoff_m``: photoreflector-skin distance
    at rest (paper: ~2 mm). ``window_offset_m``: on the lateral face, the window centre's
    offset toward the palm [m] (a dorsal window is centred: the finger is symmetric).
    """

    arc_position_m: float
    face: str = "dorsal"
    standoff_m: float = 0.002
    window_offset_m: float = 0.0
    clip_position_m: float | None = None
    clip_length_m: float = 0.008
    window_length_m: float = 0.004
    window_width_m: float = 0.006

    @property
    def clip_centre_m(self) -> float:
        """The clip's centre along the finger [m]."""
        return self.arc_position_m if self.clip_position_m is None else self.clip_position_m

    def __post_init__(self) -> None:
        if self.face not in BEND_FACES:
            raise PhysicsError(f"Module face {self.face!r} is not one a clip can carry; use "
                               f"{' or '.join(BEND_FACES)} (the palm is left free).")
        for name in ("arc_position_m", "standoff_m", "window_offset_m", "clip_length_m",
                     "window_length_m", "window_width_m", "clip_position_m"):
            if name != "clip_position_m" or self.clip_position_m is not None:
                _check_number(f"Module {name!r}", getattr(self, name), "m",
                              positive=name in ("standoff_m", "clip_length_m",
                                                "window_length_m", "window_width_m"))
        if self.window_length_m >= self.clip_length_m:
            raise PhysicsError("The module's window is as long as its clip; give "
                               "window_length_m below clip_length_m.")
        if self.face == "dorsal" and self.window_offset_m != 0:
            raise PhysicsError("A dorsal window sits on the finger's centre line; give "
                               "window_offset_m 0 or use the lateral face.")

    def check(self, geometry: BendGeometry) -> None:
        """Refuse a clip off the finger or a window off its face (one sentence)."""
        low = -geometry.proximal_length + geometry.skin_thickness
        high = geometry.tip_position - geometry.skin_thickness
        if not low + self.clip_length_m / 2 <= self.clip_centre_m <= \
                high - self.clip_length_m / 2:
            raise PhysicsError(
                f"A module clipped at {self.clip_centre_m * 1e3:.1f} mm is off the "
                f"modelled finger; clip it between {(low + self.clip_length_m / 2) * 1e3:.1f}"
                f" and {(high - self.clip_length_m / 2) * 1e3:.1f} mm.")
        if not low + self.window_length_m / 2 <= self.arc_position_m <= \
                high - self.window_length_m / 2:
            raise PhysicsError(f"A module looking at {self.arc_position_m * 1e3:.1f} mm looks "
                               "off the modelled finger; move its window onto it.")
        across = geometry.thickness / 2 if self.face == "lateral" else geometry.width / 2
        if abs(self.window_offset_m) + self.window_width_m / 2 > across + 1e-12:
            raise PhysicsError("The module's window runs off its face; narrow it or move "
                               "window_offset_m toward the face's centre.")

    @property
    def label(self) -> str:
        clip = "" if self.clip_position_m is None else \
            f" (clip {self.clip_position_m * 1e3:.1f} mm)"
        return f"{self.face}@{self.arc_position_m * 1e3:.1f}mm{clip}"

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


def default_modules(geometry: BendGeometry | None = None) -> tuple[BendModule, BendModule]:
    """The two-module layout: one clipped on the proximal phalanx whose photoreflector
    looks at the dorsal skin 5 mm into the joint (a clip around the bending skin rides
    with it and reads ~30 um over 90 deg; docs/bend.md), and one at the fingertip (lateral
    window near the palm, where the pad's compression bulges it; it rides on the bone and
    reads no bend)."""
    g = geometry or BendGeometry()
    joint = BendModule(0.005, "dorsal", clip_position_m=-0.005)
    # the clip ends 1 mm short of the contact patch: a clip edge on the patch's edge
    # folds the pad's corner under the load and the FEM stalls past ~60 deg
    clip = 0.008
    tip = BendModule(g.tip_position - g.contact_from_tip - g.contact_length / 2 - 0.001
                     - clip / 2, "lateral", window_offset_m=g.thickness / 2 - 0.004,
                     clip_length_m=clip)
    return joint, tip


DEFAULT_MODULES = default_modules()
#: The calibration grid: the issue's 0..90 deg with a margin, and the tip forces the
#: two-module FEM solves over all of it (at 1.1 N it stalls past ~65 deg, at 2.2 N past
#: ~55 deg, in the fingertip clip; docs/bend.md). Past
#: ~95 deg the palmar skin at the bone corners folds and Newton stalls).
DEFAULT_ANGLES = tuple(float(v) for v in np.linspace(0.0, 1.65, 12))
DEFAULT_FORCES = (0.0, 0.25, 0.5)
#: Largest joint-angle increment of one solve [rad] (a longer step is split).
MAX_STEP_RAD = 0.05


def check_tension_profile(values: npt.ArrayLike, what: str = "tendon tension") -> np.ndarray:
    """The profile as floats [N], or one sentence refusing a non-finite or negative value."""
    v = np.asarray(values, dtype=float)
    bad = ~np.isfinite(v) | (v < 0)
    if np.any(bad):
        first = float(v[bad].ravel()[0])
        raise BendInputError(f"A {what} profile holds {first!r} N; give finite values >= 0 "
                             "(a tendon can only pull).")
    return v


def response_digest(geometry: BendGeometry, modules: Sequence[BendModule],
                    angles: Sequence[float], forces: Sequence[float]) -> str:
    """Hash of everything that changes the FEM grid (pigment and supply do not)."""
    data = {"version": BEND_MODEL_VERSION,
            "geometry": {k: v for k, v in geometry.to_dict().items() if k != "source"},
            "modules": [m.to_dict() for m in modules], "angles": list(angles),
            "forces": list(forces)}
    return hashlib.sha256(json.dumps(data, sort_keys=True).encode()).hexdigest()[:16]


def finger_mesh(geometry: BendGeometry, modules: Sequence[BendModule]) -> Any:
    """The solver's description of this finger and its clips."""
    from .fem.finger import FingerMesh

    g = geometry
    for m in modules:
        m.check(g)
    return FingerMesh(
        thickness=g.thickness, width=g.width, proximal_length=g.proximal_length,
        joint_length=g.joint_length, distal_length=g.distal_length,
        skin_thickness=g.skin_thickness, c10=g.c10, c01=g.c01, bulk_ratio=g.bulk_ratio,
        mesh_size=g.mesh_size, tendon_height=g.thickness / 2 + g.tendon_clearance,
        tendon_guide_z=-g.tendon_guide, tendon_anchor_z=g.joint_length + g.tendon_anchor,
        contact_z=g.tip_position - g.contact_from_tip, contact_length=g.contact_length,
        modules=tuple((m.arc_position_m, m.face, m.window_offset_m, m.clip_centre_m,
                       m.clip_length_m, m.window_length_m, m.window_width_m)
                      for m in modules))


def sweep_task(geometry: dict[str, Any], modules: list[dict[str, Any]], angles: list[float],
               force: float, progress: Progress | None) -> dict[str, Any]:
    """One tip force's angle sweep, as plain data (a batch task: picklable arguments)."""
    from .fem.finger import FingerModel

    g = BendGeometry(**geometry)
    mods = [BendModule(**m) for m in modules]
    model = FingerModel(finger_mesh(g, mods))
    sweep = model.sweep(np.asarray(angles), force, progress, max_step=MAX_STEP_RAD)
    return {"tension_n": sweep.tension_n.tolist(), "bulge_m": sweep.bulge_m.tolist(),
            "nodes": sweep.nodes, "seconds": sweep.seconds}


class BendResponse:
    """Gap, voltage, output and tendon tension of each module over (angle, tip force),
    interpolated from the FEM grid by bicubic splines (NaN outside the grid)."""

    def __init__(self, geometry: BendGeometry, modules: Sequence[BendModule],
                 angles_rad: npt.ArrayLike, forces_n: npt.ArrayLike, gap_m: npt.ArrayLike,
                 tension_n: npt.ArrayLike, *, nodes: int = 0, seconds: float = 0.0,
                 pigment_white: float = _SILICONE.pigment_white,
                 supply_voltage: float = _SILICONE.supply_voltage) -> None:
        from scipy.interpolate import RectBivariateSpline

        self.geometry = geometry
        self.modules = tuple(modules)
        self.angles_rad = np.asarray(angles_rad, dtype=float)
        self.forces_n = np.asarray(forces_n, dtype=float)
        self.grid_gap_m = np.asarray(gap_m, dtype=float)          # (angles, forces, modules)
        self.grid_tension_n = np.asarray(tension_n, dtype=float)  # (angles, forces)
        self.nodes, self.seconds = int(nodes), float(seconds)
        na, nf = self.angles_rad.size, self.forces_n.size
        if self.grid_gap_m.shape != (na, nf, len(self.modules)) or \
                self.grid_tension_n.shape != (na, nf) or na < 4 or nf < 2 or \
                np.any(np.diff(self.angles_rad) <= 0) or np.any(np.diff(self.forces_n) <= 0) \
                or not np.all(np.isfinite(self.grid_gap_m)) or \
                not np.all(np.isfinite(self.grid_tension_n)):
            raise PhysicsError("A bend response's grid is malformed (shapes, order or "
                               "non-finite values); recompute it.")
        self.optics = Photoreflector(pigment_white, supply_voltage)
        ky = min(3, nf - 1)
        self._gap = [RectBivariateSpline(self.angles_rad, self.forces_n,
                                         self.grid_gap_m[:, :, k], kx=3, ky=ky, s=0)
                     for k in range(len(self.modules))]
        self._tension = RectBivariateSpline(self.angles_rad, self.forces_n,
                                            self.grid_tension_n, kx=3, ky=ky, s=0)
        self._rest_v = np.array([float(self.optics.voltage(m.standoff_m))
                                 for m in self.modules])

    # -- ranges -------------------------------------------------------------------------
    @property
    def angle_range_rad(self) -> tuple[float, float]:
        """The calibrated joint angles [rad]."""
        return float(self.angles_rad[0]), float(self.angles_rad[-1])

    @property
    def force_range_n(self) -> tuple[float, float]:
        """The calibrated fingertip contact forces [N]."""
        return float(self.forces_n[0]), float(self.forces_n[-1])

    @property
    def labels(self) -> tuple[str, ...]:
        return tuple(m.label for m in self.modules)

    # -- queries ------------------------------------------------------------------------
    def _grid(self, angle_rad: npt.ArrayLike, tip_force_n: npt.ArrayLike
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        a, f = np.broadcast_arrays(np.asarray(angle_rad, dtype=float),
                                   np.asarray(tip_force_n, dtype=float))
        tol = 1e-12
        inside = np.isfinite(a) & np.isfinite(f) & \
            (a >= self.angles_rad[0] - tol) & (a <= self.angles_rad[-1] + tol) & \
            (f >= self.forces_n[0] - tol) & (f <= self.forces_n[-1] + tol)
        ac = np.clip(np.where(inside, a, 0.0), self.angles_rad[0], self.angles_rad[-1])
        fc = np.clip(np.where(inside, f, 0.0), self.forces_n[0], self.forces_n[-1])
        return ac, fc, inside

    def _eval(self, spline: Any, a: np.ndarray, f: np.ndarray, da: int = 0,
              df: int = 0) -> np.ndarray:
        return spline.ev(a.ravel(), f.ravel(), dx=da, dy=df).reshape(a.shape)

    def _gaps(self, a: np.ndarray, f: np.ndarray, da: int = 0, df: int = 0) -> np.ndarray:
        """Each module's gap spline (or its derivative) on the clipped grid point, stacked
        on a last axis."""
        return np.stack([self._eval(s, a, f, da, df) for s in self._gap], axis=-1)

    def gap_m(self, angle_rad: npt.ArrayLike, tip_force_n: npt.ArrayLike = 0.0) -> np.ndarray:
        """Photoreflector-skin distance of each module [m], shape (..., n_modules)."""
        a, f, inside = self._grid(angle_rad, tip_force_n)
        return np.where(inside[..., None], self._gaps(a, f), np.nan)

    def voltage_v(self, angle_rad: npt.ArrayLike, tip_force_n: npt.ArrayLike = 0.0
                  ) -> np.ndarray:
        """Each module's photoreflector voltage [V] (a gap closed to 0 reads as contact)."""
        gap = self.gap_m(angle_rad, tip_force_n)
        ok = np.isfinite(gap)
        v = self.optics.voltage(np.where(ok, np.maximum(gap, 0.0), 0.0))
        return np.where(ok, v, np.nan)

    def output_v(self, angle_rad: npt.ArrayLike, tip_force_n: npt.ArrayLike = 0.0
                 ) -> np.ndarray:
        """Each module's output [V]: the paper's inverted -(V - V_rest), V_rest at the
        standoff, so it rises as the skin comes closer."""
        return self._rest_v - self.voltage_v(angle_rad, tip_force_n)

    def output_jacobian(self, angle_rad: npt.ArrayLike, tip_force_n: npt.ArrayLike = 0.0
                        ) -> np.ndarray:
        """d output / d(angle [rad], force [N]) of each module, shape (..., n_modules, 2)
        [V/rad, V/N], for a Newton inverse."""
        a, f, inside = self._grid(angle_rad, tip_force_n)
        slope = self.optics.slope(np.maximum(self._gaps(a, f), 1e-6))    # dV/dx
        jac = np.stack([-slope * self._gaps(a, f, da=1), -slope * self._gaps(a, f, df=1)],
                       axis=-1)
        return np.where(inside[..., None, None], jac, np.nan)

    def tension_n(self, angle_rad: npt.ArrayLike, tip_force_n: npt.ArrayLike = 0.0
                  ) -> np.ndarray:
        """Tendon tension that holds the angle against the skin and the contact [N]."""
        a, f, inside = self._grid(angle_rad, tip_force_n)
        # a tendon only pulls: the spline's rounding below 0 at the straight finger is 0
        return np.where(inside, np.maximum(self._eval(self._tension, a, f), 0.0), np.nan)

    def angle_from_tension(self, tension_n: npt.ArrayLike, tip_force_n: npt.ArrayLike = 0.0
                           ) -> np.ndarray:
        """The drive: the joint angle a tendon tension holds [rad] (NaN beyond the
        calibrated range). A non-finite or negative tension is refused in one sentence."""
        t = check_tension_profile(tension_n)
        t, f = np.broadcast_arrays(t, np.asarray(tip_force_n, dtype=float))
        fine = np.linspace(self.angles_rad[0], self.angles_rad[-1], 721)
        out = np.full(t.shape, np.nan)
        for idx in np.ndindex(t.shape):
            force = float(f[idx])
            if not (np.isfinite(force) and self.forces_n[0] <= force <= self.forces_n[-1]):
                continue
            curve = self._tension.ev(fine, np.full_like(fine, force))
            # the reachable branch: tension rising from the straight finger
            rising = np.concatenate([[True], np.diff(curve) > 0])
            stop = int(np.argmin(rising)) if not rising.all() else fine.size
            branch_t, branch_a = curve[:stop], fine[:stop]
            value = float(t[idx])
            # the spline's rounding is not monotone to the last bit: a tension read just
            # inside the top angle can exceed the curve's top value by a few ulps
            slack = 1e-9 * max(1.0, abs(float(branch_t[-1])))
            if branch_t[0] - 1e-9 <= value <= branch_t[-1] + slack:
                out[idx] = float(np.interp(value, branch_t, branch_a))
            elif value < branch_t[0]:
                out[idx] = float(branch_a[0])    # slack: the contact holds it straight
        return out

    # -- storage --------------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        return {"geometry": self.geometry.to_dict(),
                "modules": [m.to_dict() for m in self.modules],
                "angles_rad": self.angles_rad.tolist(), "forces_n": self.forces_n.tolist(),
                "gap_m": self.grid_gap_m.tolist(), "tension_n": self.grid_tension_n.tolist(),
                "nodes": self.nodes, "seconds": self.seconds,
                "digest": response_digest(self.geometry, self.modules,
                                          self.angles_rad.tolist(), self.forces_n.tolist())}

    @classmethod
    def from_dict(cls, data: Any) -> BendResponse:
        try:
            return cls(BendGeometry(**data["geometry"]),
                       [BendModule(**m) for m in data["modules"]], data["angles_rad"],
                       data["forces_n"], data["gap_m"], data["tension_n"],
                       nodes=int(data["nodes"]), seconds=float(data["seconds"]))
        except (KeyError, TypeError, ValueError) as exc:
            raise PhysicsError(f"A bend response file lacks or mangles {exc}; recompute "
                               "it.") from None


def compute_response(geometry: BendGeometry, modules: Sequence[BendModule],
                     angles: Sequence[float] = DEFAULT_ANGLES,
                     forces: Sequence[float] = DEFAULT_FORCES, *,
                     progress: Progress | None = None, workers: int = 1,
                     scheduler: str | None = None) -> BendResponse:
    """Solve the grid: one angle sweep per tip force, as batch tasks (``batch.run``)."""
    from .batch import run

    if not modules:
        raise PhysicsError("A bend response needs at least one module; clip one on.")
    for m in modules:
        m.check(geometry)
    args = [(geometry.to_dict(), [m.to_dict() for m in modules], list(angles), float(f))
            for f in forces]
    tension = np.zeros((len(angles), len(forces)))
    gap = np.zeros((len(angles), len(forces), len(modules)))
    nodes, seconds = 0, 0.0
    standoff = np.array([m.standoff_m for m in modules])
    for result in run(sweep_task, args, scheduler=scheduler, workers=workers,
                      progress=progress, label="tip force"):
        if result.error is not None:
            if isinstance(result.error, PhysicsError):
                raise result.error
            raise PhysicsError(f"The finger's FEM failed ({result.error}); rerun, or report "
                               "it with the geometry.") from None
        j = result.index
        tension[:, j] = result.value["tension_n"]
        gap[:, j, :] = standoff - np.asarray(result.value["bulge_m"])
        nodes, seconds = result.value["nodes"], seconds + result.value["seconds"]
    return BendResponse(geometry, modules, angles, forces, gap, tension, nodes=nodes,
                        seconds=seconds)


def response_path(geometry: BendGeometry, modules: Sequence[BendModule],
                  angles: Sequence[float] = DEFAULT_ANGLES,
                  forces: Sequence[float] = DEFAULT_FORCES,
                  cache_dir: Path | None = None) -> Path:
    from .prediction import cache_file

    return cache_file(cache_dir, f"bend-{response_digest(geometry, modules, angles, forces)}"
                      ".json")


def cached_response(geometry: BendGeometry, modules: Sequence[BendModule],
                    angles: Sequence[float] = DEFAULT_ANGLES,
                    forces: Sequence[float] = DEFAULT_FORCES,
                    cache_dir: Path | None = None) -> BendResponse | None:
    """The cached response, or None (missing or damaged: recompute it)."""
    from .prediction import read_cache

    return read_cache(response_path(geometry, modules, angles, forces, cache_dir),
                      BendResponse.from_dict)


def load_or_compute_response(geometry: BendGeometry | None = None,
                             modules: Sequence[BendModule] | None = None,
                             angles: Sequence[float] = DEFAULT_ANGLES,
                             forces: Sequence[float] = DEFAULT_FORCES, *,
                             cache_dir: Path | None = None, progress: Progress | None = None,
                             workers: int = 1) -> BendResponse:
    """The cached response for this finger and layout, solving and caching it on a miss
    (one process solves; others wait for its file, as for the prediction curve)."""
    from .prediction import load_or_compute, write_cache

    g = geometry or BendGeometry()
    mods = tuple(modules) if modules is not None else default_modules(g)
    path = response_path(g, mods, angles, forces, cache_dir)
    return load_or_compute(
        path, lambda: cached_response(g, mods, angles, forces, cache_dir),
        lambda: compute_response(g, mods, angles, forces, progress=progress,
                                 workers=workers),
        lambda r: write_cache(path, r.to_dict()), progress,
        f"computing the finger's FEM grid (cache miss: {path.name})")
