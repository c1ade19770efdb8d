"""SampleBacklog, the queue between the reader's drain thread and its consumer (pure)."""

from __future__ import annotations

import threading
import time

import pytest
from hypothesis import given
from hypothesis import strategies as st

from tactile_sensor.hardware.adc_samples import Sample, SampleBacklog, SampleBatch
from tactile_sensor.hardware.errors import SerialPortError


def is_sample(item: object) -> int:
    return int(isinstance(item, int))


def size_of(item: object) -> int:
    """Tuples stand for batches of samples, strings for state changes."""
    return len(item) if isinstance(item, tuple) else 0


def head(item: tuple, n: int) -> tuple:
    return item[:n]


# An operation: ("put", [items]) with tuples as batches of samples and strings as state
# changes, or ("take", limit).
operations = st.lists(st.one_of(
    st.tuples(st.just("put"), st.lists(st.one_of(
        st.lists(st.integers(0, 999), min_size=1, max_size=6).map(tuple),
        st.sampled_from("ab")), max_size=8)),
    st.tuples(st.just("take"), st.integers(1, 10))), max_size=40)


@given(capacity=st.integers(1, 15), ops=operations)
def test_behaves_like_a_bounded_fifo_that_refuses_new_samples_when_full(capacity, ops):
    backlog = SampleBacklog(capacity, size_of, head)
    model: list[object] = []
    dropped = peak = 0
    for op, arg in ops:
        if op == "put":
            refused = 0
            for item in arg:
                room = capacity - sum(map(size_of, model))
                n = size_of(item)
                if n > room:  # the batch's newest samples go
                    refused += n - room
                    if room == 0:
                        continue
                    item = item[:room]
                model.append(item)
            assert backlog.put(arg) == refused
            dropped += refused
            peak = max(peak, sum(map(size_of, model)))
        else:
            assert backlog.take(arg, 0.0) == model[:arg]
            del model[:arg]
        assert len(backlog) == sum(map(size_of, model)) <= capacity
        assert backlog.empty == (not model)
        assert backlog.dropped == dropped
        assert backlog.peak == peak


def test_samples_the_consumer_holds_count_against_the_capacity_until_handed_over():
    backlog = SampleBacklog(5, size_of, head)
    backlog.put([(1, 2, 3)])
    assert backlog.take(1, 0.0) == [(1, 2, 3)]
    backlog.held = 3  # the consumer hands them over one by one
    assert len(backlog) == 3 and not backlog.empty
    assert backlog.put([(4, 5, 6)]) == 1
    assert backlog.peak == 5
    backlog.held = 1
    assert len(backlog) == 3
    assert backlog.clear() == 3  # the held one is thrown away too
    assert backlog.empty and len(backlog) == 0


def test_a_batch_is_its_samples_as_columns():
    samples = [Sample(k, 1000 * k, 5 + k, (k, 2 * k), 3) for k in range(4)]
    batch = SampleBatch.of(samples)
    assert len(batch) == 4 and batch.epoch == 3
    assert list(batch) == samples
    assert list(batch.head(2)) == samples[:2]
    assert batch.counts[3] == (3, 6) and batch.host_time_ns == [5, 6, 7, 8]


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
