"""The bend calibration: fitted on a table of outputs against (angle, tip force), read back."""

from __future__ import annotations

import math

import numpy as np
import pytest
from bend_tables import ANGLES, FORCES, table
from hypothesis import given, settings
from hypothesis import strategies as st

from tactile_sensor.sensing.bend_calibration import (
    BendCalibration,
    bend_layout_refusal,
)
from tactile_sensor.sensing.errors import CalibrationError


def test_one_module_reads_the_angle_without_contact_and_no_force():
    out = table()[:, :, :1]
    cal = BendCalibration.fit(("joint",), ANGLES, FORCES, out)
    assert not cal.separates and "one module" in cal.separation
    est = cal.estimate((float(0.4 * math.sin(0.9 * 0.7)),))
    assert est.angle_rad == pytest.approx(0.7, abs=2e-3)
    assert math.isnan(est.tip_force_n) and est.in_range


@settings(max_examples=40, deadline=None)
@given(angle=st.floats(0.0, math.pi / 2), force=st.floats(0.0, 2.0))
def test_two_modules_separate_bend_and_contact(angle, force):
    cal = BendCalibration.fit(("joint", "tip"), ANGLES, FORCES, table())
    assert cal.separates, cal.separation
    joint = 0.4 * math.sin(0.9 * angle) + 0.02 * force
    tip = 0.05 * force + 0.01 * force ** 2 + 0.05 * angle
    est = cal.estimate((joint, tip))
    assert est.in_range
    assert est.angle_rad == pytest.approx(angle, abs=math.radians(0.5))
    assert est.tip_force_n == pytest.approx(force, abs=0.05)


def test_modules_in_either_order_are_read_joint_first():
    swapped = table()[:, :, ::-1]
    cal = BendCalibration.fit(("tip", "joint"), ANGLES, FORCES, swapped)
    assert cal.modules == ("joint", "tip")


def test_modules_that_vary_alike_cannot_separate_and_say_so():
    cal = BendCalibration.fit(("joint", "tip"), ANGLES, FORCES, table(alike=True))
    assert not cal.separates and "vary alike" in cal.separation
    assert math.isnan(cal.estimate((0.2, 0.1)).tip_force_n)


def test_an_angle_beyond_the_range_is_nan_and_out_of_range():
    cal = BendCalibration.fit(("joint",), ANGLES, FORCES, table()[:, :, :1])
    beyond = cal.estimate((0.6,))  # 0.4 sin(0.9 a) never exceeds 0.4
    assert math.isnan(beyond.angle_rad) and not beyond.in_range
    before = cal.estimate((-0.1,))
    assert math.isnan(before.angle_rad) and not before.in_range
    assert cal.estimate((float("nan"),)).in_range  # not tared: unknown, not out of range


def test_no_joint_module_is_refused_in_one_sentence():
    with pytest.raises(CalibrationError, match="module over the joint") as info:
        BendCalibration.fit(("tip",), ANGLES, FORCES, table()[:, :, 1:])
    assert str(info.value).replace("e.g.", "").count(". ") == 0
    assert bend_layout_refusal(("joint", "tip")) is None


@pytest.mark.parametrize("modules, outputs, match", [
    (("joint", "joint"), table(), "at most"),
    (("joint", "tip"), table()[:, :3], "shape"),
    (("joint",), np.full((ANGLES.size, FORCES.size, 1), np.nan), "non-finite"),
])
def test_bad_tables_are_refused(modules, outputs, match):
    with pytest.raises(CalibrationError, match=match):
        BendCalibration.fit(modules, ANGLES, FORCES, outputs)


def test_a_joint_output_that_turns_back_is_refused():
    a, f = np.meshgrid(ANGLES, FORCES, indexing="ij")
    with pytest.raises(CalibrationError, match="turns back"):
        BendCalibration.fit(("joint",), ANGLES, FORCES, np.sin(3 * a)[..., None] + 0 * f[..., None])


def test_the_file_round_trip_keeps_the_estimates(tmp_path):
    cal = BendCalibration.fit(("joint", "tip"), ANGLES, FORCES, table())
    path = tmp_path / "bend.json"
    cal.to_file(path)
    back = BendCalibration.from_file(path)
    assert back.estimate((0.2, 0.05)) == cal.estimate((0.2, 0.05))
    assert back.source == f"file:{path}"
    path.write_text("{}")
    with pytest.raises(CalibrationError, match="not a bend calibration"):
        BendCalibration.from_file(path)
    with pytest.raises(CalibrationError, match="Cannot read"):
        BendCalibration.from_file(tmp_path / "missing.json")


def test_noise_just_past_the_curves_top_reads_the_top_angle():
    cal = BendCalibration.fit(("joint",), ANGLES, FORCES, table()[:, :, :1])
    top = 0.4 * math.sin(0.9 * math.pi / 2)
    est = cal.estimate((top + 0.02,))  # within four times the paper's noise
    assert est.in_range and est.angle_rad == pytest.approx(math.pi / 2)
