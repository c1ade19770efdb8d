"""The bend world: protocols in angles, the actuator's input, the modules' voltages."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tactile_sensor.sim.bend_world import (
    ActuationProfile,
    BendPath,
    BendWorld,
    parse_actuation_profile,
)
from tactile_sensor.sim.errors import SimError


class Response:
    """A smooth stand-in for the FEM's table: joint reads the bend, tip the contact."""

    angle_range_rad = (0.0, math.pi / 2)

    def output_v(self, angle, force):
        a, f = np.broadcast_arrays(np.asarray(angle, float), np.asarray(force, float))
        return np.stack([0.4 * np.sin(0.9 * a) + 0.02 * f, 0.05 * f + 0.05 * a], axis=-1)


class Actuator:
    """A pressure that bends the finger less under a tip contact."""

    def angle_rad(self, pressure, force):
        return np.asarray(pressure, float) / 20_000.0 / (1 + 0.1 * np.asarray(force, float))


def world(path: BendPath, **kw) -> BendWorld:
    return BendWorld(path, Response(), Actuator(), 2.5, ("joint", "tip"), **kw)


@settings(max_examples=20, deadline=None)
@given(f=st.sampled_from([0.1, 0.5, 1.0]), force=st.sampled_from([0.0, 2.0]),
       t=st.floats(0.0, 1.0))
def test_the_finger_follows_the_protocol_angle_under_contact(f, force, t):
    path = BendPath(math.pi / 2, (f,), 2, force, 0.5)
    w = world(path)
    time = t * w.duration_s
    assert w.angle_rad(time) == pytest.approx(float(path.angle(time)), abs=2e-3)
    assert w.tip_force_n(time) == pytest.approx(float(path.tip_force(time)), abs=1e-2)


def test_a_protocol_bends_from_straight_to_its_angle_at_each_frequency():
    path = BendPath(math.pi / 2, (0.5, 1.0), 3, 2.0, 1.0)
    blocks = path.blocks()
    assert [(b[2], b[3]) for b in blocks] == [(0.5, False), (0.5, True), (1.0, False),
                                             (1.0, True)]
    assert blocks[0][1] - blocks[0][0] == pytest.approx(6.0)
    t = np.linspace(0, path.duration_s, 20001)
    assert path.angle(t).max() == pytest.approx(math.pi / 2, abs=1e-4)
    assert path.tip_force(t).max() == pytest.approx(2.0, abs=1e-3)
    assert path.tip_force(t[t < blocks[1][0]]).max() == 0.0


def test_voltages_are_rest_minus_outputs_and_the_truth_is_the_angle():
    w = world(BendPath(1.0, (0.5,), 1, 0.0, 0.5))
    t = np.array([0.0, 1.5])
    v = w.module_voltages(t)
    assert v.shape == (2, 2)
    assert v[0] == pytest.approx([2.5, 2.5])
    assert v[1, 0] == pytest.approx(2.5 - 0.4 * math.sin(0.9 * 1.0), abs=1e-3)
    stage, gauge = w.stage_and_gauge(t)
    assert stage.shape == (2, 1) and gauge.shape == (2, 3)
    assert stage[1, 0] == pytest.approx(1.0, abs=1e-3)


def test_a_users_actuation_profile_drives_the_finger():
    profile = parse_actuation_profile(["0:0", "2:20000", "4:0"])
    w = world(BendPath(rest_s=0.5), actuation=profile)
    assert w.duration_s == pytest.approx(4.5)
    assert w.angle_rad(2.0) == pytest.approx(1.0, abs=1e-3)
    assert w.actuation(1.0) == pytest.approx(10_000.0)


@pytest.mark.parametrize("items, match", [
    (["0:0", "1:nan"], "non-finite"),
    (["0:0", "1:inf"], "non-finite"),
    (["0:0", "1:-5"], "negative"),
    (["0:0", "x"], "not 'seconds:Pa'"),
    (["1:0", "0:5"], "strictly increasing"),
])
def test_a_bad_actuation_profile_is_refused_in_one_sentence(items, match):
    with pytest.raises(SimError, match=match) as info:
        parse_actuation_profile(items)
    assert str(info.value).replace("e.g.", "").count(". ") == 0


def test_an_actuation_beyond_the_fems_range_is_refused():
    with pytest.raises(SimError, match=r"beyond the FEM|outside the FEM"):
        world(BendPath(), actuation=ActuationProfile((0.0, 1.0), (0.0, 60_000.0)))
    with pytest.raises(SimError, match="beyond the FEM"):
        world(BendPath(angle_rad=2.0))


@pytest.mark.parametrize("kw, match", [
    (dict(angle_rad=0.0), "protocol.angle"),
    (dict(frequencies_hz=()), "protocol.frequencies"),
    (dict(frequencies_hz=(50.0,)), "protocol.frequencies"),
    (dict(cycles=0), "protocol.cycles"),
    (dict(tip_force_n=-1.0), "protocol.tip_force"),
    (dict(rest_s=float("nan")), "protocol.rest"),
])
def test_bad_protocol_fields_are_refused(kw, match):
    with pytest.raises(SimError, match=match):
        BendPath(**kw)
