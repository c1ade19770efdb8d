"""``Calibration`` / ``RateCalibration`` (sensing/) <-> the ``CalibrationCurve`` message, for
the model node that latches it and the driver that uses it; here because only nodes/ may
touch message types. Empty rate terms mean a static curve (every older publisher's)."""

from __future__ import annotations

from tactile_sensor.sensing.calibration import Calibration
from tactile_sensor.sensing.errors import CalibrationError
from tactile_sensor.sensing.rate_calibration import RateCalibration, RateTerm
from tactile_sensor_interfaces.msg import CalibrationCurve


def to_msg(calibration: Calibration | RateCalibration) -> CalibrationCurve:
    """The message (header left for the publisher to stamp)."""
    rate = calibration if isinstance(calibration, RateCalibration) else None
    static = rate.static if rate is not None else calibration
    return CalibrationCurve(
        output=[float(v) for v in static.output_v],
        force=[float(v) for v in static.force_n],
        source=calibration.source,
        rate_g=[float(v) for v in rate.g] if rate is not None else [],
        rate_tau=[float(v) for v in rate.tau_s] if rate is not None else [])


def from_msg(msg: CalibrationCurve) -> Calibration | RateCalibration:
    """A ``RateCalibration`` when the message has rate terms, else the static
    ``Calibration``; ``CalibrationError`` (one sentence) when it is malformed."""
    source = msg.source or "model"
    static = Calibration.from_curve(list(msg.output), list(msg.force), source)
    g, tau = [float(v) for v in msg.rate_g], [float(v) for v in msg.rate_tau]
    if not g and not tau:
        return static
    if len(g) != len(tau):
        raise CalibrationError(f"{source}: the curve has {len(g)} rate moduli (rate_g) but "
                               f"{len(tau)} relaxation times (rate_tau); they must pair up.")
    return RateCalibration(static, [RateTerm(a, b) for a, b in zip(g, tau, strict=True)])
