from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from tactile_sensor.sim.errors import SimError
from tactile_sensor.sim.profiles import PROTOCOLS, LoadProfile, parse_profile


def test_compression_presses_three_mm_at_one_mm_per_s():
    p = parse_profile("compression")
    assert p.duration_s == pytest.approx(1.0 + 3.0 + 3.0 + 1.0)
    assert p.indentation(1.0) == 0.0
    assert p.indentation(2.5) == pytest.approx(0.0015)
    assert p.indentation(4.0) == pytest.approx(0.003)
    assert p.indentation(5.5) == pytest.approx(0.0015)
    assert p.indentation(100.0) == 0.0


def test_paper_protocols():
    rep = parse_profile("repeatability")
    assert rep.cycles == 100 and rep.hold_s == 1.0
    # 100 × (3 s down + 1 s hold + 3 s up + rest) + first rest
    assert rep.duration_s == pytest.approx(0.5 + 100 * (7.0 + 0.5))
    speeds = parse_profile("speeds")
    assert speeds.speeds_m_s == (0.0001, 0.001, 0.01)
    assert speeds.duration_s == pytest.approx(1.0 + 5 * sum(6.0 / v + 1.0
                                                            for v in (0.1, 1.0, 10.0)))
    assert set(PROTOCOLS) >= {"compression", "repeatability", "speeds"}


def test_overrides_and_ramps():
    p = parse_profile("compression:cycles=3,hold=0.5")
    assert (p.cycles, p.hold_s, p.depth_m) == (3, 0.5, 0.003)
    r = parse_profile("ramp:depth=0.002,speed=0.001/0.002,cycles=2,hold=1,rest=0,preload=0.0005")
    assert r.speeds_m_s == (0.001, 0.002)
    assert r.indentation(0.0) == pytest.approx(0.0005)
    assert r.indentation(1.5) == pytest.approx(0.002)


@given(st.floats(0.0005, 0.01), st.floats(0.0001, 0.05), st.integers(1, 4),
       st.floats(0.0, 2.0))
def test_indentation_stays_between_preload_and_depth(depth, speed, cycles, hold):
    p = LoadProfile(depth_m=depth, speeds_m_s=(speed,), cycles=cycles, hold_s=hold)
    t = np.linspace(-1.0, p.duration_s + 1.0, 2001)
    d = p.indentation(t)
    assert d.min() >= 0.0 and d.max() <= depth + 1e-15
    knot_t, knot_d = p.knots()
    assert p.indentation(knot_t).max() == pytest.approx(depth)
    np.testing.assert_allclose(p.indentation(knot_t), knot_d)
    assert p.duration_s == pytest.approx(
        p.rest_s + cycles * (2 * depth / speed + hold + p.rest_s))


@pytest.mark.parametrize(("spec", "match"), [
    ("squeeze", "Unknown profile 'squeeze'"),
    ("compression:depth", "key=value"),
    ("compression:color=red", "key=value"),
    ("ramp:depth=abc", "not a number"),
    ("ramp:depth=0.5", "depth"),
    ("ramp:speed=0", "speed"),
    ("ramp:cycles=0", "cycles"),
    ("ramp:hold=-1", "hold"),
    ("ramp:preload=0.004", "preload"),
])
def test_bad_specs_say_what_is_wrong(spec, match):
    with pytest.raises(SimError, match=match):
        parse_profile(spec)
