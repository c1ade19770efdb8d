"""The CalibrationCurve message <-> calibration: static and rate-aware both ways, and every
malformed curve or rate term refused in one sentence naming the source."""

from __future__ import annotations

import pytest

from tactile_sensor.nodes import calibration_curve_msg
from tactile_sensor.sensing.calibration import Calibration
from tactile_sensor.sensing.errors import CalibrationError
from tactile_sensor.sensing.rate_calibration import (
    RateCalibration,
    RateTerm,
    describe_model,
)
from tactile_sensor_interfaces.msg import CalibrationCurve

OUTPUT = [0.0, 0.1, 0.3, 0.5]
FORCE = [0.0, 1.0, 3.5, 7.0]
STATIC = Calibration.from_curve(OUTPUT, FORCE, "fem:abc")


def curve(**fields) -> CalibrationCurve:
    return CalibrationCurve(**{"output": OUTPUT, "force": FORCE, "source": "fem:abc+prony",
                               **fields})


def test_a_static_calibration_has_no_rate_terms_and_comes_back_static():
    msg = calibration_curve_msg.to_msg(STATIC)
    assert list(msg.output) == OUTPUT and list(msg.force) == FORCE
    assert msg.source == "fem:abc"
    assert list(msg.rate_g) == [] and list(msg.rate_tau) == []
    back = calibration_curve_msg.from_msg(msg)
    assert type(back) is Calibration and describe_model(back) == "static"
    assert back.output_v == STATIC.output_v and back.force_n == STATIC.force_n
    assert back.source == "fem:abc"


def test_a_rate_aware_calibration_travels_with_its_terms():
    rate = RateCalibration(Calibration.from_curve(OUTPUT, FORCE, "fem:abc+prony"),
                           [RateTerm(0.05, 0.1), RateTerm(0.04, 1.5)])
    msg = calibration_curve_msg.to_msg(rate)
    assert list(msg.output) == OUTPUT and list(msg.force) == FORCE
    assert list(msg.rate_g) == [0.05, 0.04] and list(msg.rate_tau) == [0.1, 1.5]
    assert msg.source == "fem:abc+prony"
    back = calibration_curve_msg.from_msg(msg)
    assert isinstance(back, RateCalibration)
    assert back.terms == rate.terms and back.static.force_n == STATIC.force_n
    assert back.source == "fem:abc+prony"
    assert describe_model(back) == describe_model(rate)


def test_an_empty_source_is_named_model():
    assert calibration_curve_msg.from_msg(curve(source="")).source == "model"


@pytest.mark.parametrize(("fields", "says"), [
    ({"rate_g": [0.05, 0.04], "rate_tau": [0.1]}, "2 rate moduli (rate_g) but 1 relaxation"),
    ({"rate_g": [], "rate_tau": [0.1]}, "0 rate moduli (rate_g) but 1 relaxation"),
    ({"rate_g": [-0.1], "rate_tau": [0.1]}, "rate term 0 has modulus g=-0.1"),
    ({"rate_g": [float("nan")], "rate_tau": [0.1]}, "rate term 0 has modulus g=nan"),
    ({"rate_g": [0.1], "rate_tau": [0.0]}, "rate term 0 has tau_s=0.0"),
    ({"rate_g": [0.1, 0.1], "rate_tau": [1.0, -2.0]}, "rate term 1 has tau_s=-2.0"),
    ({"rate_g": [0.1] * 4, "rate_tau": [1.0] * 4}, "needs 1 to 3 rate terms, got 4"),
    ({"output": [0.0, 0.1], "force": [0.0]}, "output_v has 2 points but force_n has 1"),
    ({"output": [0.0, 0.0, 0.1], "force": [0.0, 1.0, 2.0]}, "strictly increasing"),
])
def test_a_malformed_curve_is_refused_in_one_sentence(fields, says):
    with pytest.raises(CalibrationError) as info:
        calibration_curve_msg.from_msg(curve(**fields))
    message = str(info.value)
    assert message.startswith("fem:abc+prony: ") and says in message, message
    assert message.count(". ") == 0 and message.endswith("."), message
