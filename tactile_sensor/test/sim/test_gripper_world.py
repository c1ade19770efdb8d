"""Gripper world: geometry, contact, load torque and the photoreflector voltage."""

from __future__ import annotations

import threading

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from tactile_sensor.control.geometry import GripperGeometry
from tactile_sensor.sim.errors import SimError
from tactile_sensor.sim.gripper_world import GripperWorld
from tactile_sensor.sim.held_object import HeldObject, ObjectSpec
from tactile_sensor.sim.skin_response import TabulatedSkin
from tactile_sensor.sim.skin_shear import TangentialStiffness


def skin() -> TabulatedSkin:
    d = np.linspace(0.0, 0.003, 31)
    force = 7.0 * (d / 0.003) ** 1.2
    return TabulatedSkin(d, force, 2.0 - 0.07 * force, thickness_m=0.005)


@given(st.floats(0.002, 0.060))
def test_geometry_round_trip_and_direction(opening):
    g = GripperGeometry()
    position = g.position_rad(opening)
    assert g.opening_m(position) == pytest.approx(opening)
    assert g.opening_m(position + 0.01) < opening           # positive rotation closes


def test_contact_starts_at_the_rod_diameter_and_is_symmetric():
    world = GripperWorld(skin(), rod_diameter_m=0.020)
    g = world.geometry
    assert world.indentations_m(g.position_rad(0.0201)) == (0.0, 0.0)
    a, b = world.indentations_m(g.position_rad(0.018))
    assert a == pytest.approx(0.001) and b == pytest.approx(0.001)
    world.set_rod(0.020, 0.002)                              # rod nearer finger B
    a, b = world.indentations_m(g.position_rad(0.018))
    assert a == 0.0 and b == pytest.approx(0.003)


@given(st.floats(0.0, 0.062), st.floats(0.0, 0.001))
def test_load_torque_is_monotonic_in_closing(opening, delta):
    world = GripperWorld(skin(), rod_diameter_m=0.020)
    g = world.geometry
    p = g.position_rad(opening)
    assert world.load_torque_nm(p + delta) >= world.load_torque_nm(p) - 1e-12


def test_load_torque_is_pitch_radius_times_both_forces():
    world = GripperWorld(skin(), rod_diameter_m=0.020)
    p = world.geometry.position_rad(0.016)
    assert world.load_torque_nm(p) == pytest.approx(0.014 * 2 * skin().force_n(0.002))


def test_closed_limit_is_a_hard_stop_without_rod():
    world = GripperWorld(skin(), rod_diameter_m=None)
    g = world.geometry
    assert world.load_torque_nm(g.closed_position_rad) == 0.0
    assert world.load_torque_nm(g.closed_position_rad + 0.01) > 0.5   # 56 N per 0.28 mm


def test_update_drives_voltage_and_force_history():
    world = GripperWorld(skin(), rod_diameter_m=0.020)
    g = world.geometry
    rest = world.photoreflector_voltage(0.0)
    world.update(1.0, g.position_rad(0.020))
    world.update(2.0, g.position_rad(0.016))
    assert world.photoreflector_voltage(2.0) < rest            # the skin bulges nearer
    assert world.latest.force_a_n == pytest.approx(skin().force_n(0.002))
    assert world.force_at(1.5) == pytest.approx(0.5 * skin().force_n(0.002))
    assert world.force_at(5.0) == world.latest.force_a_n


def test_skin_extrapolates_and_bottoms_out():
    s = skin()
    assert s.force_n(0.004) > s.force_n(0.003)
    assert s.force_n(0.006) - s.force_n(0.005) > 100.0          # resin frame
    assert s.voltage_v(0.004) == s.voltage_v(0.003)


@pytest.mark.parametrize(("d", "f", "v", "match"), [
    ([0.0], [0.0], [1.0], "length ≥ 2"),
    ([0.0, 0.0], [0.0, 1.0], [1.0, 1.0], "strictly increasing"),
    ([0.0, 0.001], [1.0, 0.0], [1.0, 1.0], "must not decrease"),
])
def test_skin_table_validation(d, f, v, match):
    with pytest.raises(SimError, match=match):
        TabulatedSkin(d, f, v)


def test_bad_world_arguments():
    with pytest.raises(ValueError, match="rod_diameter_m"):
        GripperWorld(skin(), rod_diameter_m=-0.01)
    with pytest.raises(ValueError, match="closed_opening_m"):
        GripperGeometry(closed_opening_m=0.1)


def test_reader_thread_sees_consistent_samples():
    world = GripperWorld(skin(), rod_diameter_m=0.020)
    g = world.geometry
    stop, seen = threading.Event(), []

    def reader():
        while not stop.is_set():
            seen.append(world.photoreflector_voltage(0.0))

    thread = threading.Thread(target=reader)
    thread.start()
    for i in range(2000):
        world.update(i * 1e-3, g.position_rad(0.020 - 0.004 * i / 2000))
    stop.set()
    thread.join()
    assert seen and all(1.0 < v <= 2.0 for v in seen)


def held_object() -> HeldObject:
    return HeldObject(ObjectSpec(0.2, 0.3, 0.2), TangentialStiffness([0.001], [340.0]))


def test_an_object_on_its_support_leaves_the_world_as_the_fixed_rod_had_it():
    fixed, holding = GripperWorld(skin()), GripperWorld(skin(), held=held_object())
    g = fixed.geometry
    for i, opening in enumerate(np.linspace(0.030, 0.017, 40).tolist()):
        position, t = g.position_rad(opening), 0.01 * i
        a, b = fixed.update(t, position), holding.update(t, position)
        assert a.held is None
        assert b.held is not None and b.held.position_m == 0.0 and b.held.force_a_n == 0.0
        assert (a.force_a_n, a.force_b_n, a.voltages_v) == (b.force_a_n, b.force_b_n,
                                                           b.voltages_v)
        assert fixed.load_torque_nm(position) == holding.load_torque_nm(position)


def test_a_lifted_object_slips_through_a_light_grip_and_the_normal_force_stays():
    world = GripperWorld(skin(), held=held_object())
    position = world.geometry.position_rad(0.0195)      # 0.25 mm each side: a light grip
    before = world.update(0.0, position)
    assert world.lift()
    samples = [world.update(0.001 * i, position) for i in range(1, 200)]
    assert samples[-1].held.lifted and samples[-1].held.slip_m > 0.001
    assert samples[-1].force_a_n == before.force_a_n
    assert not GripperWorld(skin()).lift()                  # no object: nothing to lift


def test_an_object_that_fell_out_leaves_the_fingers_nothing_to_press():
    held = HeldObject(ObjectSpec(0.3, 0.3, 0.2), TangentialStiffness([0.001], [340.0]),
                      reach_m=0.002)
    world = GripperWorld(skin(), held=held)
    position = world.geometry.position_rad(0.0195)
    world.update(0.0, position)
    world.lift()
    sample = next(s for s in (world.update(0.001 * i, position) for i in range(1, 500))
                  if s.held.dropped)
    assert world.indentations_m(position) == (0.0, 0.0)
    assert world.update(0.6, position).force_a_n == 0.0 and world.load_torque_nm(position) == 0
    assert sample.held.slip_m > 0.002


def test_an_object_needs_a_rod():
    with pytest.raises(ValueError, match="needs a rod diameter"):
        GripperWorld(skin(), rod_diameter_m=None, held=held_object())


class ShearTip:
    """A fingertip with a module on each side face: every output follows the press, the
    left and right ones the shear along x too (right bulges toward its reader)."""

    faces = ("front", "back", "left", "right")
    axes = 3

    def voltages_v(self, indentation_m, shear_x_m=0.0, shear_y_m=0.0):
        press = 20.0 * np.asarray(indentation_m, float)
        shear = 30.0 * np.asarray(shear_x_m, float)
        return 2.0 - np.stack([press, press, press - shear, press + shear], axis=-1)


def test_a_fingertip_that_feels_shear_reads_the_object_pulling_along_the_fingers():
    stiffness = TangentialStiffness([0.001], [340.0])
    held = HeldObject(ObjectSpec(0.1, 1.0, 1.0), stiffness)
    world = GripperWorld(skin(), held=held, fingertip=ShearTip())
    plain = GripperWorld(skin())
    assert world.faces == ShearTip.faces and world.module_voltages(0.0).shape == (4,)
    position = world.geometry.position_rad(0.018)       # 1 mm each side: holds 100 g
    rest = world.update(0.0, position)
    front, _, left, right = rest.voltages_v
    assert left == right == front                       # on its support: press only
    assert world.lift()
    held_sample = [world.update(0.001 * i, position) for i in range(1, 400)][-1]
    assert held_sample.held.slip_m == 0.0               # it sticks
    deflection = held_sample.held.deflection_a_m
    # the force is the last sub-step's, the deflection after it: the object rings
    assert deflection == pytest.approx(held_sample.held.force_a_n / 340.0, rel=0.1)
    assert deflection > 0
    front, _, left, right = held_sample.voltages_v
    assert right < front < left                         # the shear, both ways round
    assert left - right == pytest.approx(60.0 * deflection)
    # the fingers' forces are the skin's, as without the fingertip
    assert held_sample.force_a_n == plain.update(0.0, position).force_a_n
