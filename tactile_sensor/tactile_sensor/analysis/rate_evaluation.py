"""Static versus rate-aware force error for each speed and phase of a recording.

Why per phase: a static curve errs differently while loading (rate force missing), in a
hold (force relaxing at constant output) and while unloading (rate force negative); one
RMSE over a whole press would hide where the rate terms help.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from tactile_sensor.sensing.rate_calibration import RateCalibration

from .rate_history import rate_force_history, static_force
from .rate_record import PHASES, RateRecord


class CurveLike(Protocol):
    """A static output -> force table (analysis' or sensing's ``Calibration``)."""

    @property
    def output_v(self) -> Any: ...

    @property
    def force_n(self) -> Any: ...


@dataclass(frozen=True)
class PhaseError:
    speed_mm_s: float
    phase: str  # 'loading', 'hold' or 'unloading'
    samples: int
    static_rmse_n: float
    rate_rmse_n: float


def phase_table(record: RateRecord, static: CurveLike, rate: RateCalibration
                ) -> list[PhaseError]:
    """One row per (speed, phase) with samples; the rate-aware force runs over the whole
    record from its start, as the driver's would."""
    static_f = static_force(np.asarray(static.output_v, float), np.asarray(static.force_n, float),
                            record.output_v)
    rate_f = rate_force_history(rate, record.t_s, record.output_v)
    rows = []
    for speed in record.speeds():
        for code, name in PHASES.items():
            keep = record.mask([speed], code)
            if not np.any(keep):
                continue
            rows.append(PhaseError(speed, name, int(np.count_nonzero(keep)),
                                   _rmse(static_f[keep], record.force_n[keep]),
                                   _rmse(rate_f[keep], record.force_n[keep])))
    return rows


def table_dict(rows: list[PhaseError]) -> dict[str, dict[str, dict[str, Any]]]:
    """JSON-ready: speed key -> phase -> samples and both RMSEs [N]."""
    out: dict[str, dict[str, dict[str, Any]]] = {}
    for r in rows:
        out.setdefault(str(float(f"{r.speed_mm_s:.2g}")), {})[r.phase] = {
            "samples": r.samples, "static_rmse_n": _round(r.static_rmse_n),
            "rate_rmse_n": _round(r.rate_rmse_n)}
    return out


def _rmse(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.sqrt(np.mean((a - b) ** 2)))


def _round(x: float) -> float | None:
    return float(f"{x:.4g}") if math.isfinite(x) else None
