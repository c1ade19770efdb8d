"""The finger's physics as the mock's world and the driver's calibration agree: both read
one ``BendResponse`` (here built from a small grid of gaps and tensions, not solved)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tactile_sensor.nodes import bend_physics
from tactile_sensor.physics.bend import DEFAULT_MODULES, BendGeometry, BendResponse
from tactile_sensor.sim.bend_world import BendPath
from tactile_sensor.sim.errors import SimError

ANGLES = np.linspace(0.0, 1.75, 15)
FORCES = np.array([0.0, 0.55, 1.1, 1.65, 2.2])


def response() -> BendResponse:
    a, f = np.meshgrid(ANGLES, FORCES, indexing="ij")
    joint = 0.002 - 0.0006 * np.sin(0.8 * a) - 0.00005 * f   # the joint's skin rises
    tip = 0.002 - 0.0003 * f - 0.00003 * a                      # the pad bulges under contact
    tension = 5.0 * a + 1.5 * f * (1 + a)
    return BendResponse(BendGeometry(), DEFAULT_MODULES, ANGLES, FORCES,
                        np.stack([joint, tip], axis=-1), tension)


@pytest.fixture
def fem(monkeypatch):
    r = response()
    monkeypatch.setattr(bend_physics, "load_response", lambda *a, **k: r)
    return r


def values(**kw):
    base = {"bend.modules": "joint,tip", "bend.actuation_profile": [],
            "protocol.angle": 1.5708, "protocol.frequencies": [0.5], "protocol.cycles": 2,
            "protocol.tip_force": 2.0, "protocol.rest": 0.5}
    return {**base, **kw}


def test_the_driver_reads_back_the_worlds_angle_and_force(fem):
    world = bend_physics.bend_world(values(), None)
    cal = bend_physics.fem_bend_calibration(("joint", "tip"))
    assert cal.separates, cal.separation
    rest = world.module_voltages(np.zeros(1))[0]
    for t in np.linspace(1.0, world.duration_s - 1.0, 25):
        outputs = rest - world.module_voltages(np.array([t]))[0]
        est = cal.estimate(tuple(outputs))
        assert est.angle_rad == pytest.approx(float(world.angle_rad(t)), abs=math.radians(0.5))
        assert est.tip_force_n == pytest.approx(float(world.tip_force_n(t)), abs=0.05)


def test_the_tendon_holds_the_protocols_angles(fem):
    world = bend_physics.bend_world(values(**{"protocol.tip_force": 0.0}), None)
    path = BendPath(1.5708, (0.5,), 2, 0.0, 0.5)
    t = np.linspace(0, world.duration_s, 200)
    assert world.angle_rad(t) == pytest.approx(np.minimum(path.angle(t), 1.75), abs=1e-6)
    assert world.actuation(1.5) == pytest.approx(5.0 * float(world.angle_rad(1.5)), rel=1e-3)


def test_a_tension_profile_drives_the_finger_and_a_negative_one_is_refused(fem):
    world = bend_physics.bend_world(values(**{"bend.actuation_profile": ["0:0", "2:5", "4:0"],
                                              "protocol.tip_force": 0.0}), None)
    assert world.angle_rad(2.0) == pytest.approx(1.0, abs=0.01)
    with pytest.raises(SimError, match="negative"):
        bend_physics.bend_world(values(**{"bend.actuation_profile": ["0:0", "1:-1"]}), None)


def test_one_module_reads_the_angle_only(fem):
    cal = bend_physics.fem_bend_calibration(("joint",))
    assert not cal.separates and cal.full_scale_force_n == 0.0


def test_a_layout_without_the_joint_is_refused(fem):
    with pytest.raises(SimError, match="module over the joint"):
        bend_physics.bend_world(values(**{"bend.modules": "tip"}), None)
