"""The tactile force the gripper's goals read (control/tactile_force.py)."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from tactile_sensor.control.tactile_force import TactileForce, no_first_force_detail

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


def test_the_sum_gives_how_many_forces_it_holds():
    """The hold weighs its windows by count: a batch of 10 counts ten times."""
    tactile = TactileForce()
    tactile.add(1.0, 1.0, sum_n=10.0, count=10, first_stamp_s=0.99)
    tactile.add(3.0, 2.0)
    assert tactile.sum_since_last_call() == (13.0, 11)
    assert tactile.sum_since_last_call() == (0.0, 0)


def test_an_empty_batch_is_refused():
    with pytest.raises(ValueError, match="count"):
        TactileForce().add(1.0, 0.0, 0.0, 0)


def test_after_a_gate_only_forces_stamped_later_count():
    """The settler judges a correction on forces taken after it took effect: late ones
    still describe where the fingers were."""
    tactile = TactileForce()
    tactile.add(9.0, 1.0)
    tactile.count_after(2.0)
    assert tactile.mean_since_last_call() is None  # what it held is dropped
    tactile.add(7.0, 1.5)  # arrived now, taken before the gate
    tactile.add(8.0, 2.0)  # taken at the gate itself
    assert tactile.mean_since_last_call() is None
    assert tactile.latest == (8.0, 2.0)  # the newest still counts for staleness
    tactile.add(3.0, 2.5)
    tactile.add(5.0, 3.0, sum_n=9.0, count=2, first_stamp_s=2.8)
    assert tactile.mean_since_last_call() == 4.0


@given(st.lists(forces, min_size=2, max_size=20))
def test_a_batch_straddling_the_gate_counts_its_newest_force_alone(batch):
    tactile = TactileForce()
    tactile.count_after(2.0)
    tactile.add(batch[-1], 3.0, sum(batch), len(batch), first_stamp_s=1.0)
    assert tactile.mean_since_last_call() == batch[-1]


def test_a_grasp_is_refused_in_one_sentence_once_the_force_went_stale():
    tactile = TactileForce()
    assert tactile.stale_refusal(10.0, 0.2) is None  # a grasp waits for the first force
    tactile.add(1.0, 10.0)
    assert tactile.stale_refusal(10.1, 0.2) is None
    blind = tactile.stale_refusal(10.5, 0.2)  # the driver went quiet: blind or stopped
    assert blind == ("the tactile force is 0.50 s old (tactile_timeout 0.2 s): the sensor is "
                     "blind or its stream stopped; see the driver's /diagnostics ('ambient "
                     "light saturates the detector': shade the module).")
    tactile.add(float("nan"), 10.5)
    assert tactile.stale_refusal(10.5, 0.2) is not None


def test_a_goal_without_its_first_force_says_whether_an_old_one_was_heard():
    never = no_first_force_detail(0.2004, 0.2, heard=False)
    old = no_first_force_detail(0.2004, 0.2, heard=True)
    assert never.startswith("no tactile force came within 0.200 s of the goal "
                            "(tactile_timeout 0.2 s), so the fingers did not move: ")
    assert old.startswith("no fresh tactile force (the newest is older than that) came ")
    for detail in (never, old):
        assert detail.count(". ") == 0 and "start and activate the driver" in detail
