"""Queued batches of one connection become one block; state and info changes stay in place."""

from __future__ import annotations

import itertools

from hypothesis import given
from hypothesis import strategies as st

from tactile_sensor.hardware.adc_samples import SampleBatch, merged


def _batch(epoch: int, first: int, n: int) -> SampleBatch:
    batch = SampleBatch(epoch)
    for i in range(first, first + n):
        batch.append(i, i * 1000, i * 1_000_000, (i % 4096,))
    return batch


@given(st.lists(st.one_of(st.tuples(st.integers(0, 2), st.integers(1, 5)), st.just("state")),
                max_size=30))
def test_merging_keeps_every_sample_in_order_and_joins_only_one_connections_runs(plan):
    items: list[object] = []
    seq = 0
    for step in plan:
        if step == "state":
            items.append(step)
        else:
            epoch, n = step
            items.append(_batch(epoch, seq, n))
            seq += n
    out = merged(items)
    samples = [s for item in out if isinstance(item, SampleBatch) for s in item]
    assert [s.seq for s in samples] == list(range(seq))
    assert [i for i in out if not isinstance(i, SampleBatch)] == [
        i for i in items if not isinstance(i, SampleBatch)]
    for a, b in itertools.pairwise(out):
        if isinstance(a, SampleBatch) and isinstance(b, SampleBatch):
            assert a.epoch != b.epoch  # a run of one connection is one block
    assert all(len({s.epoch for s in item}) <= 1 for item in out
               if isinstance(item, SampleBatch))


def test_merging_leaves_the_queued_batches_unchanged():
    first, second = _batch(1, 0, 2), _batch(1, 2, 3)
    (block,) = merged([first, second])
    assert len(block) == 5 and len(first) == 2 and len(second) == 3
