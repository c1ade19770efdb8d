"""The tactile force the gripper's goals read (control/tactile_force.py)."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from tactile_sensor.control.tactile_force import TactileForce

forces = st.floats(-50.0, 50.0)


@given(st.lists(st.lists(forces, min_size=1, max_size=20), min_size=1, max_size=10))
def test_the_mean_covers_every_force_since_the_last_call(batches):
    tactile = TactileForce()
    for batch in batches:
        tactile.add(batch[-1], 1.0, sum(batch), len(batch))
    flat = [f for batch in batches for f in batch]
    assert tactile.mean_since_last_call() == pytest.approx(sum(flat) / len(flat), abs=1e-9)
    assert tactile.mean_since_last_call() is None
    assert tactile.latest == (batches[-1][-1], 1.0)


def test_a_single_force_counts_alone():
    tactile = TactileForce()
    assert tactile.latest is None and tactile.mean_since_last_call() is None
    tactile.add(2.0, 5.0)
    tactile.add(4.0, 6.0)
    assert tactile.latest == (4.0, 6.0)
    assert tactile.mean_since_last_call() == 3.0


def test_an_empty_batch_is_refused():
    with pytest.raises(ValueError, match="count"):
        TactileForce().add(1.0, 0.0, 0.0, 0)
