"""Rig settings that cannot go together: each refused in one sentence, the rest accepted."""

from __future__ import annotations

import re

import pytest

from tactile_sensor.sim.rig_refusals import RigSettings, lift_refusal, rig_refusal

WRENCH = 8


@pytest.mark.parametrize(("rig", "names"), [
    (RigSettings("bench", 1, has_object=True, rod_diameter_m=0.02), "held by the gripper"),
    (RigSettings("gripper", 1, has_object=True), "give rod.diameter > 0 m"),
    (RigSettings("bench", 1, scenario="office", dark=False), "sets the light itself"),
    (RigSettings("gripper", WRENCH, tilt_rad=0.05), "needs the bench world"),
    (RigSettings("bench", 4, twist_rad=0.05), "at least 6 modules"),
    (RigSettings("bench", 4, stiffness_ratio=1.15), "single-module skin"),
    (RigSettings("gripper", 4, stiffness_ratio=1.15), "single-module skin"),
    (RigSettings("bench", 1, shear_m=0.001), "needs a module array"),
])
def test_each_impossible_rig_is_one_sentence_naming_the_fix(rig, names):
    refusal = rig_refusal(rig)
    assert refusal is not None and names in refusal and refusal.endswith(".")
    assert re.search(r"\. [A-Z]", refusal) is None  # one sentence


@pytest.mark.parametrize("rig", [
    RigSettings("bench", 1),
    RigSettings("bench", 1, stiffness_ratio=1.15, scenario="office"),
    RigSettings("gripper", 1, has_object=True, rod_diameter_m=0.02, stiffness_ratio=0.9),
    RigSettings("bench", 4, shear_m=0.001),
    RigSettings("gripper", 4, has_object=True, rod_diameter_m=0.02),
    RigSettings("bench", WRENCH, shear_m=0.001, tilt_rad=0.05, twist_rad=0.05),
])
def test_the_rigs_that_can_run_are_accepted(rig):
    assert rig_refusal(rig) is None


@pytest.mark.parametrize(("mock", "has_object", "names"), [
    (True, False, "object.mass_kg is 0"),
    (False, True, "run it on mock hardware"),
])
def test_a_lift_without_an_object_or_the_mock_is_one_sentence(mock, has_object, names):
    refusal = lift_refusal(mock, has_object)
    assert refusal is not None and names in refusal and refusal.endswith(".")
    assert re.search(r"\. [A-Z]", refusal) is None
    assert lift_refusal(True, True) is None
