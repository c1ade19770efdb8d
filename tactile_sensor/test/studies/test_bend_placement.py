"""The bending finger's placement study: its spec, refused in one sentence when wrong, and
its metrics on a made-up response (the FEM behind it is tested in physics/test_bend.py)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tactile_sensor.studies.bend_placement import (
    is_bend_spec,
    load_bend_spec,
    measure,
    parse_bend_spec,
)
from tactile_sensor.studies.spec import StudySpecError

SPEC = Path(__file__).resolve().parents[2] / "config" / "studies" / "bend_placement.yaml"


def test_the_shipped_spec_parses() -> None:
    spec = load_bend_spec(SPEC)
    assert len(spec.designs) == 4
    assert all(layout[1].face == "lateral" for layout in spec.layouts())


@pytest.mark.parametrize(("data", "match"), [
    ({"kind": "bend_placement", "window_positions_m": [0.005], "colour": 1}, "unknown key"),
    ({"kind": "bend_placement"}, "needs 'window_positions_m' or 'around'"),
    ({"kind": "bend_placement", "window_positions_m": ["a"]}, "list of numbers"),
    ({"kind": "bend_placement", "window_positions_m": [0.5]}, "placement is rejected"),
    ({"kind": "bend_placement", "around": [0.01], "forces_n": [1.0, 2.0]}, "rise from 0"),
    ({"kind": "bend_placement", "around": [0.01], "noise_v": -1}, "positive number"),
    ({"kind": "bend_placement", "around": [0.01], "geometry": {"nope": 1}}, "unknown finger"),
    ({"kind": "bend_placement", "around": [0.01], "geometry": {"joint_length": -1}},
     "'geometry' is rejected"),
])
def test_bad_specs_are_refused_in_one_sentence(data: dict, match: str) -> None:
    with pytest.raises(StudySpecError, match=match):
        parse_bend_spec(data)


def test_only_a_bend_kind_is_a_bend_spec() -> None:
    assert is_bend_spec({"kind": "bend_placement"})
    assert not is_bend_spec({"vary": {}})
    assert not is_bend_spec(["kind"])


def test_metrics_of_a_made_up_response() -> None:
    from tactile_sensor.physics.bend import BendGeometry, BendResponse, default_modules

    angles, forces = np.linspace(0.0, 1.65, 12), np.array([0.0, 0.25, 0.5])
    a, f = np.meshgrid(angles, forces, indexing="ij")
    gap = np.stack([0.002 + 4e-4 * a + 1e-4 * f, 0.002 - 4e-4 * f], axis=-1)
    response = BendResponse(BendGeometry(), default_modules(), angles, forces, gap,
                            1.2 * a + 1.5 * f)
    metrics, curve, sigma = measure(response, 0.013)
    assert metrics["sensitivity_v_per_rad"] == pytest.approx(
        (curve[-1] - curve[0]) / (np.pi / 2))
    assert metrics["jacobian_condition"] >= 1.0
    assert len(sigma) == len(curve) == 19
