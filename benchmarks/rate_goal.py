"""The rate-aware calibration's goal per speed and phase, as the rate benchmarks state and
judge it: the rate-aware model error at most ``GOAL_RATIO`` times the static one and at most
``GOAL_SHARE_FS`` of full scale, the model error being the error low-passed at
``MODEL_CUTOFF_HZ`` (``analysis/rate/evaluation.py`` holds the numbers)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tactile_sensor"))

from tactile_sensor.analysis.rate.evaluation import (
    GOAL_RATIO,
    GOAL_SHARE_FS,
    MODEL_CUTOFF_HZ,
)

RATIO_TEXT = f"{GOAL_RATIO:g} x static"
SHARE_TEXT = f"{100 * GOAL_SHARE_FS:g} % FS"
CUTOFF_TEXT = f"low-passed at {MODEL_CUTOFF_HZ:g} Hz"
MODEL_ERROR_TEXT = f"model error {CUTOFF_TEXT}"
#: The goal of one row, as the results files give it.
GOAL_TEXT = f"<= {RATIO_TEXT} and <= {SHARE_TEXT}"


def limit_n(full_scale_n: float) -> float:
    """The goal's absolute bound [N]."""
    return GOAL_SHARE_FS * full_scale_n


def ratio_bound_n(static_n: np.ndarray) -> np.ndarray:
    """The goal's bound relative to the static model error [N]."""
    return GOAL_RATIO * static_n


def within_goal(rate_n: float, static_n: float, full_scale_n: float) -> bool:
    return rate_n <= min(GOAL_RATIO * static_n, limit_n(full_scale_n))


def goal_line(full_scale_n: float) -> str:
    """The goal per row in words and newtons, for a table's header."""
    return (f"full scale {full_scale_n:.3f} N; goal per row: rate-aware {GOAL_TEXT} = "
            f"{limit_n(full_scale_n):.3f} N ({MODEL_ERROR_TEXT})")
