"""The household object set: named, sourced values inside silicone's friction range."""

from __future__ import annotations

import pytest

from tactile_sensor.sim.errors import SimError
from tactile_sensor.sim.object_set import HOUSEHOLD_OBJECTS, HouseholdObject


def test_the_set_spans_at_least_twenty_objects_with_some_held_out() -> None:
    assert len(HOUSEHOLD_OBJECTS) >= 20
    assert len({o.name for o in HOUSEHOLD_OBJECTS}) == len(HOUSEHOLD_OBJECTS)
    held_out = [o for o in HOUSEHOLD_OBJECTS if o.held_out]
    assert 0 < len(held_out) < len(HOUSEHOLD_OBJECTS) // 2


def test_each_object_is_a_valid_held_object_inside_the_source_range() -> None:
    for obj in HOUSEHOLD_OBJECTS:
        spec = obj.spec()
        assert 0.25 <= spec.friction_static <= 1.0
        assert spec.friction_kinetic <= spec.friction_static
        assert 0.01 < obj.mass_kg < 1.0


def test_a_bad_object_is_refused_in_one_sentence() -> None:
    with pytest.raises(SimError, match="finite mass"):
        HouseholdObject("x", 0.0, "wood")
    with pytest.raises(SimError, match="use one of"):
        HouseholdObject("x", 0.1, "glass")
