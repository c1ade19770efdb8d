"""``ArrayCalibration`` (sensing/) <-> its message, for the model node that latches it and
the driver that uses it; here because only nodes/ may touch message types."""

from __future__ import annotations

import numpy as np

from tactile_sensor.sensing.array_calibration import ArrayCalibration
from tactile_sensor_interfaces.msg import ArrayCalibration as ArrayCalibrationMsg


def to_msg(calibration: ArrayCalibration) -> ArrayCalibrationMsg:
    """The message (header left for the publisher to stamp); matrices row-major."""
    return ArrayCalibrationMsg(
        faces=list(calibration.faces),
        feature_matrix=[float(v) for v in calibration.feature_matrix.ravel()],
        terms=[int(v) for v in calibration.terms.ravel()],
        force_x=[float(v) for v in calibration.coefficients[0]],
        force_y=[float(v) for v in calibration.coefficients[1]],
        force_z=[float(v) for v in calibration.coefficients[2]],
        torque_x=[float(v) for v in calibration.torque_coefficients[0]]
        if calibration.has_torque else [],
        torque_y=[float(v) for v in calibration.torque_coefficients[1]]
        if calibration.has_torque else [],
        torque_z=[float(v) for v in calibration.torque_coefficients[2]]
        if calibration.has_torque else [],
        force_slow_x=[float(v) for v in calibration.slow_coefficients[0]]
        if calibration.has_slow else [],
        force_slow_y=[float(v) for v in calibration.slow_coefficients[1]]
        if calibration.has_slow else [],
        force_slow_z=[float(v) for v in calibration.slow_coefficients[2]]
        if calibration.has_slow else [],
        observed=list(calibration.observed),
        output_scale_v=float(calibration.output_scale_v),
        output_max_v=[float(v) for v in calibration.output_max_v],
        source=calibration.source)


def from_msg(msg: ArrayCalibrationMsg) -> ArrayCalibration:
    """The calibration; ``CalibrationError`` (one sentence) when the message is malformed.
    Empty torque arrays and ``observed`` read as a force-only calibration (older
    publishers); empty slow-force arrays as none."""
    faces = list(msg.faces)
    m = len(faces)
    matrix = np.asarray(msg.feature_matrix, dtype=float)
    terms = np.asarray(list(msg.terms), dtype=int)
    torque = [list(msg.torque_x), list(msg.torque_y), list(msg.torque_z)]
    slow = [list(msg.force_slow_x), list(msg.force_slow_y), list(msg.force_slow_z)]
    return ArrayCalibration(
        faces, matrix.reshape(m, -1) if m and matrix.size % m == 0 else matrix,
        terms.reshape(-1, m) if m and terms.size % m == 0 else terms,
        [list(msg.force_x), list(msg.force_y), list(msg.force_z)], msg.output_scale_v,
        list(msg.output_max_v), msg.source or "model",
        torque if any(torque) else None, list(msg.observed) or None,
        slow if any(slow) else None)
