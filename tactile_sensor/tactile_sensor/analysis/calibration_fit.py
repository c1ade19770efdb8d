"""Fit, save, load and apply the output -> force calibration the driver uses.

Fit: outputs are binned, the mean force per bin is made non-decreasing by weighted
isotonic regression, and a PCHIP through those points (monotone by construction) is
sampled at evenly spaced outputs. Files are read and written through the driver's own
``sensing.calibration.Calibration`` (and ``sensing.rate_calibration`` for a calibration
with rate terms, fitted by ``rate.fit``), so the two can never disagree about the format.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from scipy.interpolate import PchipInterpolator
from scipy.optimize import isotonic_regression

from tactile_sensor.sensing.calibration import Calibration as SensingCalibration
from tactile_sensor.sensing.errors import CalibrationError
from tactile_sensor.sensing.rate_calibration import RateCalibration, load_file

from .errors import CalibrationFileError, SegmentError
from .rate.history import rate_force_history

MIN_BIN_SAMPLES = 5


@dataclass(frozen=True)
class Calibration:
    """Monotone table: output_v strictly increasing, force_n non-decreasing; with ``rate``
    the table is that calibration's static (relaxed) curve."""

    output_v: np.ndarray
    force_n: np.ndarray
    source: str
    fit: dict[str, Any] = field(default_factory=dict)
    rate: RateCalibration | None = None

    def force(self, output_v: np.ndarray) -> np.ndarray:
        """The static curve: linear interpolation, clamped to the end forces beyond the
        table (as the driver)."""
        return np.interp(output_v, self.output_v, self.force_n)

    def force_history(self, t_s: np.ndarray, output_v: np.ndarray) -> np.ndarray:
        """The driver's force along a whole record: with rate terms when it has them."""
        if self.rate is None:
            return self.force(output_v)
        return rate_force_history(self.rate, t_s, output_v)



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
    """Write the file the driver loads (format and validation: sensing/calibration.py,
    version 2 with rate terms: sensing/rate_calibration.py)."""
    if cal.rate is not None:
        cal.rate.to_file(path, fit=cal.fit)
        return
    table = SensingCalibration.from_curve(cal.output_v.tolist(), cal.force_n.tolist(),
                                          cal.source)
    table.to_file(path, fit=cal.fit)


def load_calibration(path: Path | str) -> Calibration:
    """Read a calibration exactly as the driver does; CalibrationFileError names the fault."""
    try:
        loaded = load_file(path)
    except CalibrationError as err:
        raise CalibrationFileError(str(err)) from None
    rate = loaded if isinstance(loaded, RateCalibration) else None
    table = loaded.static if isinstance(loaded, RateCalibration) else loaded
    data = json.loads(Path(path).read_text(encoding="utf-8"))
    fit = data.get("fit") if isinstance(data.get("fit"), dict) else {}
    return Calibration(np.asarray(table.output_v), np.asarray(table.force_n),
                       str(data.get("source") or table.source), fit, rate)
