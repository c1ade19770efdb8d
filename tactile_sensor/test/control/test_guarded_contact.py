"""Where the fingers were when a force was sampled, and the latency-counted stop."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from tactile_sensor.control.guarded_contact import PositionTrace, force_ahead_n, stop_goal_rad


def test_trace_interpolates_and_clamps():
    trace = PositionTrace(span_s=1.0)
    with pytest.raises(LookupError, match="no position"):
        trace.at(0.0)
    trace.add(0.0, 1.0)
    trace.add(0.01, 1.1)
    trace.add(0.01, 9.0)  # not newer: ignored
    assert trace.at(0.005) == pytest.approx(1.05)
    assert trace.at(-1.0) == 1.0 and trace.at(1.0) == 1.1


def test_trace_forgets_what_is_older_than_its_span():
    trace = PositionTrace(span_s=0.05)
    for k in range(20):
        trace.add(0.01 * k, float(k))
    assert trace.at(0.0) == pytest.approx(14.0)  # the oldest kept: 0.14 s


@given(st.floats(0.0, 5.0), st.floats(0.1, 5.0), st.floats(1.0, 100.0))
def test_stop_goal_reads_the_target_on_the_assumed_skin(force, target, k_rad):
    goal = stop_goal_rad(force, 1.0, target, k_rad)
    assert force + k_rad * (goal - 1.0) == pytest.approx(target)


def test_force_ahead_counts_travel_since_the_sample_and_until_the_command_lands():
    assert force_ahead_n(1.0, 1.0, 1.02, 0.5, 35.0, 0.01) == pytest.approx(
        1.0 + 35.0 * (0.02 + 0.005))
    assert force_ahead_n(1.0, 1.0, 0.99, 0.0, 35.0, 0.01) == 1.0  # opened: no force added
