"""The object held between the fingers: stick under the static limit, kinetic slide beyond
it, the slip it integrates, gravity only after the lift, the scripted pull, and the refusals
of a bad object."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tactile_sensor.physics.viscoelastic import RateDependentForce
from tactile_sensor.sim.errors import SimError
from tactile_sensor.sim.held_object import (
    STANDARD_GRAVITY_M_S2,
    HeldObject,
    LoadScript,
    ObjectSpec,
    object_from_values,
    parse_load_profile,
)
from tactile_sensor.sim.skin_shear import TangentialStiffness

#: A skin of constant tangential stiffness [N/m] (the FEM grid's is about this, docs).
K = 340.0
STIFFNESS = TangentialStiffness([0.0005, 0.003], [K, K])
DEPTH = (0.001, 0.001)


def run(obj: HeldObject, normal: tuple[float, float], t0: float, t1: float,
        dt: float = 1e-3) -> list:
    """Step the object as the emulator does (every ~1 ms), returning every state."""
    out = []
    for t in np.arange(t0, t1, dt).tolist():
        out.append(obj.step(t, normal, DEPTH))
    return out


def lifted(spec: ObjectSpec, normal: tuple[float, float], rate: bool = False) -> HeldObject:
    obj = HeldObject(spec, STIFFNESS,
                     (lambda: RateDependentForce((0.05, 0.04), (0.1, 1.5))) if rate else None)
    obj.step(0.0, normal, DEPTH)
    obj.lift()
    return obj


@settings(max_examples=15, deadline=None)
@given(normal=st.floats(1.0, 6.0), mu_s=st.floats(0.3, 1.0), share=st.floats(0.1, 0.8))
def test_the_object_sticks_while_the_load_stays_under_the_static_limit(normal, mu_s, share):
    limit = mu_s * 2 * normal
    mass = 0.05 * limit / STANDARD_GRAVITY_M_S2     # the weight's step rings to 2 x 5 %
    pull = share * limit - mass * STANDARD_GRAVITY_M_S2
    spec = ObjectSpec(mass, mu_s, 0.5 * mu_s, LoadScript((0.0, 2.0), (0.0, pull)))
    obj = lifted(spec, (normal, normal), rate=True)
    states = run(obj, (normal, normal), 0.0, 2.5)
    assert all(s.slip_m == 0.0 for s in states)
    assert all(c.stuck for c in obj.contacts)
    peak = max(abs(s.force_a_n) for s in states)
    assert peak <= mu_s * normal
    # the skins carry the load, deflected by it (within the ringing the weight's step left)
    assert states[-1].position_m == pytest.approx(share * limit / (2 * K),
                                                  abs=mass * STANDARD_GRAVITY_M_S2 / K)


@settings(max_examples=15, deadline=None)
@given(normal=st.floats(0.5, 5.0), mu_s=st.floats(0.3, 1.0), kinetic=st.floats(0.3, 1.0),
       over=st.floats(1.05, 3.0), mass=st.floats(0.05, 0.3))
def test_beyond_the_static_limit_it_slides_at_the_kinetic_friction(normal, mu_s, kinetic,
                                                                   over, mass):
    mu_k = kinetic * mu_s
    weight = mass * STANDARD_GRAVITY_M_S2
    pull = over * mu_s * 2 * normal - weight
    spec = ObjectSpec(mass, mu_s, mu_k, LoadScript((0.0,), (pull,)))
    obj = lifted(spec, (normal, normal))
    states = run(obj, (normal, normal), 0.0, 0.3)
    assert not any(c.stuck for c in obj.contacts)
    sliding = [s for s in states if s.slip_m > 0]
    assert sliding and all(s.force_a_n == pytest.approx(mu_k * normal) for s in sliding[1:])
    assert states[-1].force_b_n == pytest.approx(mu_k * normal)
    # the slip integrates the motion: a = (load - mu_k N) / m once both slide
    a = (weight + pull - mu_k * 2 * normal) / mass
    first, last = sliding[1], states[-1]
    span = 0.3 - 1e-3 - (len(states) - len(sliding) + 1) * 1e-3
    expected = first.velocity_m_s * span + 0.5 * a * span * span
    assert last.slip_m - first.slip_m == pytest.approx(expected, rel=0.02, abs=2e-6)
    assert last.position_m - first.position_m == pytest.approx(last.slip_m - first.slip_m)


def test_a_slide_stops_and_sticks_again_once_the_pull_drops_under_kinetic_friction():
    normal, mu_s, mu_k, mass = 2.0, 0.8, 0.5, 0.1
    weight = mass * STANDARD_GRAVITY_M_S2
    high = 1.2 * mu_s * 2 * normal - weight
    low = 0.5 * mu_k * 2 * normal - weight
    spec = ObjectSpec(mass, mu_s, mu_k, LoadScript((0.0, 0.1, 0.11), (high, high, low)))
    obj = lifted(spec, (normal, normal), rate=True)
    states = run(obj, (normal, normal), 0.0, 1.0)
    slid = states[-1].slip_m
    assert slid > 1e-3                                      # it slid while pulled hard
    assert all(c.stuck for c in obj.contacts)               # then stuck again
    after = [s.slip_m for s in states if s.slip_m == slid]
    assert len(after) > 500                                 # and stayed put for > 0.5 s
    assert max(abs(s.force_a_n) for s in states[-300:]) <= mu_s * normal


def test_gravity_and_the_pull_act_only_after_the_lift():
    spec = ObjectSpec(0.2, 0.3, 0.2, LoadScript((0.0, 1.0), (0.0, 1.0)))
    obj = HeldObject(spec, STIFFNESS)
    normal = (1.0, 1.0)
    states = run(obj, normal, 0.0, 0.5)
    assert obj.load_n(0.4) == 0.0 and not obj.lifted
    assert all(s.position_m == 0.0 and s.slip_m == 0.0 and s.force_a_n == 0.0
               for s in states)
    obj.lift()
    obj.step(0.5, normal, DEPTH)
    assert obj.lifted
    assert obj.load_n(1.0) == pytest.approx(0.2 * STANDARD_GRAVITY_M_S2 + 0.5)
    states = run(obj, normal, 0.501, 0.8)
    assert states[-1].slip_m > 0.0                          # 1.96 N > 0.6 N: it slips
    obj.set_down()
    rest = run(obj, normal, 0.8, 0.9)
    assert {s.position_m for s in rest} == {rest[0].position_m} and not obj.lifted


def test_a_finger_that_lets_go_stops_holding_and_the_object_falls():
    spec = ObjectSpec(0.1, 1.0, 0.8)
    obj = lifted(spec, (2.0, 2.0))
    held = run(obj, (2.0, 2.0), 0.0, 0.2)[-1]
    state = run(obj, (0.0, 0.0), 0.2, 0.3)[-1]        # free from 0.199 s to 0.299 s
    assert state.force_a_n == 0.0 and state.force_b_n == 0.0 and state.slip_m == 0.0
    assert state.velocity_m_s - held.velocity_m_s == pytest.approx(
        STANDARD_GRAVITY_M_S2 * 0.1, rel=1e-6)


@settings(max_examples=30, deadline=None)
@given(st.lists(st.tuples(st.floats(0.0, 100.0), st.floats(-50.0, 50.0)), min_size=1,
                max_size=6, unique_by=lambda p: p[0]), st.floats(-10.0, 200.0))
def test_the_profile_is_linear_between_its_points_and_flat_outside(points, t):
    points.sort()
    script = parse_load_profile([f"{a!r}:{b!r}" for a, b in points])
    times, forces = zip(*points, strict=True)
    for a, b in points:
        assert script.force_n(a) == pytest.approx(b)
    if t <= times[0]:
        assert script.force_n(t) == pytest.approx(forces[0])
    elif t >= times[-1]:
        assert script.force_n(t) == pytest.approx(forces[-1])
    else:
        i = next(i for i, a in enumerate(times) if a >= t)
        w = (t - times[i - 1]) / (times[i] - times[i - 1])
        assert script.force_n(t) == pytest.approx(forces[i - 1] + w * (forces[i] - forces[i - 1]),
                                                  abs=1e-9)


def test_no_profile_is_no_pull():
    assert parse_load_profile([]).force_n(3.0) == 0.0


@pytest.mark.parametrize(("entries", "sentence"), [
    (["1:nan"], "non-finite value"),
    (["inf:1"], "non-finite value"),
    (["1:0.5", "1:0.7"], "strictly increasing"),
    (["-1:0.5"], "must be >= 0 s"),
    (["soon:1"], "is not 'time:newtons'"),
    (["1"], "is not 'time:newtons'"),
])
def test_a_bad_profile_is_refused_in_one_sentence(entries, sentence):
    with pytest.raises(SimError) as error:
        parse_load_profile(entries)
    assert sentence in str(error.value) and "\n" not in str(error.value)


@pytest.mark.parametrize(("mass", "mu_s", "mu_k", "sentence"), [
    (0.1, 0.0, 0.0, "object.friction_static = 0.0 must be a finite friction coefficient > 0"),
    (0.1, 0.5, -0.1, "object.friction_kinetic = -0.1 must be"),
    (0.0, -0.5, 0.3, "object.friction_static = -0.5 must be"),   # checked without an object
    (0.1, 0.5, 0.6, "kinetic friction must not exceed static"),
    (0.0, 0.5, 0.6, "kinetic friction must not exceed static"),
    (0.1, math.nan, 0.3, "must be a finite friction coefficient"),
])
def test_bad_friction_is_refused_in_one_sentence(mass, mu_s, mu_k, sentence):
    with pytest.raises(SimError) as error:
        object_from_values(mass, mu_s, mu_k, [])
    assert sentence in str(error.value) and "\n" not in str(error.value)


def test_mass_zero_is_no_object_and_a_bad_mass_is_refused():
    assert object_from_values(0.0, 0.5, 0.5, ["1:2"]) is None
    assert object_from_values(0.1, 0.5, 0.4, ["1:2"]).load.force_n(2.0) == 2.0
    with pytest.raises(SimError, match="must be a finite mass > 0 kg"):
        ObjectSpec(-0.1, 0.5, 0.5)


def test_the_stiffness_is_the_grids_secant_along_x_at_its_largest_level():
    # two indentation steps, levels 0..2, directions 0 (+x) and 1 (+y)
    d = [0.0, 0.001, 0.002, 0.001, 0.002, 0.001, 0.002, 0.001, 0.002, 0.001, 0.002]
    level = [0, 0, 0, 1, 1, 2, 2, 1, 1, 2, 2]
    direction = [-1, -1, -1, 0, 0, 0, 0, 1, 1, 1, 1]
    sx = [0, 0, 0, 0.001, 0.002, 0.003, 0.006, 0, 0, 0, 0]
    fx = [0, 0, 0, 0.4, 0.7, 1.0, 1.8, 0, 0, 0, 0]
    grid = SimpleNamespace(indentation_m=d, level=level, direction=direction, shear_x_m=sx,
                           force_x_n=fx, digest="abc")
    k = TangentialStiffness.from_grid(grid)
    assert k(0.001) == pytest.approx(1.0 / 0.003)
    assert k(0.002) == pytest.approx(1.8 / 0.006)
    assert k(0.0015) == pytest.approx(0.5 * (1.0 / 0.003 + 1.8 / 0.006))
    assert k(0.0) == k(0.001) and k(0.01) == k(0.002)
    assert k.source == "fem-array:abc"
    with pytest.raises(SimError, match="no shear along"):
        TangentialStiffness.from_grid(SimpleNamespace(**{**grid.__dict__,
                                                         "shear_x_m": [0.0] * 11}))


def test_an_object_that_slips_off_the_skins_falls_and_is_set_down_anew():
    spec = ObjectSpec(0.3, 0.5, 0.4)                  # 2.9 N against 0.8 N of kinetic friction
    obj = HeldObject(spec, STIFFNESS, reach_m=0.011)
    obj.step(0.0, (1.0, 1.0), DEPTH)
    obj.lift()
    states = run(obj, (1.0, 1.0), 0.001, 0.3)
    fell = next(i for i, s in enumerate(states) if s.dropped)
    assert 0.011 < states[fell].slip_m < 0.012 and not states[fell - 1].dropped
    assert states[-1].force_a_n == 0.0 and states[-1].slip_m == states[fell].slip_m
    obj.set_down()
    state = obj.step(0.4, (1.0, 1.0), DEPTH)
    assert not state.dropped and state.position_m == 0.0 and state.slip_m == 0.0


def test_a_firmer_grip_on_a_stuck_object_keeps_the_skins_force_and_holds_it():
    """Mindlin and Deresiewicz: the patch a firmer press adds carries no tangential
    traction. A grip tripled while the object hangs on the skins (their stiffness 2.1 x
    from the deeper press) leaves each skin carrying half the weight, without a slip: a
    spring that scaled its force with its stiffness threw the object back off the skins."""
    rising = TangentialStiffness([0.0005, 0.003], [200.0, 800.0])
    mass, normal = 0.2, 3.0
    weight = mass * STANDARD_GRAVITY_M_S2  # eased on over a second: no ringing to speak of
    spec = ObjectSpec(mass, 0.6, 0.5, LoadScript((0.0, 1.0), (-weight, 0.0)))
    obj = HeldObject(spec, rising, lambda: RateDependentForce((0.05, 0.04), (0.1, 1.5)))
    shallow, deep = (0.001, 0.001), (0.0025, 0.0025)
    obj.step(0.0, (normal, normal), shallow)
    obj.lift()
    for t in np.arange(1e-3, 3.0, 1e-3).tolist():
        obj.step(t, (normal, normal), shallow)
    half = weight / 2
    assert obj.state.force_a_n == pytest.approx(half, rel=0.02)
    before = obj.state
    states = []
    for k, t in enumerate(np.arange(3.0, 5.0, 1e-3).tolist()):
        share = min(1.0, k / 500)  # the grip rises over 0.5 s
        depth = tuple(a + share * (b - a) for a, b in zip(shallow, deep, strict=True))
        states.append(obj.step(t, (normal * (1 + 2 * share),) * 2, depth))
    assert all(s.slip_m == 0.0 and not s.dropped for s in states)
    assert max(abs(s.force_a_n - half) for s in states) < 0.05 * half
    # the object stays where it hung (the skins' creep aside); the stiffer skins carry the
    # same force deflected less
    assert abs(states[-1].position_m - before.position_m) < 2e-4
    ratio = rising(shallow[0]) / rising(deep[0])
    assert states[-1].deflection_a_m == pytest.approx(before.deflection_a_m * ratio, rel=0.05)
