"""ArrayCalibration <-> its message: six columns and ``observed`` both ways, a force-only
calibration as older publishers send it, and a malformed torque column refused."""

from __future__ import annotations

import numpy as np
import pytest

from tactile_sensor.nodes import array_calibration_msg
from tactile_sensor.sensing.array_calibration import ArrayCalibration
from tactile_sensor.sensing.errors import CalibrationError

FACES = ("front@-0.0055", "front@0.0055", "back@-0.0055", "back@0.0055")


def calibration(torque: bool) -> ArrayCalibration:
    rng = np.random.default_rng(0)
    o = rng.uniform(0.0, 0.4, (200, 4))
    wrench = np.column_stack([o @ rng.normal(size=(4, 6 if torque else 3))])
    return ArrayCalibration.fit(FACES, o, wrench, 2, "test",
                                observed=["fx", "fy", "fz", "tz"] if torque else None,
                                slow_forces=o @ rng.normal(size=(4, 3)) if torque else None)


def test_a_six_column_calibration_round_trips_through_its_message():
    cal = calibration(torque=True)
    msg = array_calibration_msg.to_msg(cal)
    assert list(msg.observed) == ["fx", "fy", "fz", "tz"] and len(msg.torque_z) == 15
    back = array_calibration_msg.from_msg(msg)
    assert back.observed == cal.observed and back.faces == FACES and back.has_torque
    assert cal.has_slow and back.has_slow and len(msg.force_slow_y) == 15
    outputs = np.random.default_rng(1).uniform(0.0, 0.4, (10, 4))
    np.testing.assert_allclose(back.wrenches(outputs), cal.wrenches(outputs), rtol=1e-12,
                               atol=1e-12)


def test_a_force_only_message_reads_as_forces_with_nan_torque():
    msg = array_calibration_msg.to_msg(calibration(torque=False))
    assert list(msg.torque_x) == [] and list(msg.observed) == ["fx", "fy", "fz"]
    assert list(msg.force_slow_x) == []
    msg.observed = []                      # as a publisher that predates the field sends it
    back = array_calibration_msg.from_msg(msg)
    assert back.observed == ("fx", "fy", "fz") and not back.has_torque
    assert np.isnan(back.wrench([0.1] * 4)[3:]).all()


def test_torque_columns_of_the_wrong_length_are_one_sentence():
    msg = array_calibration_msg.to_msg(calibration(torque=True))
    msg.torque_y = [1.0, 2.0]
    with pytest.raises(CalibrationError, match=r"torque columns need one coefficient per "
                                               r"term \(15\) for each of x, y and z; refit"):
        array_calibration_msg.from_msg(msg)
