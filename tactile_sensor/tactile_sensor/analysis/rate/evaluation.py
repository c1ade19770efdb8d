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

from .history import rate_force_history, static_force, zero_phase_low_pass
from .record import PHASES, RateRecord

MODEL_CUTOFF_HZ = 5.0  # a 20 mm/s ramp (0.15 s) still has ~1 cycle; white noise is cut ~10x
GOAL_RATIO = 0.5  # rate-aware RMSE at most half the static curve's ...
GOAL_SHARE_FS = 0.015  # ... and at most 1.5 % of full scale, in every speed and phase


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
    static_model_rmse_n: float = math.nan  # after the low-pass (module docstring)
    rate_model_rmse_n: float = math.nan
    noise_rmse_n: float = math.nan  # what the low-pass removed from the rate-aware estimate

    def meets_goal(self, full_scale_n: float, model: bool) -> bool:
        """The goal on one measure: rate-aware at most ``GOAL_RATIO`` of the static
        error and at most ``GOAL_SHARE_FS`` of full scale."""
        static, rate = ((self.static_model_rmse_n, self.rate_model_rmse_n) if model
                        else (self.static_rmse_n, self.rate_rmse_n))
        return bool(rate <= GOAL_RATIO * static and rate <= GOAL_SHARE_FS * full_scale_n)


def phase_table(record: RateRecord, static: CurveLike, rate: RateCalibration
                ) -> list[PhaseError]:
    """One row per (speed, phase) with samples; the rate-aware force runs over the whole
    record from its start, as the driver's would."""
    static_f = static_force(np.asarray(static.output_v, float), np.asarray(static.force_n, float),
                            record.output_v)
    return phase_errors(record, static_f, rate_force_history(rate, record.t_s, record.output_v))


def phase_errors(record: RateRecord, static_f: np.ndarray, rate_f: np.ndarray
                 ) -> list[PhaseError]:
    """``phase_table`` for estimates already run over the record: any model, exact ones
    included, scored the same way."""
    period = float(np.median(np.diff(record.t_s)))
    smooth = [zero_phase_low_pass(period, MODEL_CUTOFF_HZ, x)
              for x in (static_f, rate_f, record.force_n)]
    rows = []
    for speed in record.speeds():
        for code, name in PHASES.items():
            keep = record.mask([speed], code)
            if not np.any(keep):
                continue
            model = (math.nan, math.nan, math.nan)
            if all(x is not None for x in smooth):
                ls, lr, lg = smooth
                assert ls is not None and lr is not None and lg is not None
                model = (_rmse(ls[keep], lg[keep]), _rmse(lr[keep], lg[keep]),
                         _rmse(rate_f[keep], lr[keep]))
            rows.append(PhaseError(speed, name, int(np.count_nonzero(keep)),
                                   _rmse(static_f[keep], record.force_n[keep]),
                                   _rmse(rate_f[keep], record.force_n[keep]), *model))
    return rows


def table_dict(rows: list[PhaseError]) -> dict[str, dict[str, dict[str, Any]]]:
    """JSON-ready: speed key -> phase -> samples, both per-sample RMSEs [N] and both model
    errors (``*_model_rmse_n``, low-passed) with the noise the low-pass removed."""
    out: dict[str, dict[str, dict[str, Any]]] = {}
    for r in rows:
        out.setdefault(str(float(f"{r.speed_mm_s:.2g}")), {})[r.phase] = {
            "samples": r.samples, "static_rmse_n": _round(r.static_rmse_n),
            "rate_rmse_n": _round(r.rate_rmse_n),
            "static_model_rmse_n": _round(r.static_model_rmse_n),
            "rate_model_rmse_n": _round(r.rate_model_rmse_n),
            "noise_rmse_n": _round(r.noise_rmse_n)}
    return out


def _rmse(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.sqrt(np.mean((a - b) ** 2)))


def _round(x: float) -> float | None:
    return float(f"{x:.4g}") if math.isfinite(x) else None
