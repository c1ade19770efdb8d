"""Module outputs [V] of an array -> wrench (Fx, Fy, Fz, Tx, Ty, Tz) by fitted polynomials.

The physics (docs/array.md): a lateral probe displacement bulges the face it moves toward and
draws in the opposite one, so opposite modules' difference reads shear and their sum normal
force. The polynomial's variables are therefore symmetry-adapted features, ``feature_matrix``
@ (outputs / ``output_scale_v``): the modules are grouped into orbits under the mirrors about
x = 0 and y = 0 that map the layout onto itself (``right`` <-> ``left`` keeps the offset
along y, ``front@c`` -> ``front@-c``), and each orbit gives one feature per mirror parity
(centred faces: per opposite pair their sum and their difference, positive face minus
negative). A mirror flips the features odd under it and, of the wrench, Fx and Ty (x = 0)
or Fy and Tx (y = 0), Tz under both; so each component keeps only the monomials of its own
parity. A full polynomial in the raw outputs fitted the grid's held-out points as well but
was wrong by up to 30 N at a shear direction between the grid's (its extra terms are free
off the grid's directions); the symmetric one is not. Scaling by the fit data's largest
output keeps the least squares well conditioned.

Modules are labels as physics spells them: a face, or ``FACE@OFFSET`` with the window's
offset [m] along the face (along +x on front/back, +y on left/right). Force convention: the
probe's force on the skin along +x, +y and -z (pressing positive), torque [N m] the probe's
on the skin about +x, +y, +z, as the FEM reports them; faces as in physics (front +y, back
-y, left -x, right +x). ``observed`` lists the components the layout can tell apart
(``physics.observability.wrench_metrics``); the others evaluate to NaN. Beyond the
fitted outputs the polynomial extrapolates; ``in_range`` tells the caller.

File (JSON), version 2: ``{"format": "tactile_sensor/array_calibration", "version": 2,
"faces": [...], "feature_matrix": [[...], ...], "degree": d, "output_scale_v": s, "terms":
[[e_1, ..., e_m], ...], "force_x_n": [...], "force_y_n": [...], "force_z_n": [...],
"torque_x_nm": [...], "torque_y_nm": [...], "torque_z_nm": [...], "observed": ["fx", ...],
"force_slow_x_n": [...], "force_slow_y_n": [...], "force_slow_z_n": [...],
"output_max_v": [...], "source": "...", "fit": {...}}``: with z = feature_matrix @ (o / s),
component_k = sum_t coef_k[t] prod_j z_j ** terms[t][j]. Version 1 (forces only, no
``torque_*`` nor ``observed``) still loads, observing fx, fy, fz.

The force's slow part (``force_slow_*``, optional, with the torques): the force a tilt or a
twist adds, which the press-and-shear grid that fits the forces never saw. A tilt about y
pushes the skin along x as a shear does, and only the torque's few millivolts tell the two
apart, so this part is fitted like the torques (their degree, their noise) on what the
force polynomial leaves of the wrench paths' forces; a driver low-passes it with the torques
and adds it to the force. ``wrench``/``wrenches`` return the static sum.
"""

from __future__ import annotations

import itertools
import json
import math
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from tactile_sensor.sensing.calibration import file_source, read_json_file
from tactile_sensor.sensing.errors import CalibrationError
from tactile_sensor.sensing.press_scaled_terms import fit_press_scaled, press_groups

FILE_FORMAT = "tactile_sensor/array_calibration"
FILE_VERSION = 2
READ_VERSIONS = (1, 2)
FACES = ("front", "back", "left", "right")
AXES = ("force_x_n", "force_y_n", "force_z_n")
TORQUE_AXES = ("torque_x_nm", "torque_y_nm", "torque_z_nm")
SLOW_AXES = ("force_slow_x_n", "force_slow_y_n", "force_slow_z_n")
#: Wrench components in column order: forces [N], torques [N m] (as physics' WRENCH_AXES).
COMPONENTS = ("fx", "fy", "fz", "tx", "ty", "tz")
FORCES_ONLY = COMPONENTS[:3]
#: Per component its parity under the mirrors about x = 0 and y = 0 (1: the mirror flips it);
#: torques are pseudo-vectors, so Tx flips with y like Fy, Ty with x like Fx, Tz with both.
COMPONENT_PARITY = {"fx": (1, 0), "fy": (0, 1), "fz": (0, 0), "tx": (0, 1), "ty": (1, 0),
                    "tz": (1, 1)}
NOISE_COPIES = 30  # noisy copies of each point when the fit is given an output noise
#: Degree of the torque polynomials: the wrench paths are few (six directions of load), so
#: a low degree keeps the torque's free terms from wandering between them.
TORQUE_DEGREE = 2
_MIRRORED = ({"right": "left", "left": "right"}, {"front": "back", "back": "front"})
#: Representative order within an orbit: the positive face first, then the larger offset.
_RANK = {"right": 0, "left": 1, "front": 2, "back": 3}


def parse_label(label: str) -> tuple[str, float]:
    """(face, offset [m]) of a module label ``FACE`` or ``FACE@OFFSET``; ValueError if it is
    neither."""
    face, at, offset = str(label).partition("@")
    if face not in FACES or (at and not offset.strip()):
        raise ValueError(label)
    c = float(offset) if at else 0.0
    if not math.isfinite(c):
        raise ValueError(label)
    return face, c + 0.0


def _key(face: str, offset: float) -> tuple[str, float]:
    return face, round(offset, 9) + 0.0


def _mirror(module: tuple[str, float], axis: int) -> tuple[str, float]:
    """The module the mirror about ``axis`` = 0 maps ``module`` onto."""
    face, c = module
    if face in _MIRRORED[axis]:
        return _key(_MIRRORED[axis][face], c)   # across the mirror: the offset stays
    return _key(face, -c)                        # along the mirror: the offset flips


def mirror_axes(faces: Sequence[str]) -> tuple[bool, bool]:
    """Whether the mirror about x = 0 (first) and y = 0 (second) maps the modules onto
    themselves (only then does its parity constrain the fit)."""
    keys = {_key(*parse_label(f)) for f in faces}
    return tuple(all(_mirror(k, a) in keys for k in keys) for a in (0, 1))  # type: ignore


def symmetric_features(faces: Sequence[str]) -> tuple[np.ndarray, list[tuple[int, int]]]:
    """(feature matrix over the outputs in ``faces`` order, per feature its (x, y) parity:
    1 where mirroring that axis flips the feature's sign). One feature per orbit of the
    layout's mirrors and parity; a parity along an axis whose mirror does not map the layout
    onto itself is 0 (that mirror of the array is no array)."""
    keys = [_key(*parse_label(f)) for f in faces]
    index = {k: i for i, k in enumerate(keys)}
    closed = mirror_axes(faces)
    ops = [(sx, sy) for sx in ((0, 1) if closed[0] else (0,))
           for sy in ((0, 1) if closed[1] else (0,))]

    def image(k: tuple[str, float], sx: int, sy: int) -> tuple[str, float]:
        if sx:
            k = _mirror(k, 0)
        return _mirror(k, 1) if sy else k

    orbits: list[list[tuple[str, float]]] = []
    seen: set[tuple[str, float]] = set()
    for k in keys:
        if k not in seen:
            orbit = sorted({image(k, sx, sy) for sx, sy in ops},
                           key=lambda m: (_RANK[m[0]], -m[1]))
            seen.update(orbit)
            orbits.append(orbit)
    orbits.sort(key=lambda o: (-len(o), _RANK[o[0][0]] if len(o) > 1 else index[o[0]]))
    rows: list[np.ndarray] = []
    parity: list[tuple[int, int]] = []
    for orbit in orbits:
        for px, py in ops:                       # the characters of the mirror group
            row = np.zeros(len(faces))
            for sx, sy in ops:
                row[index[image(orbit[0], sx, sy)]] += (-1.0) ** (px * sx + py * sy)
            if np.any(row):
                rows.append(row / np.abs(row).max())
                parity.append((px, py))
    return np.stack(rows), parity


def monomial_factors(terms: np.ndarray) -> np.ndarray:
    """(terms, degree) feature column of each factor of each monomial (exponents ``terms``,
    (terms, m)); column m, a feature that is 1, pads the monomials of lower degree."""
    m = terms.shape[1]
    columns = np.full((terms.shape[0], max(1, int(terms.sum(axis=1).max(initial=0)))), m)
    for t, exponents in enumerate(terms):
        factors = np.repeat(np.arange(m), exponents)
        columns[t, :factors.size] = factors
    return columns


def polynomial_terms(modules: int, degree: int) -> list[tuple[int, ...]]:
    """Exponent tuples of every monomial up to ``degree`` in ``modules`` variables."""
    terms = [e for total in range(degree + 1)
             for e in itertools.product(range(total + 1), repeat=modules) if sum(e) == total]
    return sorted(set(terms), key=lambda e: (sum(e), tuple(-v for v in e)))


def _compile_wrench(mix: np.ndarray, terms: np.ndarray, coefficients: np.ndarray,
                    observed: Sequence[bool]) -> Callable[..., tuple[float, ...]]:
    """One reading's six components as a straight-line Python function of the outputs.

    The driver evaluates the polynomials once per sample at 1 kHz: numpy's per-call
    overhead made that 70 us for four modules (ten times the whole single-module chain),
    the unrolled expression (numbers as exact ``repr``, zero coefficients left out) about
    4 us. A monomial that several components use is computed once; an unobserved
    component is the constant NaN.
    """
    m = mix.shape[1]
    lines = [f"def wrench({', '.join(f'o{i}' for i in range(m))}):"]
    for j, row in enumerate(mix):
        mixed = " + ".join(f"{float(c)!r} * o{i}" for i, c in enumerate(row) if c != 0.0)
        lines.append(f"    z{j} = {mixed or '0.0'}")
    power = {1: "z{}".format}
    for e in range(2, int(terms.max(initial=1)) + 1):
        power[e] = f"z{{}}_{e}".format
    live = coefficients[np.asarray(observed, bool)]
    for j in range(m):
        used = terms[np.any(live != 0.0, axis=0), j] if live.size else terms[:0, j]
        for e in range(2, int(used.max(initial=0)) + 1):
            lines.append(f"    {power[e](j)} = {power[e - 1](j)} * z{j}")
    monomials = []
    for t, exponents in enumerate(terms):
        factors = [power[e](j) for j, e in enumerate(exponents) if e]
        mono = " * ".join(factors) or "1.0"
        if len(factors) > 1 and np.count_nonzero(live[:, t]) > 1:
            lines.append(f"    m{t} = {mono}")
            mono = f"m{t}"
        monomials.append(mono)
    sums = []
    for row, seen in zip(coefficients, observed, strict=True):
        parts = [f"{float(c)!r} * {mono}" for c, mono in zip(row, monomials, strict=True)
                 if c != 0.0]
        sums.append((" + ".join(parts) or "0.0") if seen else "nan")
    lines.append(f"    return ({', '.join(sums)})")
    namespace: dict[str, Any] = {"nan": math.nan}
    exec(compile("\n".join(lines), "<array calibration>", "exec"), namespace)
    return namespace["wrench"]


def _check_labels(faces: tuple[str, ...], where: str) -> None:
    """Distinct module labels, at least one."""
    try:
        keys = [_key(*parse_label(f)) for f in faces]
    except ValueError:
        keys = []
    if not faces or len(set(keys)) != len(faces):
        raise CalibrationError(f"{where}: 'faces' must be distinct module labels (a face "
                               f"out of {', '.join(FACES)}, optionally FACE@OFFSET in "
                               f"m); got {list(faces)}.")


class ArrayCalibration:
    """An immutable, validated outputs -> wrench polynomial (forces always, torques when
    ``torque_coefficients`` are given and ``observed`` names them)."""

    def __init__(self, faces: Sequence[str], feature_matrix: Sequence[Sequence[float]],
                 terms: Sequence[Sequence[int]], coefficients: Sequence[Sequence[float]],
                 output_scale_v: float, output_max_v: Sequence[float], source: str,
                 torque_coefficients: Sequence[Sequence[float]] | None = None,
                 observed: Sequence[str] | None = None,
                 slow_coefficients: Sequence[Sequence[float]] | None = None) -> None:
        where = source or "the array calibration"
        self.faces = tuple(str(f) for f in faces)
        _check_labels(self.faces, where)
        scale = self._store_numbers(where, feature_matrix, terms, coefficients, output_scale_v,
                                    output_max_v, torque_coefficients, slow_coefficients)
        self.observed = self._observed_components(where, observed)
        self._check_values(where, scale)
        self.output_scale_v = scale
        self.source = str(source)
        self._seen = np.array([c in self.observed for c in COMPONENTS])
        self._wrench_one = _compile_wrench(
            self.feature_matrix / scale, self.terms,
            np.concatenate([self.coefficients + self.slow_coefficients,
                            self.torque_coefficients]), self._seen)
        self._parts_one = _compile_wrench(
            self.feature_matrix / scale, self.terms,
            np.concatenate([self.coefficients, self.torque_coefficients,
                            self.slow_coefficients]), np.concatenate([self._seen,
                                                                      self._seen[:3]]))
        self._limits = tuple(float(v) * 1.05 for v in self.output_max_v)

    def _store_numbers(self, where: str, feature_matrix: Sequence[Sequence[float]],
                       terms: Sequence[Sequence[int]], coefficients: Sequence[Sequence[float]],
                       output_scale_v: float, output_max_v: Sequence[float],
                       torque_coefficients: Sequence[Sequence[float]] | None,
                       slow_coefficients: Sequence[Sequence[float]] | None) -> float:
        """The file's numbers as arrays, with one coefficient per term for each component
        given; returns the output scale (checked with the rest by ``_check_values``)."""
        try:
            self.feature_matrix = np.asarray(feature_matrix, dtype=float)
            self.terms = np.asarray(terms, dtype=int).reshape(-1, len(self.faces))
            rows = [np.asarray(c, dtype=float).ravel() for c in coefficients]
            torque_rows = None if torque_coefficients is None else [
                np.asarray(c, dtype=float).ravel() for c in torque_coefficients]
            slow_rows = None if slow_coefficients is None else [
                np.asarray(c, dtype=float).ravel() for c in slow_coefficients]
            self.output_max_v = np.asarray(output_max_v, dtype=float)
            scale = float(output_scale_v)
        except (TypeError, ValueError):
            raise CalibrationError(f"{where}: terms, coefficients and scales must be numbers "
                                   f"with one exponent per face; refit it.") from None
        if len(rows) != 3 or any(r.size != self.terms.shape[0] for r in rows) or \
                self.terms.size == 0:
            raise CalibrationError(f"{where}: needs one coefficient per term for each of "
                                   f"x, y and z; refit it.")
        if torque_rows is not None and (len(torque_rows) != 3 or any(
                r.size != self.terms.shape[0] for r in torque_rows)):
            raise CalibrationError(f"{where}: the torque columns need one coefficient per "
                                   f"term ({self.terms.shape[0]}) for each of x, y and z; "
                                   "refit it.")
        if slow_rows is not None and (torque_rows is None or len(slow_rows) != 3 or any(
                r.size != self.terms.shape[0] for r in slow_rows)):
            raise CalibrationError(f"{where}: the force's slow part needs the torque columns "
                                   f"and one coefficient per term ({self.terms.shape[0]}) for "
                                   "each of x, y and z; refit it.")
        self.has_torque = torque_rows is not None
        self.has_slow = slow_rows is not None
        self.coefficients = np.stack(rows)
        self.torque_coefficients = np.stack(torque_rows) if torque_rows is not None else \
            np.zeros_like(self.coefficients)
        self.slow_coefficients = np.stack(slow_rows) if slow_rows is not None else \
            np.zeros_like(self.coefficients)
        return scale

    def _observed_components(self, where: str, observed: Sequence[str] | None
                             ) -> tuple[str, ...]:
        """The components read (torques only with torque columns), in ``COMPONENTS`` order."""
        wanted = FORCES_ONLY if observed is None else tuple(str(c) for c in observed)
        if not wanted or len(set(wanted)) != len(wanted) or any(
                c not in COMPONENTS for c in wanted) or (not self.has_torque and any(
                c.startswith("t") for c in wanted)):
            raise CalibrationError(f"{where}: 'observed' must be distinct components out of "
                                   f"{', '.join(COMPONENTS)} (torques only with torque "
                                   f"columns); got {list(wanted)}.")
        return tuple(c for c in COMPONENTS if c in wanted)

    def _check_values(self, where: str, scale: float) -> None:
        """Shapes that match the faces, exponents >= 0 and every number finite."""
        if self.feature_matrix.shape != (len(self.faces),) * 2 or not np.all(
                np.isfinite(self.feature_matrix)):
            raise CalibrationError(f"{where}: 'feature_matrix' must be square with one row "
                                   "and column per face, of finite numbers; refit it.")
        if self.output_max_v.shape != (len(self.faces),):
            raise CalibrationError(f"{where}: 'output_max_v' needs one value per face.")
        if np.any(self.terms < 0) or not (math.isfinite(scale) and scale > 0) or not np.all(
                np.isfinite(self.coefficients)) or not np.all(
                np.isfinite(self.torque_coefficients)) or not np.all(
                np.isfinite(self.slow_coefficients)) or not np.all(
                np.isfinite(self.output_max_v)):
            raise CalibrationError(f"{where}: exponents must be >= 0, the output scale > 0 "
                                   "and every number finite; refit it.")

    @property
    def full_scale_force_n(self) -> float:
        """Normal force Fz [N] with every face at the largest output the fit saw: beyond it
        the polynomial extrapolates, so that is the most pressing it measures."""
        return float(self._wrench_one(*(float(v) for v in self.output_max_v))[2])

    @property
    def degree(self) -> int:
        return int(self.terms.sum(axis=1).max())

    @property
    def unobserved(self) -> tuple[str, ...]:
        """The wrench components this calibration reads as NaN, in ``COMPONENTS`` order."""
        return tuple(c for c in COMPONENTS if c not in self.observed)

    def unobserved_reason(self) -> str:
        """One sentence on the components read as NaN and why ("" when all six are seen)."""
        missing = self.unobserved
        if not missing:
            return ""
        torques = [c for c in missing if c.startswith("t")]
        forces = [c for c in missing if c.startswith("f")]
        parts = []
        if torques:
            why = ("the layout's modules cannot observe torque" if self.has_torque else
                   "the calibration has no torque columns (force only; centred "
                   "windows cannot observe a torque at all)")
            parts.append(f"{', '.join(torques)}: {why}")
        if forces:
            parts.append(f"{', '.join(forces)}: the layout's modules cannot observe "
                         "this force")
        return "; ".join(parts)

    def _basis(self, outputs: np.ndarray) -> np.ndarray:
        """(n, terms) monomials of the features: each a product of its few factors, as
        multiplications (a fit evaluates tens of thousands of noisy points, and a power
        per feature and term cost the model node seconds at every start)."""
        z = (np.atleast_2d(outputs) / self.output_scale_v) @ self.feature_matrix.T  # (n, m)
        factors = np.concatenate([z, np.ones((z.shape[0], 1))], axis=1)
        columns = monomial_factors(self.terms)
        basis = factors[:, columns[:, 0]]
        for k in range(1, columns.shape[1]):
            basis *= factors[:, columns[:, k]]
        return basis

    def _checked(self, outputs: np.ndarray) -> np.ndarray:
        outputs = np.asarray(outputs, dtype=float)
        if outputs.ndim != 2 or outputs.shape[1] != len(self.faces):
            raise CalibrationError(f"Expected outputs of {len(self.faces)} modules "
                                   f"({', '.join(self.faces)}), got shape {outputs.shape}.")
        return outputs

    def forces(self, outputs: np.ndarray) -> np.ndarray:
        """(n, 3) forces [N] for (n, modules) outputs [V] in ``faces`` order."""
        return self.wrenches(outputs)[:, :3]

    def wrenches(self, outputs: np.ndarray) -> np.ndarray:
        """(n, 6) wrenches [N, N m] for (n, modules) outputs [V]; NaN where unobserved."""
        out = self._basis(self._checked(outputs)) @ np.concatenate(
            [self.coefficients + self.slow_coefficients, self.torque_coefficients]).T
        out[:, ~self._seen] = math.nan
        return out

    def _values(self, outputs: Mapping[str, float] | Sequence[float]) -> list[float]:
        if isinstance(outputs, Mapping):
            missing = [f for f in self.faces if f not in outputs]
            if missing:
                raise CalibrationError(f"No output for module(s) {', '.join(missing)}; the "
                                       f"calibration needs {', '.join(self.faces)}.")
            return [float(outputs[f]) for f in self.faces]
        values = [float(v) for v in outputs]
        if len(values) != len(self.faces):
            raise CalibrationError(f"Expected outputs of {len(self.faces)} modules "
                                   f"({', '.join(self.faces)}), got {len(values)}.")
        return values

    def force(self, outputs: Mapping[str, float] | Sequence[float]
              ) -> tuple[float, float, float]:
        """(Fx, Fy, Fz) [N] of one reading: a module -> output mapping or a sequence in
        ``faces`` order."""
        fx, fy, fz, *_ = self._wrench_one(*self._values(outputs))
        return fx, fy, fz

    def wrench(self, outputs: Mapping[str, float] | Sequence[float]) -> tuple[float, ...]:
        """(Fx, Fy, Fz, Tx, Ty, Tz) [N, N m] of one reading, NaN where unobserved."""
        return self._wrench_one(*self._values(outputs))

    def wrench_unchecked(self, outputs: Sequence[float]) -> tuple[float, ...]:
        """``wrench`` of a sequence already in ``faces`` order and length: the per-sample
        path, without the checks' list."""
        return self._wrench_one(*outputs)

    def wrench_parts_unchecked(self, outputs: Sequence[float]) -> tuple[float, ...]:
        """(Fx, Fy, Fz, Tx, Ty, Tz, slow Fx, slow Fy, slow Fz) of one reading in ``faces``
        order, the force without its slow part: a driver low-passes the last six and adds
        the slow part to the force (module docstring)."""
        return self._parts_one(*outputs)

    def in_range(self, outputs: Sequence[float], margin: float = 0.05) -> bool:
        """Whether no output exceeds the fitted range by more than ``margin`` of it."""
        if margin == 0.05:  # the driver's call, once per sample: no numpy round trip
            return all(o <= m for o, m in zip(outputs, self._limits, strict=True))
        return bool(np.all(np.asarray(outputs, float) <= self.output_max_v * (1 + margin)))

    def reordered(self, faces: Sequence[str]) -> ArrayCalibration:
        """The same calibration for the outputs in ``faces`` order (the same modules, labels
        compared by face and offset); ``CalibrationError`` if they are other modules."""
        try:
            want = [_key(*parse_label(f)) for f in faces]
        except ValueError:
            want = []
        have = [_key(*parse_label(f)) for f in self.faces]
        if sorted(want) != sorted(have) or len(set(want)) != len(want):
            raise CalibrationError(f"The array calibration {self.source} is for modules "
                                   f"{', '.join(self.faces)}, not {', '.join(faces)}.")
        if want == have and tuple(faces) == self.faces:
            return self
        order = [have.index(k) for k in want]
        torque = self.torque_coefficients if self.has_torque else None
        slow = self.slow_coefficients if self.has_slow else None
        return ArrayCalibration(tuple(faces), self.feature_matrix[:, order], self.terms,
                                self.coefficients, self.output_scale_v,
                                self.output_max_v[order], self.source, torque, self.observed,
                                slow)

    # -- fitting -----------------------------------------------------------------------------

    @classmethod
    def fit(cls, faces: Sequence[str], outputs: np.ndarray, wrench: np.ndarray, degree: int,
            source: str, noise_v: float = 0.0, torque_degree: int = TORQUE_DEGREE,
            observed: Sequence[str] | None = None, torque_noise_v: float | None = None,
            slow_forces: np.ndarray | None = None, press_scaled: bool = False
            ) -> ArrayCalibration:
        """Least squares of each component on the monomials of the features that the
        array's mirror symmetry allows it (module docstring): forces up to ``degree``,
        torques up to ``torque_degree``.

        ``wrench`` is (points, 3) forces or (points, 6) forces and torques; a NaN entry
        means no data for that component at that point (e.g. forces from one load set,
        torques from another), so each component is fitted on its own finite rows.
        ``observed`` (default: the forces, and the torques that have data) are the
        components fitted; the others read NaN.

        ``torque_noise_v`` (default ``noise_v``) is the torques' own: their signal is a few
        mV, so noise in the fit shrinks their coefficients (regression dilution: 5 mV cut a
        synthetic torque by a fifth) where the forces' many terms need it.

        ``slow_forces`` (points, 3), with the torques: every point's force, also where
        ``wrench`` leaves it NaN (the wrench paths'); the force's slow part is fitted, like
        the torques, on what the force polynomial leaves of it (module docstring).

        ``press_scaled``: the torques and the slow part add to their linear terms gains
        that follow the press (``sensing.press_scaled_terms``: unbiased under noise).

        ``noise_v`` > 0 fits every point also as ``NOISE_COPIES`` copies with Gaussian output
        noise of that sigma [V] (fixed seed), so the fit cannot lean on terms that amplify a
        module's noise. Why: on the noise-free FEM grid the two opposite-pair sums are nearly
        the same number (both follow the indentation), and the plain fit gave Fz coefficients
        of -335 and +671 on their cancelling cubes; 13 mV of output noise per module then
        made 1.75 N of Fz error, against 0.16 N with 5 mV of noise in the fit.
        """
        outputs = np.asarray(outputs, dtype=float)
        wrench = np.asarray(wrench, dtype=float)
        _check_degrees(degree, torque_degree)
        torque_degree = min(torque_degree, degree)
        torque_noise_v = noise_v if torque_noise_v is None else torque_noise_v
        _check_fit_data(faces, outputs, wrench, (noise_v, torque_noise_v))
        six = wrench.shape[1] == 6
        wanted = _fitted_components(wrench, observed)
        terms = polynomial_terms(len(faces), degree)
        scale = float(np.abs(outputs).max()) or 1.0
        matrix, parity = symmetric_features(faces)
        probe = cls(faces, matrix, terms, np.zeros((3, len(terms))), scale,
                    outputs.max(axis=0), source)
        bases = {sigma: _noisy_basis(probe, outputs, wrench, sigma)
                 for sigma in {noise_v, torque_noise_v}}
        allowed = _AllowedTerms(terms, parity, mirror_axes(faces), torque_degree)
        groups = press_groups(terms, parity) if press_scaled else []
        coef = np.zeros((6, len(terms)))
        counts = np.isfinite(wrench).sum(axis=0)
        for k, name in enumerate(COMPONENTS):
            if name not in wanted:
                continue
            keep = allowed.of(name, torque=k >= 3)
            basis, values = bases[noise_v if k < 3 else torque_noise_v]
            rows = np.isfinite(values[:, k])
            if counts[k] < keep.sum():
                raise CalibrationError(
                    f"A degree-{torque_degree if k >= 3 else degree} {name} fit of "
                    f"{len(faces)} modules has {int(keep.sum())} terms but only "
                    f"{int(counts[k])} points; lower the degree or add "
                    f"{'load paths' if k >= 3 else 'grid points'}.")
            if keep.any() and k >= 3 and groups:
                coef[k] = fit_press_scaled(basis[rows], values[rows, k], keep, groups)
            elif keep.any():
                coef[k, keep] = np.linalg.lstsq(basis[rows][:, keep], values[rows, k],
                                                rcond=None)[0]
        slow = None
        if slow_forces is not None and six:
            left = _checked_slow(slow_forces, outputs) - probe._basis(outputs) @ coef[:3].T
            slow = _fit_slow(left, bases[torque_noise_v][0], allowed, wanted, groups)
        return cls(faces, matrix, terms, coef[:3], scale, outputs.max(axis=0), source,
                   coef[3:] if six else None, wanted, slow)

    # -- files -------------------------------------------------------------------------------

    def to_dict(self, fit: Mapping[str, Any] | None = None) -> dict[str, Any]:
        data: dict[str, Any] = {"format": FILE_FORMAT, "version": FILE_VERSION,
                                "faces": list(self.faces),
                                "feature_matrix": self.feature_matrix.tolist(),
                                "degree": self.degree,
                                "output_scale_v": self.output_scale_v,
                                "terms": self.terms.tolist(),
                                "output_max_v": self.output_max_v.tolist(),
                                "observed": list(self.observed),
                                "source": self.source}
        data.update({axis: self.coefficients[k].tolist() for k, axis in enumerate(AXES)})
        if self.has_torque:
            data.update({axis: self.torque_coefficients[k].tolist()
                         for k, axis in enumerate(TORQUE_AXES)})
        if self.has_slow:
            data.update({axis: self.slow_coefficients[k].tolist()
                         for k, axis in enumerate(SLOW_AXES)})
        if fit is not None:
            data["fit"] = dict(fit)
        return data

    @classmethod
    def from_mapping(cls, data: Any, source: str) -> ArrayCalibration:
        if not isinstance(data, Mapping):
            raise CalibrationError(f"{source}: expected a JSON object, got "
                                   f"{type(data).__name__}.")
        if data.get("format") != FILE_FORMAT:
            raise CalibrationError(f"{source}: 'format' must be \"{FILE_FORMAT}\"; this is not "
                                   "an array calibration file.")
        version = data.get("version")
        if version not in READ_VERSIONS or isinstance(version, bool):
            raise CalibrationError(f"{source}: array calibration version "
                                   f"{version!r} is not supported (expected "
                                   f"{' or '.join(map(str, READ_VERSIONS))}); refit it.")
        required = ["faces", "feature_matrix", "terms", "output_scale_v", "output_max_v",
                    *AXES]
        if version >= 2:
            required.append("observed")
        missing = [k for k in required if k not in data]
        torque = [k for k in TORQUE_AXES if k in data]
        if torque and len(torque) != 3:
            missing += [k for k in TORQUE_AXES if k not in data]
        slow = [k for k in SLOW_AXES if k in data]
        if slow and len(slow) != 3:
            missing += [k for k in SLOW_AXES if k not in data]
        if missing:
            raise CalibrationError(f"{source}: missing {', '.join(missing)}; refit it.")
        if not isinstance(data["faces"], list):
            raise CalibrationError(f"{source}: 'faces' must be a list of module labels.")
        observed = data.get("observed")
        if observed is not None and not isinstance(observed, list):
            raise CalibrationError(f"{source}: 'observed' must be a list of components "
                                   f"out of {', '.join(COMPONENTS)}.")
        return cls(data["faces"], data["feature_matrix"], data["terms"],
                   [data[a] for a in AXES], data["output_scale_v"], data["output_max_v"],
                   source, [data[a] for a in TORQUE_AXES] if torque else None, observed,
                   [data[a] for a in SLOW_AXES] if slow else None)

    @classmethod
    def from_file(cls, path: Path | str) -> ArrayCalibration:
        path = Path(path)
        data = read_json_file(path, "Array calibration file", "write one with "
                              "'tactile-sensor model array-calibration --calibration FILE'",
                              "rewrite it")
        cal = cls.from_mapping(data, f"file:{path}")
        cal.source = file_source(path, data)
        return cal

    def to_file(self, path: Path | str, fit: Mapping[str, Any] | None = None) -> None:
        Path(path).write_text(json.dumps(self.to_dict(fit), indent=1) + "\n",
                              encoding="utf-8")

    def __repr__(self) -> str:
        return (f"ArrayCalibration({', '.join(self.faces)}, degree {self.degree}, "
                f"source={self.source!r})")


def _check_degrees(degree: int, torque_degree: int) -> None:
    if degree < 1 or torque_degree < 1:
        raise CalibrationError(f"The polynomial degree must be >= 1, got {degree} (torque "
                               f"{torque_degree}).")


def _check_fit_data(faces: Sequence[str], outputs: np.ndarray, wrench: np.ndarray,
                    noises_v: tuple[float, float]) -> None:
    for value in noises_v:
        if not (math.isfinite(value) and 0.0 <= value <= 1.0):
            raise CalibrationError(f"The fit's output noise must be in [0, 1] V, got "
                                   f"{value!r}.")
    if outputs.ndim != 2 or outputs.shape[1] != len(faces) or wrench.ndim != 2 or \
            wrench.shape not in ((outputs.shape[0], 3), (outputs.shape[0], 6)) or \
            not np.all(np.isfinite(outputs)):
        raise CalibrationError("Fitting needs finite (points, modules) outputs and "
                               "(points, 3) forces or (points, 6) wrenches for the "
                               "same points.")


def _fitted_components(wrench: np.ndarray, observed: Sequence[str] | None
                       ) -> tuple[str, ...]:
    """``observed``, or the forces and the torques that have data; each must have data."""
    has_data = [bool(np.isfinite(wrench[:, k]).any()) for k in range(wrench.shape[1])]
    wanted = tuple(observed) if observed is not None else tuple(
        c for k, c in enumerate(COMPONENTS[:wrench.shape[1]]) if k < 3 or has_data[k])
    lacking = [c for c in wanted if c not in COMPONENTS or COMPONENTS.index(c) >=
               wrench.shape[1] or not has_data[COMPONENTS.index(c)]]
    if lacking:
        raise CalibrationError(f"Cannot fit {', '.join(lacking)}: the fit data has no "
                               "finite values of it; give its column or leave it out "
                               "of observed.")
    return wanted


def _noisy_basis(probe: ArrayCalibration, outputs: np.ndarray, wrench: np.ndarray,
                 sigma: float) -> tuple[np.ndarray, np.ndarray]:
    """(basis, wrench) of the points, with ``NOISE_COPIES`` noisy copies of each when
    ``sigma`` > 0 (fixed seed: ``ArrayCalibration.fit``)."""
    if sigma <= 0:
        return probe._basis(outputs), wrench
    rng = np.random.default_rng(0)
    jitter = rng.normal(0.0, sigma, (NOISE_COPIES, *outputs.shape))
    return (probe._basis(np.concatenate([outputs, *(outputs + jitter)])),
            np.tile(wrench, (NOISE_COPIES + 1, 1)))


class _AllowedTerms:
    """Which monomials each component may use: those of its own mirror parity under the
    mirrors the layout has, and for a torque (or the force's slow part) only up to the
    torque degree."""

    def __init__(self, terms: list[tuple[int, ...]], parity: list[tuple[int, int]],
                 closed: tuple[bool, bool], torque_degree: int) -> None:
        exponents = np.array(terms)
        self._odd = exponents @ np.array(parity) % 2              # (terms, 2): x, y parity
        self._total = exponents.sum(axis=1)
        self._closed = np.array(closed, int)
        self._torque_degree = torque_degree

    def of(self, name: str, torque: bool) -> np.ndarray:
        closed = self._closed
        keep = np.all(self._odd * closed == np.array(COMPONENT_PARITY[name]) * closed, axis=1)
        if torque:
            keep &= self._total <= self._torque_degree
        return keep


def _checked_slow(slow_forces: np.ndarray, outputs: np.ndarray) -> np.ndarray:
    slow_forces = np.asarray(slow_forces, dtype=float)
    if slow_forces.shape != (outputs.shape[0], 3):
        raise CalibrationError("The slow forces need one (Fx, Fy, Fz) row per point.")
    return slow_forces


def _fit_slow(left: np.ndarray, basis: np.ndarray, allowed: _AllowedTerms,
              wanted: tuple[str, ...], groups: list[tuple[int, tuple[int, ...]]]
              ) -> np.ndarray:
    """The force's slow part, fitted to what the force polynomial left of each point's
    force (``left``) on the torques' basis: their degree, their noise copies, their press
    gains (``groups``)."""
    copies = basis.shape[0] // left.shape[0]
    values = np.tile(left, (copies, 1))
    slow = np.zeros((3, basis.shape[1]))
    for k, name in enumerate(COMPONENTS[:3]):
        rows = np.isfinite(values[:, k])
        keep = allowed.of(name, torque=True)
        if name in wanted and keep.any() and rows.sum() >= keep.sum() and groups:
            slow[k] = fit_press_scaled(basis[rows], values[rows, k], keep, groups)
        elif name in wanted and keep.any() and rows.sum() >= keep.sum():
            slow[k, keep] = np.linalg.lstsq(basis[rows][:, keep], values[rows, k],
                                            rcond=None)[0]
    return slow
