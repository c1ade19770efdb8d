"""Module outputs [V] of an array -> force vector (Fx, Fy, Fz) [N] by a fitted polynomial.

The physics (docs/array.md): a lateral probe displacement bulges the face it moves toward and
draws in the opposite one, so opposite modules' difference reads shear and their sum normal
force. The polynomial's variables are therefore those features, ``feature_matrix`` @
(outputs / ``output_scale_v``): per pair of opposite modules their sum and their difference
(positive face minus negative face), a module without its opposite as it is. Mirroring the
skin about x = 0 flips the x difference and Fx and nothing else (likewise y), so when every
module has its opposite Fx keeps only the monomials odd in the x difference and even in the
y difference, Fy the reverse, Fz those even in both. A full polynomial in the raw outputs
fitted the grid's held-out points as well but was wrong by up to 30 N at a shear direction
between the grid's (its extra terms are free off the grid's directions); the symmetric one
is not. Scaling by the fit data's largest output keeps the least squares well conditioned.

Force convention: the probe's force on the skin along +x, +y and -z (pressing positive), as
the FEM's sweep reports it; faces as in physics (front +y, back -y, left -x, right +x).
Beyond the fitted outputs the polynomial extrapolates; ``in_range`` tells the caller.

File (JSON): ``{"format": "tactile_sensor/array_calibration", "version": 1, "faces": [...],
"feature_matrix": [[...], ...], "degree": d, "output_scale_v": s, "terms": [[e_1, ...,
e_m], ...], "force_x_n": [...], "force_y_n": [...], "force_z_n": [...], "output_max_v":
[...], "source": "...", "fit": {...}}``: with z = feature_matrix @ (o / s),
force_k = sum_t coef_k[t] prod_j z_j ** terms[t][j].
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

FILE_FORMAT = "tactile_sensor/array_calibration"
FILE_VERSION = 1
FACES = ("front", "back", "left", "right")
AXES = ("force_x_n", "force_y_n", "force_z_n")
_PAIRS = (("right", "left"), ("front", "back"))   # (positive, negative) face along x, y
NOISE_COPIES = 30  # noisy copies of each point when the fit is given an output noise


def symmetric_features(faces: Sequence[str]) -> tuple[np.ndarray, list[tuple[int, int]]]:
    """(feature matrix over the outputs in ``faces`` order, per feature its (x, y) parity:
    1 where mirroring that axis flips the feature's sign). Parities are all 0 when a module
    lacks its opposite (no mirror of the array is an array)."""
    index = {f: i for i, f in enumerate(faces)}
    rows: list[np.ndarray] = []
    parity: list[tuple[int, int]] = []
    paired: set[str] = set()
    for axis, (pos, neg) in enumerate(_PAIRS):
        if pos in index and neg in index:
            for sign in (1.0, -1.0):
                row = np.zeros(len(faces))
                row[index[pos]], row[index[neg]] = 1.0, sign
                rows.append(row)
                parity.append((int(sign < 0 and axis == 0), int(sign < 0 and axis == 1)))
            paired |= {pos, neg}
    for face in faces:
        if face not in paired:
            row = np.zeros(len(faces))
            row[index[face]] = 1.0
            rows.append(row)
            parity.append((0, 0))
    if len(paired) != len(faces):
        parity = [(0, 0)] * len(rows)
    return np.stack(rows), parity


def polynomial_terms(modules: int, degree: int) -> list[tuple[int, ...]]:
    """Exponent tuples of every monomial up to ``degree`` in ``modules`` variables."""
    terms = [e for total in range(degree + 1)
             for e in itertools.product(range(total + 1), repeat=modules) if sum(e) == total]
    return sorted(set(terms), key=lambda e: (sum(e), tuple(-v for v in e)))


def _compile_force(mix: np.ndarray, terms: np.ndarray, coefficients: np.ndarray
                   ) -> Callable[..., tuple[float, float, float]]:
    """One reading's (Fx, Fy, Fz) as a straight-line Python function of the outputs.

    The driver evaluates the polynomial once per sample at 1 kHz: numpy's per-call overhead
    made that 70 us for four modules (ten times the whole single-module chain), the
    unrolled expression (numbers as exact ``repr``, zero coefficients left out) about 4 us.
    """
    m = mix.shape[1]
    lines = [f"def force({', '.join(f'o{i}' for i in range(m))}):"]
    for j, row in enumerate(mix):
        mixed = " + ".join(f"{float(c)!r} * o{i}" for i, c in enumerate(row) if c != 0.0)
        lines.append(f"    z{j} = {mixed or '0.0'}")
    power = {1: "z{}".format}
    for e in range(2, int(terms.max(initial=1)) + 1):
        power[e] = f"z{{}}_{e}".format
    for j in range(m):
        for e in range(2, int(terms[:, j].max(initial=0)) + 1):
            lines.append(f"    {power[e](j)} = {power[e - 1](j)} * z{j}")
    monomials = []
    for t in terms:
        factors = [power[e](j) for j, e in enumerate(t) if e]
        monomials.append(" * ".join(factors) or "1.0")
    sums = []
    for row in coefficients:
        parts = [f"{float(c)!r} * {mono}" for c, mono in zip(row, monomials, strict=True)
                 if c != 0.0]
        sums.append(" + ".join(parts) or "0.0")
    lines.append(f"    return ({sums[0]}, {sums[1]}, {sums[2]})")
    namespace: dict[str, Any] = {}
    exec(compile("\n".join(lines), "<array calibration>", "exec"), namespace)
    return namespace["force"]


class ArrayCalibration:
    """An immutable, validated outputs -> (Fx, Fy, Fz) polynomial."""

    def __init__(self, faces: Sequence[str], feature_matrix: Sequence[Sequence[float]],
                 terms: Sequence[Sequence[int]], coefficients: Sequence[Sequence[float]],
                 output_scale_v: float, output_max_v: Sequence[float], source: str) -> None:
        where = source or "the array calibration"
        self.faces = tuple(str(f) for f in faces)
        if not self.faces or len(set(self.faces)) != len(self.faces) or any(
                f not in FACES for f in self.faces):
            raise CalibrationError(f"{where}: 'faces' must be distinct names out of "
                                   f"{', '.join(FACES)}; got {list(self.faces)}.")
        try:
            self.feature_matrix = np.asarray(feature_matrix, dtype=float)
            self.terms = np.asarray(terms, dtype=int).reshape(-1, len(self.faces))
            rows = [np.asarray(c, dtype=float).ravel() for c in coefficients]
            self.output_max_v = np.asarray(output_max_v, dtype=float)
            scale = float(output_scale_v)
        except (TypeError, ValueError):
            raise CalibrationError(f"{where}: terms, coefficients and scales must be numbers "
                                   f"with one exponent per face; refit it.") from None
        if len(rows) != 3 or any(r.size != self.terms.shape[0] for r in rows) or \
                self.terms.size == 0:
            raise CalibrationError(f"{where}: needs one coefficient per term for each of "
                                   f"x, y and z; refit it.")
        self.coefficients = np.stack(rows)
        if self.feature_matrix.shape != (len(self.faces),) * 2 or not np.all(
                np.isfinite(self.feature_matrix)):
            raise CalibrationError(f"{where}: 'feature_matrix' must be square with one row "
                                   "and column per face, of finite numbers; refit it.")
        if self.output_max_v.shape != (len(self.faces),):
            raise CalibrationError(f"{where}: 'output_max_v' needs one value per face.")
        if np.any(self.terms < 0) or not (math.isfinite(scale) and scale > 0) or not np.all(
                np.isfinite(self.coefficients)) or not np.all(np.isfinite(self.output_max_v)):
            raise CalibrationError(f"{where}: exponents must be >= 0, the output scale > 0 "
                                   "and every number finite; refit it.")
        self.output_scale_v = scale
        self.source = str(source)
        self._force_one = _compile_force(self.feature_matrix / scale, self.terms,
                                         self.coefficients)
        self._limits = tuple(float(v) * 1.05 for v in self.output_max_v)

    @property
    def full_scale_force_n(self) -> float:
        """Normal force Fz [N] with every face at the largest output the fit saw: beyond it
        the polynomial extrapolates, so that is the most pressing it measures."""
        return float(self._force_one(*(float(v) for v in self.output_max_v))[2])

    @property
    def degree(self) -> int:
        return int(self.terms.sum(axis=1).max())

    def _basis(self, outputs: np.ndarray) -> np.ndarray:
        z = (np.atleast_2d(outputs) / self.output_scale_v) @ self.feature_matrix.T  # (n, m)
        return np.prod(z[:, None, :] ** self.terms[None, :, :], axis=2)        # (n, terms)

    def forces(self, outputs: np.ndarray) -> np.ndarray:
        """(n, 3) forces [N] for (n, modules) outputs [V] in ``faces`` order."""
        outputs = np.asarray(outputs, dtype=float)
        if outputs.ndim != 2 or outputs.shape[1] != len(self.faces):
            raise CalibrationError(f"Expected outputs of {len(self.faces)} modules "
                                   f"({', '.join(self.faces)}), got shape {outputs.shape}.")
        return self._basis(outputs) @ self.coefficients.T

    def force(self, outputs: Mapping[str, float] | Sequence[float]
              ) -> tuple[float, float, float]:
        """(Fx, Fy, Fz) [N] of one reading: a face -> output mapping or a sequence in
        ``faces`` order."""
        if isinstance(outputs, Mapping):
            missing = [f for f in self.faces if f not in outputs]
            if missing:
                raise CalibrationError(f"No output for module(s) {', '.join(missing)}; the "
                                       f"calibration needs {', '.join(self.faces)}.")
            values = [float(outputs[f]) for f in self.faces]
        else:
            values = [float(v) for v in outputs]
            if len(values) != len(self.faces):
                raise CalibrationError(f"Expected outputs of {len(self.faces)} modules "
                                       f"({', '.join(self.faces)}), got {len(values)}.")
        return self._force_one(*values)

    def in_range(self, outputs: Sequence[float], margin: float = 0.05) -> bool:
        """Whether no output exceeds the fitted range by more than ``margin`` of it."""
        if margin == 0.05:  # the driver's call, once per sample: no numpy round trip
            return all(o <= m for o, m in zip(outputs, self._limits, strict=True))
        return bool(np.all(np.asarray(outputs, float) <= self.output_max_v * (1 + margin)))

    # -- fitting -----------------------------------------------------------------------------

    @classmethod
    def fit(cls, faces: Sequence[str], outputs: np.ndarray, forces: np.ndarray, degree: int,
            source: str, noise_v: float = 0.0) -> ArrayCalibration:
        """Least squares of each force component on the monomials up to ``degree`` of the
        features that the array's mirror symmetry allows it (module docstring).

        ``noise_v`` > 0 fits every point also as ``NOISE_COPIES`` copies with Gaussian output
        noise of that sigma [V] (fixed seed), so the fit cannot lean on terms that amplify a
        module's noise. Why: on the noise-free FEM grid the two opposite-pair sums are nearly
        the same number (both follow the indentation), and the plain fit gave Fz coefficients
        of -335 and +671 on their cancelling cubes; 13 mV of output noise per module then
        made 1.75 N of Fz error, against 0.16 N with 5 mV of noise in the fit.
        """
        outputs = np.asarray(outputs, dtype=float)
        forces = np.asarray(forces, dtype=float)
        if degree < 1:
            raise CalibrationError(f"The polynomial degree must be >= 1, got {degree}.")
        if not (math.isfinite(noise_v) and 0.0 <= noise_v <= 1.0):
            raise CalibrationError(f"The fit's output noise must be in [0, 1] V, got "
                                   f"{noise_v!r}.")
        if outputs.ndim != 2 or outputs.shape[1] != len(faces) or forces.shape != (
                outputs.shape[0], 3):
            raise CalibrationError("Fitting needs (points, modules) outputs and (points, 3) "
                                   "forces for the same points.")
        terms = polynomial_terms(len(faces), degree)
        if outputs.shape[0] < len(terms):
            raise CalibrationError(f"A degree-{degree} fit of {len(faces)} modules has "
                                   f"{len(terms)} terms but only {outputs.shape[0]} points; "
                                   "lower the degree or add grid points.")
        scale = float(np.abs(outputs).max()) or 1.0
        matrix, parity = symmetric_features(faces)
        probe = cls(faces, matrix, terms, np.zeros((3, len(terms))), scale,
                    outputs.max(axis=0), source)
        if noise_v > 0:
            rng = np.random.default_rng(0)
            jitter = rng.normal(0.0, noise_v, (NOISE_COPIES, *outputs.shape))
            outputs = np.concatenate([outputs, *(outputs + jitter)])
            forces = np.tile(forces, (NOISE_COPIES + 1, 1))
        basis = probe._basis(outputs)
        odd = np.array(terms) @ np.array(parity) % 2               # (terms, 2): x, y parity
        coef = np.zeros((3, len(terms)))
        for k, want in enumerate(((1, 0), (0, 1), (0, 0))):
            keep = np.all(odd == want, axis=1) if np.any(parity) else np.ones(len(terms),
                                                                               bool)
            if keep.any():
                coef[k, keep] = np.linalg.lstsq(basis[:, keep], forces[:, k], rcond=None)[0]
        return cls(faces, matrix, terms, coef, scale, outputs.max(axis=0), source)

    # -- files -------------------------------------------------------------------------------

    def to_dict(self, fit: Mapping[str, Any] | None = None) -> dict[str, Any]:
        data: dict[str, Any] = {"format": FILE_FORMAT, "version": FILE_VERSION,
                                "faces": list(self.faces),
                                "feature_matrix": self.feature_matrix.tolist(),
                                "degree": self.degree,
                                "output_scale_v": self.output_scale_v,
                                "terms": self.terms.tolist(),
                                "output_max_v": self.output_max_v.tolist(),
                                "source": self.source}
        data.update({axis: self.coefficients[k].tolist() for k, axis in enumerate(AXES)})
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
        if data.get("version") != FILE_VERSION:
            raise CalibrationError(f"{source}: array calibration version "
                                   f"{data.get('version')!r} is not supported (expected "
                                   f"{FILE_VERSION}); refit it.")
        missing = [k for k in ("faces", "feature_matrix", "terms", "output_scale_v",
                               "output_max_v", *AXES) if k not in data]
        if missing:
            raise CalibrationError(f"{source}: missing {', '.join(missing)}; refit it.")
        if not isinstance(data["faces"], list):
            raise CalibrationError(f"{source}: 'faces' must be a list of face names.")
        return cls(data["faces"], data["feature_matrix"], data["terms"],
                   [data[a] for a in AXES], data["output_scale_v"], data["output_max_v"],
                   source)

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
