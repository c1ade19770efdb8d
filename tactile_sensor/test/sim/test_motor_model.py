"""Motor model: the profile reaches the goal; the current limit stalls the output (the ideal
servo, ``drivetrain=None``; the drivetrain's own behaviour is test_drivetrain.py's)."""

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
    motor = MotorModel(0.0, drivetrain=None)
    cmd = MotorCommand(True, 2.0, profile_velocity_rad_s=1.0,
                       profile_acceleration_rad_s2=4.0, current_limit_a=1.0)
    motor.step(1.0, cmd)
    assert motor.state.position_rad == pytest.approx(1.0 - 0.125, abs=2e-3)  # 0.25 s ramp
    motor.step(1.5, cmd)
    assert motor.state.position_rad == pytest.approx(2.0)
    assert motor.state.velocity_rad_s == pytest.approx(0.0)


def test_zero_profile_runs_at_no_load_speed():
    motor = MotorModel(0.0, drivetrain=None)
    motor.step(0.1, MotorCommand(True, 10.0, 0.0, 0.0, 1.0))
    assert motor.state.velocity_rad_s == pytest.approx(77 * 2 * math.pi / 60, rel=1e-6)


@settings(max_examples=40, deadline=None)
@given(st.floats(0.05, 2.0), st.floats(5.0, 200.0))
def test_stall_where_load_equals_available_torque(current_a, stiffness):
    motor = MotorModel(0.0, spring(0.5, stiffness), drivetrain=None)
    motor.step(3.0, MotorCommand(True, 5.0, 2.0, 0.0, current_a))
    stall_a = 12.0 / (12.0 / 2.3)
    capacity = TORQUE_CONSTANT_NM_PER_A * min(current_a, stall_a)
    assert motor.load_torque(motor.state.position_rad) == pytest.approx(capacity, rel=1e-3)
    assert motor.state.current_a == pytest.approx(capacity / TORQUE_CONSTANT_NM_PER_A)
    assert motor.state.stalled


def test_lowering_the_limit_backs_off_and_torque_off_yields():
    motor = MotorModel(0.0, spring(0.1, 10.0), drivetrain=None)
    motor.step(2.0, MotorCommand(True, 1.0, 2.0, 0.0, 0.6))
    pressed = motor.state.position_rad
    motor.step(1.0, MotorCommand(True, 1.0, 2.0, 0.0, 0.2))
    assert motor.state.position_rad < pressed
    motor.step(1.0, MotorCommand(False, 1.0, 2.0, 0.0, 0.2))
    assert motor.load_torque(motor.state.position_rad) == pytest.approx(
        BACKDRIVE_TORQUE_NM, rel=1e-3)
    assert motor.state.current_a == 0.0


def test_low_voltage_limits_torque():
    motor = MotorModel(0.0, spring(0.1, 10.0), drivetrain=None)
    motor.step(2.0, MotorCommand(True, 1.0, 2.0, 0.0, 3.0, input_voltage_v=6.0))
    assert motor.load_torque(motor.state.position_rad) == pytest.approx(
        TORQUE_CONSTANT_NM_PER_A * 6.0 / (12.0 / 2.3), rel=1e-3)
    assert motor.overload_time_s > 1.0     # pushing at the stall current counts to overload


def test_no_time_no_change():
    motor = MotorModel(1.0, drivetrain=None)
    before = (motor.state.position_rad, motor.state.velocity_rad_s)
    for dt in (0.0, -0.01):
        motor.step(dt, MotorCommand(True, 2.0, 1.0, 0.0, 1.0))
    assert (motor.state.position_rad, motor.state.velocity_rad_s) == before


def test_a_new_goal_starts_from_the_present_velocity():
    """Velocity override (XM430 e-manual, Profile Velocity): a goal written while moving
    makes a profile that starts at the present trajectory velocity. With a finite Profile
    Acceleration a goal behind a moving output is overshot and then approached from the
    other side; with Profile Acceleration 0 (rectangular profile) the trajectory stops at
    once, which is why the gripper's stop writes acceleration 0."""
    ramp = MotorModel(0.0, drivetrain=None)
    ramp.step(0.5, MotorCommand(True, 5.0, 1.0, 0.0, 1.0))
    here = ramp.state.position_rad
    ramp.step(0.05, MotorCommand(True, here, 1.0, 10.0, 1.0))
    assert ramp.state.position_rad > here + 0.03  # still going: 1 rad/s at 10 rad/s^2
    ramp.step(2.0, MotorCommand(True, here, 1.0, 10.0, 1.0))
    assert ramp.state.position_rad == pytest.approx(here)

    step = MotorModel(0.0, drivetrain=None)
    step.step(0.5, MotorCommand(True, 5.0, 1.0, 0.0, 1.0))
    here = step.state.position_rad
    step.step(0.001, MotorCommand(True, here, 1.0, 0.0, 1.0))
    assert step.state.position_rad == pytest.approx(here)
    assert step.state.velocity_rad_s == 0.0
