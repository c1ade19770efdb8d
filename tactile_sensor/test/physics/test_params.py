from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from tactile_sensor.physics.errors import PhysicsError
from tactile_sensor.physics.params import PhysicsParams


def test_defaults_are_the_paper_material():
    p = PhysicsParams()
    assert p.c01 == pytest.approx(1.218e4) and p.c10 == pytest.approx(-33.35)
    assert p.width == pytest.approx(0.022) and p.max_indentation == pytest.approx(0.003)


@pytest.mark.parametrize("bad, match", [
    ({"nope": 1}, "Unknown physics parameter 'nope'"),
    ({"height": "tall"}, "'height' must be a float"),
    ({"height": -1}, "'height' is -1"),
    ({"steps": 2.5}, "'steps' must be a int"),
    ({"boundary": "glued"}, "'boundary'"),
    ({"c10": -20000.0}, "shear modulus"),
    ({"pigment_white": 120}, "'pigment_white'"),
    ({"prony_tau": [1.0]}, "different lengths"),
    ({"width": float("nan")}, "finite"),
    ({"window_center_z": 0.02}, "window"),
])
def test_bad_values_name_the_parameter(bad, match):
    with pytest.raises(PhysicsError, match=match):
        PhysicsParams.from_mapping(bad)


@given(h=st.floats(0.02, 0.05), g=st.floats(0.001, 0.003))
def test_digest_changes_with_curve_fields_only(h, g):
    p = PhysicsParams().replace(height=h, gap=g)
    assert p.digest() == PhysicsParams.from_mapping(p.to_dict()).digest()
    assert p.digest() != p.replace(height=h + 1e-3).digest()
    assert p.digest() == p.replace(prony_g=(0.1, 0.2)).digest()


def test_strings_from_the_cli_are_coerced():
    p = PhysicsParams.from_mapping({"height": "0.03", "steps": "20", "prony_g": "0.1,0.2"})
    assert p.height == 0.03 and p.steps == 20 and p.prony_g == (0.1, 0.2)


def test_modules_are_a_set_of_faces_in_one_spelling():
    p = PhysicsParams(modules="right, front,left")
    assert p.modules == "front,left,right" and p.module_faces == ("front", "left", "right")
    assert p.window_faces == ("front", "back", "left", "right")
    assert PhysicsParams.from_mapping({"modules": ["back", "front"]}) == \
        PhysicsParams(modules="front,back")
    assert PhysicsParams(modules="left").window_faces == ("left", "right")


@pytest.mark.parametrize("bad, match", [
    ({"modules": "top"}, "'modules' is 'top'"),
    ({"modules": "front,front"}, "distinct faces"),
    ({"modules": ""}, "'modules'"),
    ({"max_shear_x": 0.001, "boundary": "frictionless"}, "need the bonded boundary"),
    ({"max_indentation": 0.0}, "load path is zero"),
    ({"max_shear_y": "far"}, "'max_shear_y' must be a float"),
    ({"window_width": 0.021, "depth": 0.02}, "'window_width' must be smaller"),
])
def test_bad_shear_and_module_values_name_the_parameter(bad, match):
    with pytest.raises(PhysicsError, match=match):
        PhysicsParams.from_mapping(bad)


def test_new_fields_at_their_defaults_keep_the_cache_key():
    """Caches written before shear and modules existed stay valid for the default curve."""
    base = PhysicsParams()
    assert base.digest() == "fd52094d1d89acb5"
    assert base.replace(max_shear_x=1e-3).digest() != base.digest()
    assert base.replace(modules="front,back").digest() != base.digest()
    assert base.replace(array_steps=3).digest() == base.digest()
    assert base.replace(array_steps=3).grid_digest() != base.grid_digest()
    assert base.replace(height=0.031).grid_digest() != base.grid_digest()
