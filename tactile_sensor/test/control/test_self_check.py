"""The self-check's fit: two factors from one slow close, and each refusal."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tactile_sensor.control.geometry import GripperGeometry
from tactile_sensor.control.self_check import (
    CLOSED_LIMIT_WITHOUT_CONTACT,
    TOO_FEW_SAMPLES,
    TOO_UNCERTAIN,
    ClosingRecord,
    DriveTrain,
    SelfCheckError,
    SkinPrediction,
    fit_self_check,
)

#: A convex skin like the FEM's (about 5 N and 0.4 V at 2.4 mm), 0..3 mm.
D = np.linspace(0.0, 0.003, 16)
PREDICTION = SkinPrediction(tuple(D.tolist()), tuple((1.6e3 * D + 2.6e5 * D**2).tolist()),
                            tuple((150.0 * D + 7e3 * D**2).tolist()))
GEOMETRY = GripperGeometry()
STEP_RAD = 2.0 * math.pi / 4096.0
FREE_CURRENT_A = 0.0188


RIGID = DriveTrain()


def closing(gain: float, stiffness: float, *, lead_m: float = 0.0, train: DriveTrain = RIGID,
            output_noise_v: float = 0.003, current_noise_a: float = 0.0,
            press_m: float = 0.002, seed: int = 0, rod: bool = True,
            free_current_a: float = FREE_CURRENT_A) -> ClosingRecord:
    """A close at 1 mm/s sampled at 100 Hz: 1.5 mm free, then ``press_m`` into finger A's
    skin; finger B touches ``lead_m`` of travel before it. The racks follow the servo
    through the train's play and lag it by its compliance (solved by fixed point)."""
    rng = np.random.default_rng(seed)
    r = GEOMETRY.pitch_radius_m
    speed = GEOMETRY.finger_speed_to_rad_s(0.001)
    ticks = int((0.0015 + press_m) / 0.001 / 0.01)
    exact = 2.0 + speed * 0.01 * np.arange(ticks)
    position = np.round(exact / STEP_RAD) * STEP_RAD
    rack = train.rack_positions_rad(position)
    contact = rack[0] + 0.0015 / r
    force = np.zeros_like(rack)
    for _ in range(30):
        travel = r * (rack - contact) - train.compliance_m_per_n * force
        d_a, d_b = np.maximum(travel, 0.0), np.maximum(travel + lead_m, 0.0)
        force = stiffness * (PREDICTION.force(d_a) + PREDICTION.force(d_b)) if rod else 0 * d_a
    # the load-dependent friction: u (1 - ratio) = skin force x r (sim/drivetrain.py)
    current = free_current_a + force * r / (train.torque_constant_nm_per_a
                                            * (1.0 - train.load_friction_ratio))
    current = current + rng.normal(0.0, current_noise_a, current.size)
    current = np.round(current / 2.69e-3) * 2.69e-3
    out = 0.002 + gain * PREDICTION.output(d_a) * rod + rng.normal(0.0, output_noise_v,
                                                                   d_a.size)
    return ClosingRecord.of(position, np.full(position.size, speed), current, out)


@settings(max_examples=20, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.floats(0.6, 1.3), st.floats(0.7, 1.4), st.floats(-0.0005, 0.0005),
       st.floats(0.0, 0.02), st.floats(0.0, 2e-6), st.integers(0, 1000))
def test_both_factors_come_back_through_play_compliance_and_an_off_centre_object(
        gain, stiffness, lead_m, backlash_rad, compliance, seed):
    train = DriveTrain(backlash_rad=backlash_rad, compliance_m_per_n=compliance)
    record = closing(gain, stiffness, lead_m=lead_m, train=train, seed=seed,
                     press_m=0.002 - max(lead_m, 0.0))
    fit = fit_self_check(record, PREDICTION, train)
    assert fit.optical_gain == pytest.approx(gain, abs=0.03)
    assert fit.stiffness == pytest.approx(stiffness, abs=0.03)
    assert 0.0 < fit.optical_gain_sigma < 0.015 and 0.0 < fit.stiffness_sigma < 0.015


def test_a_servo_whose_load_friction_is_left_out_reads_a_stiffer_skin():
    """The load-dependent friction scales the current as a stiffer skin would: the train's
    ratio is what tells them apart (1 / (1 - 0.234) = 1.31 x without it)."""
    record = closing(1.0, 1.0)
    assert fit_self_check(record, PREDICTION).stiffness == pytest.approx(1.0, abs=0.03)
    lossless = DriveTrain(load_friction_ratio=0.0)
    assert fit_self_check(record, PREDICTION, lossless).stiffness == pytest.approx(
        1.0 / (1.0 - 0.234), abs=0.03)
    with pytest.raises(ValueError, match="load friction ratio"):
        DriveTrain(load_friction_ratio=1.0)


def test_a_map_without_the_trains_compliance_misreads_the_stiffness():
    """The compliance is part of the map: a fit that leaves it out reads a softer skin and
    a dimmer emitter, both past the +-0.03 a correction needs."""
    train = DriveTrain(compliance_m_per_n=1e-5)
    record = closing(1.0, 1.2, train=train)
    assert fit_self_check(record, PREDICTION, train).stiffness == pytest.approx(1.2, abs=0.01)
    rigid = fit_self_check(record, PREDICTION, DriveTrain())
    assert rigid.stiffness < 1.2 - 0.05 and rigid.optical_gain < 1.0 - 0.04


def test_a_free_current_between_two_codes_is_an_uncertainty_not_a_bias():
    """The mock's friction current (0.020 A) reads as 7 codes (0.0188 A): the rack force
    comes out 0.11 N high. Finger B first pins its contact from the force alone and holds;
    the module's finger first leaves finger B's contact to a kink the offset moves, and
    the fit says so instead of reading a stiffer skin."""
    b_first = fit_self_check(closing(1.0, 1.0, lead_m=0.0005, press_m=0.0015,
                                     free_current_a=0.020), PREDICTION)
    assert abs(b_first.stiffness - 1.0) < min(0.03, 3.0 * b_first.stiffness_sigma)
    with pytest.raises(SelfCheckError, match="too uncertain") as err:
        fit_self_check(closing(1.0, 1.0, lead_m=-0.001, free_current_a=0.020), PREDICTION)
    assert err.value.outcome == TOO_UNCERTAIN


def test_the_play_operator_lags_a_close_by_its_width_and_holds_on_a_reversal():
    train = DriveTrain(backlash_rad=0.01)
    servo = np.array([0.0, 0.005, 0.02, 0.03, 0.025, 0.021, 0.019, 0.03])
    assert train.rack_positions_rad(servo).tolist() == pytest.approx(
        [-0.01, -0.005, 0.01, 0.02, 0.02, 0.02, 0.019, 0.02])


def test_the_corrected_curve_scales_output_and_force():
    fit = fit_self_check(closing(0.8, 1.15), PREDICTION)
    out, force = fit.corrected_curve(PREDICTION)
    assert np.all(np.diff(out) > 0)
    assert out[-1] == pytest.approx(fit.optical_gain * PREDICTION.output_v[-1])
    assert force[-1] == pytest.approx(fit.stiffness * PREDICTION.force_n[-1])


def test_no_object_between_the_fingers_ends_at_the_closed_limit_without_contact():
    with pytest.raises(SelfCheckError, match="without touching anything") as err:
        fit_self_check(closing(1.0, 1.0, rod=False), PREDICTION)
    assert err.value.outcome == CLOSED_LIMIT_WITHOUT_CONTACT


def test_a_fit_too_uncertain_to_apply_is_refused():
    record = closing(1.0, 1.0, output_noise_v=0.06, current_noise_a=0.02, seed=3)
    with pytest.raises(SelfCheckError, match="too uncertain to apply") as err:
        fit_self_check(record, PREDICTION)
    assert err.value.outcome == TOO_UNCERTAIN


def test_a_record_too_short_or_too_shallow_is_refused():
    short = closing(1.0, 1.0)
    cut = ClosingRecord(*(a[:12] for a in (short.position_rad, short.velocity_rad_s,
                                           short.current_a, short.output_v)))
    with pytest.raises(SelfCheckError, match="start it with the fingers open") as err:
        fit_self_check(cut, PREDICTION)
    assert err.value.outcome == TOO_FEW_SAMPLES
    with pytest.raises(SelfCheckError, match="close more slowly or further") as err:
        fit_self_check(closing(1.0, 1.0, press_m=0.0001, output_noise_v=0.0), PREDICTION)
    assert err.value.outcome == TOO_FEW_SAMPLES


def test_an_object_far_off_the_centre_is_refused_not_misread():
    record = closing(1.0, 1.0, lead_m=0.0029, press_m=0.0008, output_noise_v=0.0)
    with pytest.raises(SelfCheckError, match="too uncertain to apply") as err:
        fit_self_check(record, PREDICTION)
    assert err.value.outcome == TOO_UNCERTAIN


def test_malformed_inputs_are_refused():
    with pytest.raises(ValueError, match="start at 0"):
        SkinPrediction((0.001, 0.002, 0.003), (0.0, 1.0, 2.0), (0.0, 0.1, 0.2))
    with pytest.raises(ValueError, match="pair up"):
        SkinPrediction((0.0, 0.001), (0.0, 1.0), (0.0, 0.1))
    with pytest.raises(ValueError, match="non-negative backlash"):
        DriveTrain(backlash_rad=-0.1)
    with pytest.raises(ValueError, match="equal length"):
        ClosingRecord.of([0.0, 1.0], [0.0], [0.0, 0.0], [0.0, 0.0])
    record = ClosingRecord.of([0.0, math.nan], [1.0, 1.0], [0.0, 0.0], [0.0, 0.0])
    assert record.position_rad.size == 1  # a sample with a missing value is dropped


@pytest.mark.parametrize("backlash_rad", [0.0044, 0.01])
def test_a_play_changes_no_factor_only_where_finger_a_touched(backlash_rad):
    """A close turns one way, so the play operator shifts every rack position by the play
    alike: the fit's contact takes it up, to the last digit, and both factors stay."""
    record = closing(0.9, 1.1)
    without = fit_self_check(record, PREDICTION, DriveTrain())
    played = fit_self_check(record, PREDICTION, DriveTrain(backlash_rad=backlash_rad))
    assert (played.optical_gain, played.stiffness) == pytest.approx(
        (without.optical_gain, without.stiffness), rel=1e-9)
    assert without.contact_position_rad - played.contact_position_rad == pytest.approx(
        backlash_rad, abs=1e-9)
