"""Fit, save, load and apply the output -> force calibration the driver uses.

Fit: outputs are binned, the mean force per bin is made non-decreasing by weighted
isotonic regression, and a PCHIP through those points (monotone by construction) is
sampled at evenly spaced outputs. The file format is the one in docs/CONTRACTS.md.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from scipy.interpolate import PchipInterpolator
from scipy.optimize import isotonic_regression

from .errors import CalibrationFileError, SegmentError

FORMAT = "tactile_sensor/calibration"
VERSION = 1
MIN_BIN_SAMPLES = 5


@dataclass(frozen=True)
class Calibration:
    """Monotone table: output_v strictly increasing, force_n non-decreasing."""

    output_v: np.ndarray
    force_n: np.ndarray
    source: str
    fit: dict[str, Any] = field(default_factory=dict)

    def force(self, output_v: np.ndarray) -> np.ndarray:
        """Linear interpolation, clamped to the end forces beyond the table (as the driver)."""
        return np.interp(output_v, self.output_v, self.force_n)

    def to_dict(self) -> dict[str, Any]:
        return {"format": FORMAT, "version": VERSION,
                "output_v": [float(x) for x in self.output_v],
                "force_n": [float(x) for x in self.force_n],
                "source": self.source, "fit": self.fit}


def fit_calibration(output_v: np.ndarray, force_n: np.ndarray, source: str,
                    bins: int = 40, points: int = 64) -> Calibration:
    """Monotone output -> force curve through binned, isotonic-regressed means."""
    keep = np.isfinite(output_v) & np.isfinite(force_n)
    x, y = output_v[keep], force_n[keep]
    if x.size < 2 * MIN_BIN_SAMPLES:
        raise SegmentError(f"only {x.size} samples are available to fit a calibration; "
                           "record at least one full press at the reference speed.")
    lo, hi = np.percentile(x, [0.5, 99.5])
    if not hi > lo:
        raise SegmentError("the module output does not change during the presses, so no "
                           "calibration can be fitted; check the reading topic and the sensor.")
    edges = np.linspace(lo, hi, bins + 1)
    which = np.clip(np.digitize(x, edges) - 1, 0, bins - 1)
    inside = (x >= lo) & (x <= hi)
    counts = np.bincount(which[inside], minlength=bins)
    sx = np.bincount(which[inside], weights=x[inside], minlength=bins)
    sy = np.bincount(which[inside], weights=y[inside], minlength=bins)
    ok = counts >= MIN_BIN_SAMPLES
    if np.count_nonzero(ok) < 2:
        raise SegmentError("the press samples fill fewer than two output bins, so no "
                           "calibration can be fitted; record a full press.")
    bx, by, w = sx[ok] / counts[ok], sy[ok] / counts[ok], counts[ok].astype(float)
    strictly = np.concatenate(([True], np.diff(bx) > 0))
    bx, by, w = bx[strictly], by[strictly], w[strictly]
    iso = isotonic_regression(by, weights=w, increasing=True).x
    out = np.linspace(bx[0], bx[-1], points)
    force = np.maximum.accumulate(PchipInterpolator(bx, iso)(out))
    rmse = float(np.sqrt(np.mean((np.interp(x, out, force) - y) ** 2)))
    return Calibration(out, force, source, {
        "method": "binned means, weighted isotonic regression, PCHIP",
        "bins": int(bx.size), "samples": int(x.size), "in_sample_rmse_n": rmse})


def save_calibration(cal: Calibration, path: Path) -> None:
    path.write_text(json.dumps(cal.to_dict(), indent=2) + "\n", encoding="utf-8")


def load_calibration(path: Path | str) -> Calibration:
    """Read and validate a calibration file; CalibrationFileError names what is wrong."""
    path = Path(path)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except OSError as err:
        raise CalibrationFileError(f"cannot read the calibration file {path} "
                                   f"({err.strerror}); pass an existing file.") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as err:
        raise CalibrationFileError(f"the calibration file {path} is not valid JSON ({err}); "
                                   "write it with 'tactile-sensor analyze --fit-calibration'."
                                   ) from None
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise CalibrationFileError(f"the calibration file {path} lacks \"format\": "
                                   f"\"{FORMAT}\"; pass a file in the format of "
                                   "docs/CONTRACTS.md.")
    if data.get("version") != VERSION:
        raise CalibrationFileError(f"the calibration file {path} has version "
                                   f"{data.get('version')!r}, this tool reads {VERSION}; "
                                   "refit it with this version.")
    arrays = []
    for key in ("output_v", "force_n"):
        value = data.get(key)
        try:
            arr = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            arr = np.zeros(0)
        if arr.ndim != 1 or arr.size < 2 or not np.all(np.isfinite(arr)):
            raise CalibrationFileError(f"the calibration file {path} needs \"{key}\" as a "
                                       "list of at least two finite numbers; fix or refit it.")
        arrays.append(arr)
    out, force = arrays
    if out.size != force.size:
        raise CalibrationFileError(f"the calibration file {path} has {out.size} outputs but "
                                   f"{force.size} forces; they must pair up.")
    if np.any(np.diff(out) <= 0):
        raise CalibrationFileError(f"the calibration file {path} has output_v not strictly "
                                   "increasing; fix or refit it.")
    if np.any(np.diff(force) < 0):
        raise CalibrationFileError(f"the calibration file {path} has force_n decreasing; a "
                                   "calibration must be monotone - fix or refit it.")
    fit = data.get("fit") if isinstance(data.get("fit"), dict) else {}
    return Calibration(out, force, str(data.get("source", path)), fit)
