"""What the gripper's diagnostics say about its servo (hardware/xm430_health.py)."""

from __future__ import annotations

from tactile_sensor.hardware.health import Level
from tactile_sensor.hardware.xm430 import ServoState
from tactile_sensor.hardware.xm430_health import xm430_health

STATE = ServoState(3.14159, 0.0, 0.1234, 12.04, 31.6, False, frozenset())


def test_ready_with_the_latest_sample():
    health = xm430_health(frozenset(), "", STATE)
    assert (health.level, health.message) == (Level.OK, "ready")
    assert health.values == {"position_rad": "3.1416", "current_a": "0.123",
                             "input_voltage_v": "12.0", "temperature_c": "32",
                             "hardware_error": "none"}


def test_a_hardware_error_outranks_the_bus():
    bits = frozenset({"overload", "overheating"})
    health = xm430_health(bits, "no status packet", STATE)
    assert (health.level, health.message) == (Level.ERROR,
                                              "hardware error: overheating, overload")
    assert health.values["hardware_error"] == "overheating,overload"


def test_an_unreachable_servo_is_an_error_without_values_before_a_sample():
    health = xm430_health(frozenset(), "no status packet", None)
    assert (health.level, health.message, health.values) == (
        Level.ERROR, "no status packet", {})
