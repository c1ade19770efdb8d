from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from tactile_sensor.sim.errors import SimError
from tactile_sensor.sim.profiles import (
    ARRAY_PROTOCOLS,
    PROTOCOLS,
    SHEAR_DIRECTIONS,
    LoadProfile,
    ShearProfile,
    array_profile,
    array_profile_from_protocol,
)


def test_shear_protocol_presses_sweeps_eight_directions_and_releases():
    p = array_profile_from_protocol("shear")
    assert isinstance(p, ShearProfile)
    assert (p.depth_m, p.speed_m_s, p.amplitude_m, p.directions) == (0.003, 0.001, 0.006, 8)
    # rest 1 + press 3 + 8 x (out 6 + back 6) + release 3 + rest 1
    assert p.duration_s == pytest.approx(1 + 3 + 8 * 12 + 3 + 1)
    assert p.shear_ratio == pytest.approx(2.0)
    assert p.indentation(0.5) == 0.0 and p.indentation(2.5) == pytest.approx(0.0015)
    expected = [(0.006, 0.0), (-0.006, 0.0), (0.0, 0.006), (0.0, -0.006)] + [
        (a * 0.006 / math.sqrt(2), b * 0.006 / math.sqrt(2))
        for a, b in ((1, 1), (-1, -1), (-1, 1), (1, -1))]
    for k, (ex, ey) in enumerate(expected):
        out, back = 4.0 + 12 * k + 6, 4.0 + 12 * k + 12
        assert p.indentation(out) == pytest.approx(0.003)
        assert p.lateral(out) == pytest.approx((ex, ey), abs=1e-12)
        assert p.lateral(back) == pytest.approx((0.0, 0.0), abs=1e-12)
        assert math.hypot(*p.lateral(out - 3)) == pytest.approx(0.003)  # 1 mm/s sideways
    assert p.indentation(102.5) == pytest.approx(0.0005)
    assert p.indentation(1000.0) == 0.0 and p.lateral(-1.0) == (0.0, 0.0)


def test_four_directions_holds_and_cycles():
    p = ShearProfile(depth_m=0.002, speed_m_s=0.002, amplitude_m=0.004, directions=4,
                     cycles=2, hold_s=0.5, rest_s=0.25)
    per_cycle = 1.0 + 0.5 + 4 * (2.0 + 2.0 + 0.5) + 1.0 + 0.25
    assert p.duration_s == pytest.approx(0.25 + 2 * per_cycle)
    times, points = p.knots()
    assert points.shape == (times.size, 3)
    assert np.all(np.diff(times) >= 0)
    lateral = points[:, 1:]
    assert np.abs(lateral).max() == pytest.approx(0.004)
    assert not np.any((lateral[:, 0] != 0) & (lateral[:, 1] != 0))  # no diagonals with 4
    assert SHEAR_DIRECTIONS[:4] == ((1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (0.0, -1.0))


@given(t=st.floats(-10.0, 200.0))
def test_lateral_motion_only_at_depth(t):
    p = array_profile_from_protocol("shear")
    sx, sy = p.lateral(t)
    if sx or sy:
        assert p.indentation(t) == pytest.approx(0.003)
    assert math.hypot(sx, sy) <= 0.006 + 1e-12


def test_array_protocols_and_the_bench_table_are_both_loaded():
    assert set(ARRAY_PROTOCOLS) == {"compression", "shear", "wrench"}
    assert ARRAY_PROTOCOLS["shear"]["shear_m"] == 0.006
    assert set(PROTOCOLS) >= {"compression", "repeatability", "speeds", "rest"}
    compression = array_profile_from_protocol("compression")
    assert isinstance(compression, LoadProfile)
    assert compression == LoadProfile(**PROTOCOLS["compression"])
    short = array_profile_from_protocol("shear", shear_directions=4, shear_m=0.003)
    assert isinstance(short, ShearProfile) and short.directions == 4
    assert short.amplitude_m == 0.003


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"depth_m": 0.0}, "depth"),
    ({"depth_m": 0.05}, "depth"),
    ({"depth_m": float("nan")}, "depth"),
    ({"speed_m_s": 0.0}, "speed"),
    ({"speed_m_s": 2.0}, "speed"),
    ({"amplitude_m": -0.001}, "shear amplitude"),
    ({"amplitude_m": 0.1}, "shear amplitude"),
    ({"amplitude_m": "6 mm"}, "shear amplitude"),
    ({"directions": 6}, "directions"),
    ({"directions": 4.0}, "directions"),
    ({"directions": True}, "directions"),
    ({"cycles": 0}, "cycles"),
    ({"cycles": 1.5}, "cycles"),
    ({"hold_s": -1.0}, "hold"),
    ({"rest_s": float("inf")}, "rest"),
])
def test_bad_shear_profiles_say_what_to_fix(kwargs, message):
    with pytest.raises(SimError, match=message) as info:
        ShearProfile(**kwargs)
    assert str(info.value).count(". ") == 0 and str(info.value).endswith(".")


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"shear_m": 0.003, "speeds_m_s": (0.001, 0.01)}, "one speed"),
    ({"shear_m": 0.003, "preload_m": 0.001}, "preload"),
    ({"shear_m": -0.001}, "shear"),
    ({"shear_m": 0.003, "shear_directions": 5}, "directions"),
])
def test_bad_array_protocol_parameters(kwargs, message):
    with pytest.raises(SimError, match=message):
        array_profile(**kwargs)


def test_unknown_array_protocol():
    with pytest.raises(SimError, match="compression, shear"):
        array_profile_from_protocol("twist")
