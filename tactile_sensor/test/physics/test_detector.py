"""The QTR-1A's detector circuit: the dark room is the optics model's output exactly; light,
heat and an ageing emitter move it as the datasheet figures say, and it holds at a rail."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from tactile_sensor.physics.detector import (
    DARK_CURRENT_A,
    PULL_UP_OHM,
    DetectorState,
    headroom_ratio,
    module_output_v,
    response_tau_s,
)
from tactile_sensor.physics.errors import PhysicsError

REST_V = 1.9873  # the default skin's output at rest (physics defaults, 2 mm gap)
REST_DROP_V = 5.0 - REST_V


@given(st.lists(st.floats(0.0, 5.0), min_size=1, max_size=20))
def test_the_dark_room_is_the_optics_models_output_exactly(volts):
    v = np.array(volts)
    assert np.array_equal(module_output_v(v, 0.0, REST_DROP_V, DetectorState()), v)


def test_ambient_light_adds_the_emitters_rest_drop_times_its_ratio():
    out = module_output_v(np.array([REST_V, 3.0]), 0.2, REST_DROP_V, DetectorState())
    assert out == pytest.approx([REST_V - 0.2 * REST_DROP_V, 3.0 - 0.2 * REST_DROP_V],
                                abs=1e-6)


@given(st.floats(0.0, 50.0), st.floats(0.0, 5.0))
def test_the_output_holds_between_the_rails_whatever_the_light(ratio, v):
    out = module_output_v(np.array([v]), ratio, REST_DROP_V, DetectorState(delta_k=40.0))
    assert -0.02 <= float(out[0]) <= 5.02  # the rounded corners are ~1/40 V wide


def test_light_past_the_headroom_holds_the_output_at_the_lower_rail():
    room = headroom_ratio(REST_V)
    assert room == pytest.approx(REST_V / REST_DROP_V, rel=1e-9)
    at = module_output_v(np.array([REST_V]), 0.6 * room, REST_DROP_V, DetectorState())
    assert float(at[0]) == pytest.approx(0.4 * REST_V, abs=1e-3)
    past = module_output_v(np.array([REST_V, 1.5]), 1.5 * room, REST_DROP_V, DetectorState())
    assert np.all(past < 0.03)


def test_heat_dims_the_emitter_and_adds_dark_current():
    warm = DetectorState(delta_k=20.0)
    assert warm.skin_gain == pytest.approx((1 - 0.006 * 20) * (1 + 0.005 * 20))
    assert warm.dark_drop_v == pytest.approx(DARK_CURRENT_A * PULL_UP_OHM * 3.0)
    out = module_output_v(np.array([REST_V]), 0.0, REST_DROP_V, warm)
    # a dimmer skin light raises the output; the dark current lowers it by millivolts
    expected = 5.0 - REST_DROP_V * warm.skin_gain - warm.dark_drop_v
    assert float(out[0]) == pytest.approx(expected, abs=1e-6)
    room = headroom_ratio(REST_V, state=warm)  # where the warm output meets the rail
    edge = 5.0 - REST_DROP_V * warm.skin_gain - room * REST_DROP_V * warm.detector_gain
    assert edge - warm.dark_drop_v == pytest.approx(0.0, abs=1e-9)
    assert headroom_ratio(REST_V, state=DetectorState(emitter_ratio=0.7)) > \
        headroom_ratio(REST_V)


def test_an_aged_emitter_shrinks_the_skins_swing_in_proportion():
    aged = DetectorState(emitter_ratio=0.7)
    v = np.array([REST_V, 1.5])
    out = module_output_v(v, 0.0, REST_DROP_V, aged)
    assert 5.0 - out == pytest.approx(0.7 * (5.0 - v), rel=1e-6)


def test_the_response_time_is_the_datasheets_scaled_to_the_pull_up():
    # 20 us 10-90 % at 1 kOhm -> 0.94 ms at 47 kOhm -> tau = 0.94 ms / ln 9
    assert response_tau_s() == pytest.approx(0.94e-3 / math.log(9.0), rel=1e-9)


@pytest.mark.parametrize(("kwargs", "name"), [
    ({"delta_k": float("nan")}, "temperature.delta_k"),
    ({"delta_k": 90.0}, "temperature.delta_k"),
    ({"emitter_ratio": -0.1}, "emitter.output_ratio"),
    ({"emitter_ratio": float("inf")}, "emitter.output_ratio"),
])
def test_an_impossible_state_is_refused_naming_the_parameter(kwargs, name):
    with pytest.raises(PhysicsError, match=name):
        DetectorState(**kwargs)


def test_no_headroom_can_be_stated_against_an_output_at_the_supply():
    with pytest.raises(PhysicsError, match="no emitter light"):
        headroom_ratio(5.0)
