"""The live force topic gets the newest readings of a block, never a backlog."""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from tactile_sensor.sensing.live_force import LiveSelector

MS = 1_000_000


@given(st.lists(st.integers(0, 50 * MS), max_size=200).map(sorted),
       st.floats(0.0, 0.05), st.booleans())
def test_the_live_readings_are_the_newest_within_the_window_and_the_rest_are_counted(
        stamps, window_s, behind):
    live = LiveSelector(window_s)
    first = live.first_live(stamps, behind)
    if behind or not stamps:
        assert first == len(stamps)
    else:
        assert first < len(stamps)  # the newest always goes out
        assert all(s >= stamps[-1] - live.window_ns for s in stamps[first:])
        assert all(s < stamps[-1] - live.window_ns for s in stamps[:first])
    assert live.skipped == first


def test_a_driver_that_keeps_up_publishes_every_reading_live():
    live = LiveSelector(0.01)
    for block in ([0], [1 * MS, 2 * MS], [3 * MS, 4 * MS, 5 * MS, 6 * MS]):
        assert live.first_live(block, behind=False) == 0
    assert live.skipped == 0


def test_a_second_of_backlog_leaves_only_its_last_10_ms_live():
    stamps = [i * MS for i in range(1000)]
    live = LiveSelector(0.01)
    assert live.first_live(stamps, behind=False) == 989
    assert live.first_live(stamps, behind=True) == 1000
    assert live.skipped == 989 + 1000


@pytest.mark.parametrize("window", [-0.001, math.nan])
def test_a_negative_or_nan_window_is_refused(window):
    with pytest.raises(ValueError, match="live window"):
        LiveSelector(window)
