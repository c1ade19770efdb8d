"""``CalibrationCorrection`` (sensing/) <-> its message, for the gripper that latches the
self-check's correction and the driver that applies it; here because only nodes/ may touch
message types."""

from __future__ import annotations

from tactile_sensor.sensing.calibration_correction import CalibrationCorrection
from tactile_sensor_interfaces.msg import CalibrationCorrection as CalibrationCorrectionMsg


def to_msg(correction: CalibrationCorrection) -> CalibrationCorrectionMsg:
    """The message, stamped with the correction's time."""
    msg = CalibrationCorrectionMsg(
        source=correction.source, optical_gain=float(correction.optical_gain),
        optical_gain_sigma=float(correction.optical_gain_sigma),
        stiffness=float(correction.stiffness),
        stiffness_sigma=float(correction.stiffness_sigma),
        keep_on_new_calibration=bool(correction.keep_on_new_calibration))
    seconds = int(correction.stamp_s // 1)
    msg.header.stamp.sec = seconds
    msg.header.stamp.nanosec = min(round((correction.stamp_s - seconds) * 1e9), 999_999_999)
    return msg


def from_msg(msg: CalibrationCorrectionMsg) -> CalibrationCorrection:
    """The correction; ``CalibrationError`` (one sentence) when its factors are not usable."""
    return CalibrationCorrection(
        msg.source or "calibration_correction", msg.optical_gain, msg.stiffness,
        msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9,
        msg.keep_on_new_calibration, msg.optical_gain_sigma, msg.stiffness_sigma)
