"""What the gripper's self-check needs from ROS: the newest module output, the model's
prediction for the skin (``~/predict``) and the corrected calibration as a curve; here
because only nodes/ may touch message types and services."""

from __future__ import annotations

import threading
from typing import Any

import numpy as np

from tactile_sensor.control.self_check import (
    SelfCheckError,
    SelfCheckFit,
    SkinPrediction,
)
from tactile_sensor.sensing.calibration import Calibration

#: The indentations the prediction is asked at [m]: the FEM sweep's default range.
PREDICTION_INDENTATION_M = np.linspace(0.0, 0.003, 31)
#: How long the model may take to answer [s] (a cached curve answers at once).
PREDICT_TIMEOUT_S = 5.0
MODEL_NOT_READY = "model_not_ready"


class LatestOutput:
    """The driver's module outputs [V] between two control ticks, and when the newest
    came (monotonic [s]): a tick takes their mean, every reading's worth of noise
    averaged (the driver publishes faster than the gripper ticks)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._sum, self._count = 0.0, 0
        self._mean = 0.0
        self._newest_s: float | None = None

    def add(self, output_v: float, at_s: float) -> None:
        with self._lock:
            self._sum += float(output_v)
            self._count += 1
            self._newest_s = at_s

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


def corrected_calibration(fit: SelfCheckFit, prediction: SkinPrediction) -> Calibration:
    """The FEM curve scaled by the fit's factors, named for where it comes from."""
    output, force = fit.corrected_curve(prediction)
    return Calibration(output.tolist(), force.tolist(), (
        f"self_check:gain={fit.optical_gain:.4f}+-{fit.optical_gain_sigma:.4f},"
        f"stiffness={fit.stiffness:.4f}+-{fit.stiffness_sigma:.4f}"))
