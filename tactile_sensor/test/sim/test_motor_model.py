"""Motor model: the profile reaches the goal; the current limit stalls the output."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tactile_sensor.sim.motor_model import (
    BACKDRIVE_TORQUE_NM,
    TORQUE_CONSTANT_NM_PER_A,
    MotorCommand,
    MotorModel,
)


def spring(position_of_contact: float, stiffness: float):
    return lambda p: max(0.0, p - position_of_contact) * stiffness


def test_trapezoidal_profile_timing():
    motor = MotorModel(0.0)
    cmd = MotorCommand(True, 2.0, profile_velocity_rad_s=1.0,
                       profile_acceleration_rad_s2=4.0, current_limit_a=1.0)
    motor.step(1.0, cmd)
    assert motor.state.position_rad == pytest.approx(1.0 - 0.125, abs=2e-3)  # 0.25 s ramp
    motor.step(1.5, cmd)
    assert motor.state.position_rad == pytest.approx(2.0)
    assert motor.state.velocity_rad_s == pytest.approx(0.0)


def test_zero_profile_runs_at_no_load_speed():
    motor = MotorModel(0.0)
    motor.step(0.1, MotorCommand(True, 10.0, 0.0, 0.0, 1.0))
    assert motor.state.velocity_rad_s == pytest.approx(77 * 2 * math.pi / 60, rel=1e-6)


@settings(max_examples=40, deadline=None)
@given(st.floats(0.05, 2.0), st.floats(5.0, 200.0))
def test_stall_where_load_equals_available_torque(current_a, stiffness):
    motor = MotorModel(0.0, spring(0.5, stiffness))
    motor.step(3.0, MotorCommand(True, 5.0, 2.0, 0.0, current_a))
    stall_a = 12.0 / (12.0 / 2.3)
    capacity = TORQUE_CONSTANT_NM_PER_A * min(current_a, stall_a)
    assert motor.load_torque(motor.state.position_rad) == pytest.approx(capacity, rel=1e-3)
    assert motor.state.current_a == pytest.approx(capacity / TORQUE_CONSTANT_NM_PER_A)
    assert motor.state.stalled


def test_lowering_the_limit_backs_off_and_torque_off_yields():
    motor = MotorModel(0.0, spring(0.1, 10.0))
    motor.step(2.0, MotorCommand(True, 1.0, 2.0, 0.0, 0.6))
    pressed = motor.state.position_rad
    motor.step(1.0, MotorCommand(True, 1.0, 2.0, 0.0, 0.2))
    assert motor.state.position_rad < pressed
    motor.step(1.0, MotorCommand(False, 1.0, 2.0, 0.0, 0.2))
    assert motor.load_torque(motor.state.position_rad) == pytest.approx(
        BACKDRIVE_TORQUE_NM, rel=1e-3)
    assert motor.state.current_a == 0.0


def test_low_voltage_limits_torque():
    motor = MotorModel(0.0, spring(0.1, 10.0))
    motor.step(2.0, MotorCommand(True, 1.0, 2.0, 0.0, 3.0, input_voltage_v=6.0))
    assert motor.load_torque(motor.state.position_rad) == pytest.approx(
        TORQUE_CONSTANT_NM_PER_A * 6.0 / (12.0 / 2.3), rel=1e-3)
    assert motor.overload_time_s > 1.0     # pushing at the stall current counts to overload
