"""The servo's drivetrain: its parameters refused in one sentence, and what the servo does
through it (friction in Present Current, an output that sticks, play before the racks)."""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from tactile_sensor.sim.drivetrain import DEFAULT_DRIVETRAIN, Drivetrain, DrivetrainError
from tactile_sensor.sim.gripper_world import GripperWorld
from tactile_sensor.sim.motor_model import TORQUE_CONSTANT_NM_PER_A, MotorCommand, MotorModel
from tactile_sensor.test.emulated_xm430 import linear_skin

PULSE = 2 * math.pi / 4096
NAMES = ("torque_offset_nm", "coulomb_friction_nm", "stribeck_friction_nm",
         "stribeck_velocity_rad_s", "viscous_friction_nm_s", "load_friction_ratio",
         "backlash_rad", "guide_friction_n")


@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize("value", [-0.01, math.nan, math.inf])
def test_a_negative_or_non_finite_parameter_is_refused_by_name(name, value):
    with pytest.raises(DrivetrainError, match=rf"^drivetrain\.{name} = .* must be a finite "
                                              "number >= 0; set it") as refused:
        Drivetrain(**{name: value})
    assert "\n" not in str(refused.value) and str(refused.value).endswith(".")


def test_a_stribeck_velocity_of_zero_is_refused():
    with pytest.raises(DrivetrainError, match="stribeck_velocity_rad_s must be above 0"):
        Drivetrain(stribeck_velocity_rad_s=0.0)


def test_a_load_friction_ratio_of_one_is_refused():
    with pytest.raises(DrivetrainError, match="below 1"):
        Drivetrain(load_friction_ratio=1.0)


def test_a_backlash_as_large_as_the_rods_clearance_is_refused():
    world = GripperWorld(linear_skin(), rod_diameter_m=0.020)
    clearance = world.rod_clearance_rad  # 20 mm of the 60 mm open gap: 20 mm / 14 mm
    assert clearance == pytest.approx(0.020 / 0.014)
    Drivetrain(backlash_rad=0.99 * clearance).check_clearance(clearance)
    with pytest.raises(DrivetrainError, match="as large as the rod's clearance"):
        Drivetrain(backlash_rad=clearance).check_clearance(clearance)
    assert GripperWorld(linear_skin(), rod_diameter_m=None).rod_clearance_rad == math.inf


def test_the_mock_parameters_build_the_drivetrain_and_the_defaults_are_the_sources():
    values = {"drivetrain.backlash_rad": 0.002, "drivetrain.coulomb_friction_nm": 0.05,
              "rod.diameter": 0.02}
    train = Drivetrain.from_parameters(values)
    assert (train.backlash_rad, train.coulomb_friction_nm) == (0.002, 0.05)
    assert train.torque_offset_nm == DEFAULT_DRIVETRAIN.torque_offset_nm
    # XM430-W350 graph's 0.22 N m at the W210's gear; MX-64 M4; 15 arcmin
    assert DEFAULT_DRIVETRAIN.torque_offset_nm == pytest.approx(0.1323, abs=1e-4)
    assert DEFAULT_DRIVETRAIN.backlash_rad == pytest.approx(math.radians(15 / 60))
    assert MotorModel(0.0).drivetrain is DEFAULT_DRIVETRAIN  # on by default


def test_present_current_reads_the_friction_of_a_free_close():
    motor = MotorModel(0.0)
    motor.step(0.5, MotorCommand(True, 2.0, 0.5, 0.0, 1.0))
    train = DEFAULT_DRIVETRAIN
    expected = train.friction_nm(0.5, TORQUE_CONSTANT_NM_PER_A * motor.state.current_a)
    assert motor.state.velocity_rad_s == pytest.approx(0.5)
    assert TORQUE_CONSTANT_NM_PER_A * motor.state.current_a == pytest.approx(expected,
                                                                             rel=1e-3)
    # well over the ideal servo's 0.02 A
    assert motor.state.current_a > 0.1


def test_a_current_under_the_torque_offset_does_not_move_the_output():
    motor = MotorModel(0.0)
    motor.step(1.0, MotorCommand(True, 1.0, 0.5, 0.0, 0.10))
    assert motor.state.position_rad == 0.0
    assert motor.state.current_a == pytest.approx(0.10)


@given(st.floats(0.0, 0.05))
def test_the_output_rests_short_of_its_goal_within_the_friction_at_rest(load_nm):
    """Position control acts through the friction: a goal reached from below leaves the
    output where the P term's torque no longer beats the load and the friction at rest."""
    motor = MotorModel(0.0, lambda p: load_nm)
    motor.step(2.0, MotorCommand(True, 0.5, 0.5, 0.0, 1.0))
    train = DEFAULT_DRIVETRAIN
    lag = 0.5 - motor.state.position_rad
    kp = train.gain_a_per_rad(800) * TORQUE_CONSTANT_NM_PER_A
    motor_nm = kp * lag
    assert motor.state.velocity_rad_s == 0.0
    assert motor_nm - load_nm <= train.friction_nm(0.0, motor_nm) + 1e-6
    assert lag > 10 * PULSE  # the default friction needs over ten pulses of error
    # a goal moved back within the band moves nothing
    rest = motor.state.position_rad
    motor.step(0.5, MotorCommand(True, 0.5 - 0.5 * lag, 0.5, 0.0, 1.0))
    assert motor.state.position_rad == rest


def test_the_racks_lag_the_output_by_the_backlash_after_a_reversal():
    motor = MotorModel(0.0)
    motor.step(2.0, MotorCommand(True, 0.5, 0.5, 0.0, 1.0))
    s = motor.state
    assert s.rack_position_rad == pytest.approx(s.position_rad - DEFAULT_DRIVETRAIN.backlash_rad)
    motor.step(2.0, MotorCommand(True, 0.0, 0.5, 0.0, 1.0))
    assert s.rack_position_rad == pytest.approx(s.position_rad)  # pulled open on the other face


def test_the_ideal_drivetrain_has_no_loss():
    ideal = Drivetrain.ideal()
    assert ideal.friction_nm(0.0, 1.0) == 0.0
    assert ideal.rack_after(0.3, 0.5) == 0.5


def _close_and_open(backlash_rad: float, contact_rad: float
                    ) -> list[tuple[float, float, float]]:
    """(Present Position, Present Current, rack position) each 10 ms of a slow close from 0.25 to
    0.40 rad into a stiffening skin touched near 0.3 rad (about 2 N at the end), and back
    open to 0.25 rad, on the default drivetrain with that play."""
    def skin_nm(rack_rad: float) -> float:
        d = max(0.0, rack_rad - contact_rad) * 0.014  # the indentation [m]
        return 0.014 * (1750.0 * d + 0.5 * 157.0 * 1750.0 * d * d * 1e3)

    motor = MotorModel(0.25, skin_nm, drivetrain=Drivetrain(backlash_rad=backlash_rad))
    record = []
    for goal in (0.40, 0.25):
        for _ in range(200):
            motor.step(0.01, MotorCommand(True, goal, 0.1, 0.0, 1.0))
            s = motor.state
            record.append((s.position_rad, s.current_a, s.rack_position_rad))
    return record


@pytest.mark.parametrize("backlash_rad", [DEFAULT_DRIVETRAIN.backlash_rad,
                                          2 * DEFAULT_DRIVETRAIN.backlash_rad])
def test_a_skin_between_the_fingers_hides_the_play_but_for_where_they_touch(backlash_rad):
    """Why the self-check cannot identify the backlash: the skins push the racks open, so
    they bear on the pinion's closing face closing and opening alike, and the play never
    opens in contact. A close and an opening with the play read, position for position and
    current for current, as a servo without play on an object nearer by the play (to
    within the guide friction, which acts only where the pinion bears: 0.03 of one
    current unit); the object's place is the fit's own unknown, so no close or opening on
    it tells the play."""
    contact = 0.3
    with_play = _close_and_open(backlash_rad, contact)
    without = _close_and_open(0.0, contact + backlash_rad)
    pairs = list(zip(with_play, without, strict=True))
    assert max(abs(a[0] - b[0]) for a, b in pairs) < 0.1 * PULSE
    assert max(abs(a[1] - b[1]) for a, b in pairs) < 1e-4  # a current unit: 2.69 mA
    # and the play is there: in contact the racks trail the encoder by it both ways
    pressed = [(p, rack) for p, _, rack in with_play if rack > contact + 0.01]
    assert len(pressed) > 100
    assert all(p - rack == pytest.approx(backlash_rad, abs=1e-9) for p, rack in pressed)
