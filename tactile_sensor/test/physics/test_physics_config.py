"""config/physics.yaml states the physics defaults the code uses, so the file a user edits
and the model that runs without it never disagree."""

from __future__ import annotations

import yaml

from tactile_sensor.configurations import config_dir
from tactile_sensor.physics.params import PhysicsParams


def test_physics_yaml_matches_the_defaults():
    data = yaml.safe_load((config_dir() / "physics.yaml").read_text())
    values = data["/**"]["ros__parameters"]
    assert set(values) == set(PhysicsParams.names())
    assert PhysicsParams.from_mapping(values) == PhysicsParams()
