"""What the gripper's self-check needs from ROS: the module outputs, the model's prediction
for the skin (``~/predict``) and the correction it latches for the driver; here because
only nodes/ may touch message types and services."""

from __future__ import annotations

import math
import threading
from typing import Any

import numpy as np

from tactile_sensor.control.self_check import (
    SelfCheckError,
    SelfCheckFit,
    SkinPrediction,
)
from tactile_sensor.sensing.calibration_correction import CalibrationCorrection

#: The indentations the prediction is asked at [m]: the FEM sweep's default range.
PREDICTION_INDENTATION_M = np.linspace(0.0, 0.003, 31)
#: How long the model may take to answer [s] (a cached curve answers at once).
PREDICT_TIMEOUT_S = 5.0
MODEL_NOT_READY = "model_not_ready"
#: How long a self-check waits, once the fingers stopped, for the module outputs stamped
#: up to the servo's last sample [s]: readings come late on a busy machine (the driver
#: publishes what it read in a batch); servo samples without them are left out.
KEPT_WAIT_S = 1.0


class LatestOutput:
    """The driver's module outputs [V] between two control ticks, and when the newest
    came (monotonic [s]): a tick takes their mean, every reading's worth of noise
    averaged (the driver publishes faster than the gripper ticks). While a self-check asks
    (``keep``), every output is also kept with its stamp (host time [s] of its ADC
    sample), for pairing with the servo's samples once the close is over."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._came = threading.Condition(self._lock)
        self._sum, self._count = 0.0, 0
        self._mean = 0.0
        self._newest_s: float | None = None
        self._newest_stamp_s = -math.inf
        self._kept: list[tuple[float, float]] | None = None

    def add(self, output_v: float, at_s: float, stamp_s: float = -math.inf) -> None:
        with self._lock:
            self._sum += float(output_v)
            self._count += 1
            self._newest_s = at_s
            self._newest_stamp_s = max(self._newest_stamp_s, stamp_s)
            if self._kept is not None:
                self._kept.append((stamp_s, float(output_v)))
                self._came.notify_all()

    def fresh(self, now_s: float, stale_after_s: float) -> float | None:
        """The mean of the outputs since the last call (the last mean when none came), or
        None when the newest is older than ``stale_after_s``."""
        with self._lock:
            if self._newest_s is None or now_s - self._newest_s > stale_after_s:
                return None
            if self._count:
                self._mean = self._sum / self._count
                self._sum, self._count = 0.0, 0
            return self._mean

    def keep(self, on: bool) -> None:
        """Start keeping every output with its stamp (anew), or stop and forget them."""
        with self._lock:
            self._kept = [] if on else None

    def kept(self, until_s: float, timeout_s: float = KEPT_WAIT_S
             ) -> tuple[list[float], list[float]]:
        """(stamps [s], outputs [V]) kept so far, once one stamped at or after ``until_s``
        came, or after ``timeout_s`` (the ones that came by then)."""
        with self._came:
            self._came.wait_for(lambda: self._newest_stamp_s >= until_s, timeout_s)
            kept = list(self._kept or ())
        return [k[0] for k in kept], [k[1] for k in kept]


def fetch_prediction(client: Any, request: Any) -> SkinPrediction:
    """The model's prediction at ``PREDICTION_INDENTATION_M``; ``SelfCheckError`` (one
    sentence) when the model does not answer or cannot predict yet."""
    if not client.wait_for_service(timeout_sec=PREDICT_TIMEOUT_S):
        raise SelfCheckError(MODEL_NOT_READY, (
            f"The model's prediction service ({client.srv_name}) does not answer; start the "
            "model node (it comes with the gripper configuration)."))
    request.indentation = PREDICTION_INDENTATION_M.tolist()
    done = threading.Event()
    future = client.call_async(request)
    future.add_done_callback(lambda _f: done.set())
    if not done.wait(PREDICT_TIMEOUT_S) or future.result() is None:
        raise SelfCheckError(MODEL_NOT_READY, (
            f"The model did not answer within {PREDICT_TIMEOUT_S:g} s; run the self-check "
            "again once the model logs 'prediction ready'."))
    response = future.result()
    if not response.success:
        raise SelfCheckError(MODEL_NOT_READY, (
            f"The model cannot predict the skin yet ({response.message}); run the "
            "self-check again once it is ready."))
    return SkinPrediction(tuple(PREDICTION_INDENTATION_M.tolist()), tuple(response.force),
                          tuple(response.output))


def correction_of(fit: SelfCheckFit, stamp_s: float) -> CalibrationCorrection:
    """The fit's two factors as a correction over the driver's calibration, named for
    where it comes from."""
    return CalibrationCorrection(
        f"self_check:gain={fit.optical_gain:.4f}+-{fit.optical_gain_sigma:.4f},"
        f"stiffness={fit.stiffness:.4f}+-{fit.stiffness_sigma:.4f}",
        fit.optical_gain, fit.stiffness, stamp_s,
        optical_gain_sigma=fit.optical_gain_sigma, stiffness_sigma=fit.stiffness_sigma)
