"""SampleBacklog, the queue between the reader's serial and dispatch threads (pure)."""

from __future__ import annotations

import threading
import time

import pytest
from hypothesis import given
from hypothesis import strategies as st

from tactile_sensor.hardware.adc_reader import SampleBacklog
from tactile_sensor.hardware.errors import SerialPortError


def is_sample(item: object) -> bool:
    return isinstance(item, int)


# An operation: ("put", [items]) with ints as samples and strings as state changes,
# or ("take", limit).
operations = st.lists(st.one_of(
    st.tuples(st.just("put"), st.lists(st.one_of(st.integers(0, 999), st.sampled_from("ab")),
                                       max_size=12)),
    st.tuples(st.just("take"), st.integers(1, 10))), max_size=40)


@given(capacity=st.integers(1, 15), ops=operations)
def test_behaves_like_a_bounded_fifo_that_refuses_new_samples_when_full(capacity, ops):
    backlog = SampleBacklog(capacity, is_sample)
    model: list[object] = []
    dropped = peak = 0
    for op, arg in ops:
        if op == "put":
            refused = 0
            for item in arg:
                if is_sample(item) and sum(map(is_sample, model)) >= capacity:
                    refused += 1
                else:
                    model.append(item)
            assert backlog.put(arg) == refused
            dropped += refused
            peak = max(peak, sum(map(is_sample, model)))
        else:
            assert backlog.take(arg, 0.0) == model[:arg]
            del model[:arg]
        assert len(backlog) == sum(map(is_sample, model)) <= capacity
        assert backlog.dropped == dropped
        assert backlog.peak == peak


def test_state_changes_are_kept_even_when_full():
    backlog = SampleBacklog(2, is_sample)
    assert backlog.put([1, 2, "connected", 3, "stopped"]) == 1
    assert backlog.take(10, 0.0) == [1, 2, "connected", "stopped"]


def test_take_waits_for_a_put_from_another_thread():
    backlog = SampleBacklog(10, is_sample)
    threading.Timer(0.05, backlog.put, args=([7],)).start()
    start = time.monotonic()
    assert backlog.take(5, 2.0) == [7]
    assert time.monotonic() - start < 1.0


def test_take_times_out_empty_and_close_wakes_it_at_once():
    backlog = SampleBacklog(10, is_sample)
    assert backlog.take(5, 0.02) == []
    threading.Timer(0.05, backlog.close).start()
    start = time.monotonic()
    assert backlog.take(5, 5.0) == []
    assert time.monotonic() - start < 1.0
    backlog.put([1])  # a closed backlog still hands out what it holds
    assert backlog.take(5, 5.0) == [1]


def test_clear_says_how_many_samples_it_throws_away():
    backlog = SampleBacklog(10, is_sample)
    backlog.put([1, "x", 2, 3])
    assert backlog.clear() == 3
    assert backlog.dropped == 0 and len(backlog) == 0
    assert backlog.take(5, 0.0) == []


@pytest.mark.parametrize("capacity", [0, -5, 2.5, True, None])
def test_a_capacity_that_is_not_a_positive_count_is_refused(capacity):
    with pytest.raises(SerialPortError, match="backlog capacity"):
        SampleBacklog(capacity)
