"""Module outputs -> joint angle and fingertip contact force: fitted on the FEM, applied per
sample.

A finger's modules read its skin: the one over the joint mostly its bend, the one at the
fingertip mostly a contact there, each a little of both (physics/bend.py). The FEM gives
every module's output on a grid of (bend angle, tip force); the fit turns that table around:

- **One module** (over the joint): its output against the angle with no contact is the
  calibration (monotone, interpolated). It cannot tell a contact from a bend, so the angle
  is read as if nothing touched the finger and the force is NaN.
- **Two modules** (joint, fingertip): each module's output is a polynomial in (angle,
  force) fitted on the grid (the degree that reads held-out grid points best); a sample's
  two outputs are solved for (angle, force) by Newton steps from an inverse polynomial's
  guess. Where the two outputs' gradients stand nearly parallel somewhere on the grid
  (``MIN_SEPARATION_SINE``), or the solve reads held-out grid points back worse than
  ``SEPARATION_ANGLE_RAD`` / ``SEPARATION_FORCE_N``, the layout cannot tell contact from
  bend and the calibration falls back to the joint module alone, saying so in
  ``separation``.

Outputs are taken against the straight finger without contact (the driver's tare), so the
FEM's outputs are shifted to read 0 there. Beyond the calibration's range the estimate is
NaN (``in_range`` False): the table says nothing there. With the joint module alone that is
an output past the curve's ends by more than ``OUTPUT_MARGIN_V``; with two, an angle past
the range by more than ``RANGE_MARGIN`` of its span.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from itertools import combinations_with_replacement
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from tactile_sensor.sensing.errors import CalibrationError

NAN = float("nan")
#: The joint module's name, and the fingertip's.
JOINT, TIP = "joint", "tip"
#: How far beyond the fitted angle range [fraction of its span] an estimate may still be
#: read (clamped to the range): noise on an output at a range end.
RANGE_MARGIN = 0.03
#: With the joint module alone, how far its output may pass the curve's ends and still be
#: read as the end's angle [V]: four times the paper's 13 mV noise (31.5 dB, Sec. III-C).
#: The curve flattens toward its top (the gap saturates), where an angle margin would let
#: every noise excursion read NaN.
OUTPUT_MARGIN_V = 0.05
#: Largest held-out error on the FEM grid with which two modules still separate bend and
#: contact (half the goals' 2 deg, and a twentieth of the 2 N contact).
SEPARATION_ANGLE_RAD = math.radians(1.0)
SEPARATION_FORCE_N = 0.1
#: Polynomial degrees tried for the two-module inverse, lowest first.
DEGREES = (2, 3, 4, 5, 6)
FILE_FORMAT = "tactile_sensor.bend_calibration/1"


def _monomials(degree: int) -> tuple[tuple[int, int], ...]:
    """Exponents (i, j) of x**i * y**j with i + j <= degree."""
    terms = [(0, 0)]
    for d in range(1, degree + 1):
        for combo in combinations_with_replacement((0, 1), d):
            terms.append((combo.count(0), combo.count(1)))
    return tuple(terms)


def _design(x: np.ndarray, y: np.ndarray, terms: Sequence[tuple[int, int]]) -> np.ndarray:
    return np.column_stack([x ** i * y ** j for i, j in terms])


@dataclass(frozen=True)
class BendEstimate:
    """One sample's estimate: angle [rad], tip force [N] (NaN where not observed), and
    whether the outputs fell inside the calibration's range."""

    angle_rad: float
    tip_force_n: float
    in_range: bool


@dataclass(frozen=True)
class BendCalibration:
    """The inverse map, for ``modules`` in the driver's channel order (joint first)."""

    modules: tuple[str, ...]
    angle_range_rad: tuple[float, float]
    force_range_n: tuple[float, float]
    # one module: the joint's output [V] (increasing) against the angle [rad]
    curve_output_v: tuple[float, ...] = ()
    curve_angle_rad: tuple[float, ...] = ()
    # two modules: a first guess, polynomial in (joint, tip) outputs / output_scale_v ...
    terms: tuple[tuple[int, int], ...] = ()
    angle_coef: tuple[float, ...] = ()
    force_coef: tuple[float, ...] = ()
    output_scale_v: float = 1.0
    # ... refined by Newton steps on the forward map: each module's output [V], polynomial
    # in (angle / angle span, force / force span)
    forward_terms: tuple[tuple[int, int], ...] = ()
    joint_coef: tuple[float, ...] = ()
    tip_coef: tuple[float, ...] = ()
    #: Held-out error of the fit on the FEM grid: angle [rad], force [N] (NaN: not fitted).
    fit_error: tuple[float, float] = (NAN, NAN)
    #: Why the force is NaN ('' when the layout separates bend and contact).
    separation: str = ""
    source: str = ""
    _coef: Any = field(default=None, init=False, repr=False, compare=False)

    @property
    def separates(self) -> bool:
        """Two modules that tell a contact from a bend: the force is observed."""
        return bool(self.angle_coef) and not self.separation

    @property
    def full_scale_force_n(self) -> float:
        """The most tip force it reports [N] (0 when it reports none)."""
        return self.force_range_n[1] if self.separates else 0.0

    # -- fit -----------------------------------------------------------------------------------

    @classmethod
    def fit(cls, modules: Sequence[str], angles_rad: npt.ArrayLike, forces_n: npt.ArrayLike,
            outputs_v: npt.ArrayLike, source: str = "fem-bend") -> BendCalibration:
        """From the FEM table: ``outputs_v[a, f, m]`` is module ``modules[m]``'s output at
        ``angles_rad[a]`` and ``forces_n[f]`` (both increasing from 0: straight, no
        contact). ``CalibrationError`` naming the problem when the table cannot be read
        back."""
        modules = tuple(modules)
        a = np.asarray(angles_rad, float)
        f = np.asarray(forces_n, float)
        out = np.asarray(outputs_v, float)
        if JOINT not in modules:
            raise CalibrationError(bend_layout_refusal(modules) or "")
        if len(modules) > 2 or len(set(modules)) != len(modules) or (
                len(modules) == 2 and TIP not in modules):
            raise CalibrationError(f"A bend calibration reads the joint module and at most "
                                   f"a fingertip one, not {', '.join(modules)}; name "
                                   "'joint' or 'joint,tip'.")
        if a.ndim != 1 or f.ndim != 1 or a.size < 3 or f.size < 1 or out.shape != (
                a.size, f.size, len(modules)):
            raise CalibrationError(f"The bend table has outputs of shape {out.shape} for "
                                   f"{a.size} angles, {f.size} forces and {len(modules)} "
                                   "modules; recompute it.")
        if not (np.all(np.isfinite(a)) and np.all(np.isfinite(f)) and np.all(np.isfinite(out))):
            raise CalibrationError("The bend table holds a non-finite value; recompute it.")
        if np.any(np.diff(a) <= 0) or (f.size > 1 and np.any(np.diff(f) <= 0)) or f[0] != 0:
            raise CalibrationError("The bend table's angles and forces must increase and its "
                                   "forces start at 0 N (no contact); recompute it.")
        order = [modules.index(JOINT)] + ([modules.index(TIP)] if TIP in modules else [])
        out = out[:, :, order] - out[0, 0, order]  # read against straight, no contact
        names = tuple(modules[i] for i in order)
        angle_range = (float(a[0]), float(a[-1]))
        force_range = (float(f[0]), float(f[-1]))
        curve_o, curve_a = _monotone_curve(a, out[:, 0, 0])
        base = dict(modules=names, angle_range_rad=angle_range, force_range_n=force_range,
                    curve_output_v=tuple(curve_o.tolist()),
                    curve_angle_rad=tuple(curve_a.tolist()), source=source)
        if len(names) == 1:
            return cls(**base, separation="one module cannot tell a fingertip contact from "
                                          "a bend: the angle is read as if nothing touched "
                                          "the finger")
        if f.size < 3:
            return cls(**base, separation="the bend table has no contact forces to fit")
        return cls(**base, **_two_module_fit(a, f, out))

    # -- apply ---------------------------------------------------------------------------------

    def estimate(self, outputs_v: Sequence[float]) -> BendEstimate:
        """The angle and force of one sample's outputs (``modules`` order, tared)."""
        if any(o != o for o in outputs_v):
            return BendEstimate(NAN, NAN, True)
        lo, hi = self.angle_range_rad
        margin = RANGE_MARGIN * (hi - lo)
        if self.separates:
            angle, force = self._poly(outputs_v[0], outputs_v[1])
        else:
            o = self.curve_output_v
            if not o or not o[0] - OUTPUT_MARGIN_V <= outputs_v[0] <= o[-1] + OUTPUT_MARGIN_V:
                return BendEstimate(NAN, NAN, False)
            angle = float(np.interp(outputs_v[0], o, self.curve_angle_rad))
            force = NAN
        if not lo - margin <= angle <= hi + margin:
            return BendEstimate(NAN, NAN, False)
        angle = min(max(angle, lo), hi)
        if force == force:
            f_lo, f_hi = self.force_range_n
            f_margin = RANGE_MARGIN * (f_hi - f_lo)
            if not f_lo - f_margin <= force <= f_hi + f_margin:
                return BendEstimate(angle, NAN, False)
            force = min(max(force, f_lo), f_hi)
        return BendEstimate(angle, force, True)

    def estimate_many(self, outputs_v: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``estimate`` over rows of outputs (n, modules): angles, forces, in-range flags."""
        rows = np.atleast_2d(np.asarray(outputs_v, float))
        found = [self.estimate(tuple(r.tolist())) for r in rows]
        return (np.array([e.angle_rad for e in found]), np.array([e.tip_force_n for e in found]),
                np.array([e.in_range for e in found]))

    def _poly(self, joint_v: float, tip_v: float) -> tuple[float, float]:
        """(angle, force): the inverse polynomial's guess, then Newton steps on the forward
        map (the inverse alone bends at the range's ends, where an output flattens)."""
        model = self._coef
        if model is None:
            model = _Forward(self)
            object.__setattr__(self, "_coef", model)
        return model.solve(joint_v, tip_v)

    # -- files ---------------------------------------------------------------------------------

    def to_dict(self) -> dict[str, Any]:
        return {"format": FILE_FORMAT, "modules": list(self.modules),
                "angle_range_rad": list(self.angle_range_rad),
                "force_range_n": list(self.force_range_n),
                "curve_output_v": list(self.curve_output_v),
                "curve_angle_rad": list(self.curve_angle_rad),
                "terms": [list(t) for t in self.terms], "angle_coef": list(self.angle_coef),
                "force_coef": list(self.force_coef), "output_scale_v": self.output_scale_v,
                "forward_terms": [list(t) for t in self.forward_terms],
                "joint_coef": list(self.joint_coef), "tip_coef": list(self.tip_coef),
                "fit_error": list(self.fit_error), "separation": self.separation,
                "source": self.source}

    @classmethod
    def from_dict(cls, data: dict[str, Any], source: str = "") -> BendCalibration:
        if not isinstance(data, dict) or data.get("format") != FILE_FORMAT:
            raise CalibrationError(f"{source or 'The data'} is not a bend calibration "
                                   f"(format {FILE_FORMAT}); write one with "
                                   "BendCalibration.to_file.")
        try:
            return cls(modules=tuple(data["modules"]),
                       angle_range_rad=tuple(data["angle_range_rad"]),  # type: ignore[arg-type]
                       force_range_n=tuple(data["force_range_n"]),  # type: ignore[arg-type]
                       curve_output_v=tuple(data["curve_output_v"]),
                       curve_angle_rad=tuple(data["curve_angle_rad"]),
                       terms=tuple(tuple(t) for t in data["terms"]),  # type: ignore[misc]
                       angle_coef=tuple(data["angle_coef"]),
                       force_coef=tuple(data["force_coef"]),
                       output_scale_v=float(data["output_scale_v"]),
                       forward_terms=tuple(tuple(t) for t in data["forward_terms"]),  # type: ignore[misc]
                       joint_coef=tuple(data["joint_coef"]), tip_coef=tuple(data["tip_coef"]),
                       fit_error=tuple(data["fit_error"]),  # type: ignore[arg-type]
                       separation=str(data["separation"]),
                       source=source or str(data["source"]))
        except (KeyError, TypeError, ValueError) as exc:
            raise CalibrationError(f"{source or 'The bend calibration'} lacks or garbles "
                                   f"{exc}; write it again with BendCalibration.to_file."
                                   ) from None

    def to_file(self, path: Path | str) -> None:
        Path(path).write_text(json.dumps(self.to_dict(), indent=1))

    @classmethod
    def from_file(cls, path: Path | str) -> BendCalibration:
        try:
            data = json.loads(Path(path).read_text())
        except (OSError, ValueError) as exc:
            raise CalibrationError(f"Cannot read the bend calibration {path} ({exc}); give "
                                   "the path of a file BendCalibration.to_file wrote.") from None
        return cls.from_dict(data, f"file:{path}")

    def describe(self) -> str:
        """One line for the log: what it reads and whether it separates contact."""
        lo, hi = (math.degrees(v) for v in self.angle_range_rad)
        what = (f"angle and tip force from {' and '.join(self.modules)} (held-out error "
                f"{math.degrees(self.fit_error[0]):.2f} deg, {self.fit_error[1]:.3f} N)"
                if self.separates else f"angle from the joint module; force NaN: "
                                       f"{self.separation}")
        return f"{what}, {lo:.0f}-{hi:.0f} deg, from {self.source}"


#: Newton steps at most per sample, and the step [fraction of the span] that ends them.
NEWTON_STEPS = 6
NEWTON_TOLERANCE = 1e-6
#: Two modules separate bend and contact where their outputs' gradients in (angle, force),
#: each over its span, stand at least this far from parallel (sine of their angle)
#: everywhere on the grid; nearer, a noise-sized output change moves the solution far.
MIN_SEPARATION_SINE = 0.1


def _poly_terms(x: float, y: float, terms: Sequence[tuple[int, int]]) -> list[float]:
    return [x ** i * y ** j for i, j in terms]


class _Forward:
    """The forward map's polynomials and its Newton solve, in plain floats (per sample)."""

    def __init__(self, cal: BendCalibration) -> None:
        self.cal = cal
        lo, hi = cal.angle_range_rad
        f_lo, f_hi = cal.force_range_n
        self.a_span, self.f_span = hi - lo, f_hi - f_lo
        self.terms = cal.forward_terms
        self.jc, self.tc = cal.joint_coef, cal.tip_coef
        # derivative terms: d/dx x^i y^j = i x^(i-1) y^j
        self.inverse = (cal.terms, cal.angle_coef, cal.force_coef, cal.output_scale_v)

    def _value_and_jacobian(self, x: float, y: float) -> tuple[float, float, float, float,
                                                               float, float]:
        oj = ot = djx = djy = dtx = dty = 0.0
        for (i, j), cj, ct in zip(self.terms, self.jc, self.tc, strict=True):
            m = x ** i * y ** j
            oj += cj * m
            ot += ct * m
            if i:
                dx = i * x ** (i - 1) * y ** j
                djx += cj * dx
                dtx += ct * dx
            if j:
                dy = j * x ** i * y ** (j - 1)
                djy += cj * dy
                dty += ct * dy
        return oj, ot, djx, djy, dtx, dty

    def solve(self, joint_v: float, tip_v: float) -> tuple[float, float]:
        terms, ca, cf, scale = self.inverse
        m = _poly_terms(joint_v / scale, tip_v / scale, terms)
        angle = sum(c * v for c, v in zip(ca, m, strict=True))
        force = sum(c * v for c, v in zip(cf, m, strict=True))
        lo = self.cal.angle_range_rad[0]
        f_lo = self.cal.force_range_n[0]
        x = min(max((angle - lo) / self.a_span, 0.0), 1.0)
        y = min(max((force - f_lo) / self.f_span, 0.0), 1.0)
        for _ in range(NEWTON_STEPS):
            oj, ot, a11, a12, a21, a22 = self._value_and_jacobian(x, y)
            det = a11 * a22 - a12 * a21
            if det == 0.0:
                break
            rj, rt = joint_v - oj, tip_v - ot
            dx = (a22 * rj - a12 * rt) / det
            dy = (a11 * rt - a21 * rj) / det
            # a step at most half the span: far outside, the polynomials mean nothing
            dx, dy = min(max(dx, -0.5), 0.5), min(max(dy, -0.5), 0.5)
            x, y = x + dx, y + dy
            if abs(dx) < NEWTON_TOLERANCE and abs(dy) < NEWTON_TOLERANCE:
                break
        return lo + x * self.a_span, f_lo + y * self.f_span


def _two_module_fit(a: np.ndarray, f: np.ndarray, out: np.ndarray) -> dict[str, Any]:
    """The two-module fields of a calibration from the (angle, force, module) table, joint
    first: forward polynomials, the inverse guess, its held-out error and the separation."""
    grid_a, grid_f = np.meshgrid(a, f, indexing="ij")
    xa = ((grid_a - a[0]) / (a[-1] - a[0])).ravel()
    yf = ((grid_f - f[0]) / (f[-1] - f[0])).ravel()
    oj, ot = out[:, :, 0].ravel(), out[:, :, 1].ravel()
    scale = float(max(np.abs(oj).max(), np.abs(ot).max(), 1e-12))
    ia, jf = np.meshgrid(np.arange(a.size), np.arange(f.size), indexing="ij")
    train = ((ia % 2 == 0) | (jf % 2 == 0)).ravel()
    best: tuple[float, int] | None = None
    for degree in DEGREES:  # forward: the lowest degree that reads held-out points best
        terms = _monomials(degree)
        if train.sum() < 2 * len(terms):
            break
        design = _design(xa[train], yf[train], terms)
        check = _design(xa[~train], yf[~train], terms)
        err = 0.0
        for o in (oj, ot):
            c = np.linalg.lstsq(design, o[train], rcond=None)[0]
            err = max(err, float(np.max(np.abs(check @ c - o[~train]))) if (~train).any()
                      else 0.0)
        if best is None or err < best[0] * 0.8:
            best = (err, degree)
    if best is None:
        return {"separation": "the bend table is too small to fit two modules"}
    forward = _monomials(best[1])
    full = _design(xa, yf, forward)
    jc = np.linalg.lstsq(full, oj, rcond=None)[0]
    tc = np.linalg.lstsq(full, ot, rcond=None)[0]
    inverse = _monomials(3)
    guess = _design(oj / scale, ot / scale, inverse)
    ca = np.linalg.lstsq(guess, grid_a.ravel(), rcond=None)[0]
    cf = np.linalg.lstsq(guess, grid_f.ravel(), rcond=None)[0]
    fields: dict[str, Any] = dict(
        terms=inverse, angle_coef=tuple(ca.tolist()), force_coef=tuple(cf.tolist()),
        output_scale_v=scale, forward_terms=forward, joint_coef=tuple(jc.tolist()),
        tip_coef=tuple(tc.tolist()))
    # how far from parallel the two gradients stand, over the grid
    model = _Forward(BendCalibration(("joint", "tip"), (float(a[0]), float(a[-1])),
                                     (float(f[0]), float(f[-1])), **fields))
    sines = []
    for x, y in zip(xa.tolist(), yf.tolist(), strict=True):
        _, _, a11, a12, a21, a22 = model._value_and_jacobian(x, y)
        norm = math.hypot(a11, a12) * math.hypot(a21, a22)
        sines.append(abs(a11 * a22 - a12 * a21) / norm if norm > 0 else 0.0)
    sine = min(sines)
    # held out: the whole estimate (guess and Newton) on the points the forward fit skipped
    err_a = err_f = 0.0
    check = ~train if (~train).any() else train
    for o1, o2, ta, tf in zip(oj[check].tolist(), ot[check].tolist(),
                              grid_a.ravel()[check].tolist(), grid_f.ravel()[check].tolist(),
                              strict=True):
        ea, ef = model.solve(o1, o2)
        err_a, err_f = max(err_a, abs(ea - ta)), max(err_f, abs(ef - tf))
    fields["fit_error"] = (err_a, err_f)
    if sine < MIN_SEPARATION_SINE or err_a > SEPARATION_ANGLE_RAD or \
            err_f > SEPARATION_FORCE_N:
        fields["separation"] = (
            f"the joint and fingertip modules vary alike with bend and contact (their "
            f"gradients stand {math.degrees(math.asin(min(sine, 1.0))):.1f} deg from "
            f"parallel at worst; the fit reads the FEM's own table back within "
            f"{math.degrees(err_a):.2f} deg and {err_f:.3f} N): the angle is read as if "
            "nothing touched the finger")
    return fields


def _monotone_curve(angles: np.ndarray, outputs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The joint output against the angle, increasing in output: the FEM's points, oriented
    so the output rises; ``CalibrationError`` when the output does not move one way."""
    d = np.diff(outputs)
    if np.all(d > 0):
        return outputs, angles
    if np.all(d < 0):
        return outputs[::-1], angles[::-1]
    raise CalibrationError("The joint module's output does not change one way with the bend "
                           "(it turns back within the angle range), so one output reads two "
                           "angles; narrow the bend table's angle range or move the module.")


def bend_layout_refusal(modules: Sequence[str]) -> str | None:
    """Why a bend layout cannot read the joint angle, in one sentence (None: it can)."""
    if JOINT not in modules:
        named = ", ".join(modules) or "none"
        return (f"A bend configuration needs a module over the joint to read its angle, and "
                f"its modules are {named}; add 'joint' (e.g. modules 'joint' or "
                "'joint,tip').")
    return None
