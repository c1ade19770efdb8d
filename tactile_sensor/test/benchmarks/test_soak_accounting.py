"""The soak benchmark's pure bookkeeping: schedule, loss attribution, growth slope, goals."""

from __future__ import annotations

import importlib
import math
import sys
from itertools import pairwise
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

# The soak's modules sit beside it in benchmarks/ and import each other by file name, as
# `python benchmarks/soak.py` does: a benchmark of this project, not a dependency.
sys.path.insert(0, str(Path(__file__).resolve().parents[3] / "benchmarks"))
_accounting = importlib.import_module("soak_accounting")
FAULT_KINDS = _accounting.FAULT_KINDS
LossAccount = _accounting.LossAccount
LossSnapshot = _accounting.LossSnapshot
account_losses = _accounting.account_losses
evaluate_goals = _accounting.evaluate_goals
fault_schedule = _accounting.fault_schedule
growth_per_hour = _accounting.growth_per_hour
in_any_window = _accounting.in_any_window
parse_device_stats = _accounting.parse_device_stats


@settings(deadline=None)  # a loaded machine, not the code, sets the time
@given(st.floats(60.0, 7200.0), st.floats(0.0, 30.0), st.floats(5.0, 60.0))
def test_schedule_holds_every_kind_spaced_and_inside_the_run(run_s: float, warmup_s: float,
                                                             spacing_s: float) -> None:
    try:
        faults = fault_schedule(run_s, warmup_s=warmup_s, spacing_s=spacing_s)
    except ValueError:
        assert run_s < warmup_s + 10.0 + max(spacing_s, 10.0) + 3 * spacing_s + 1e-9
        return
    assert {f.kind for f in faults} == set(FAULT_KINDS)
    starts = [f.at_s for f in faults]
    assert starts == sorted(starts) and starts[0] == pytest.approx(warmup_s)
    assert all(b - a >= spacing_s - 1e-9 for a, b in pairwise(starts))
    assert all(f.at_s + f.duration_s <= run_s - 10.0 + 1e-9 for f in faults)


def test_schedule_of_a_short_run_says_how_long_it_must_be() -> None:
    with pytest.raises(ValueError, match="needs at least"):
        fault_schedule(30.0)
    with pytest.raises(ValueError, match="run_s"):
        fault_schedule(math.nan)


def test_two_minute_schedule_is_one_of_each() -> None:
    faults = fault_schedule(120.0)
    assert [f.kind for f in faults][:4] == list(FAULT_KINDS)
    assert next(f for f in faults if f.kind == "adc_unplug").duration_s == 2.0


def test_window_overlap_is_half_open_on_the_left() -> None:
    assert in_any_window(0.0, 5.0, [(5.0, 6.0)])
    assert not in_any_window(6.0, 7.0, [(5.0, 6.0)])
    assert in_any_window(5.5, 5.6, [(5.0, 6.0)])
    assert not in_any_window(0.0, 4.9, [(5.0, 6.0)])


def test_losses_in_a_window_are_explained_and_others_are_not() -> None:
    snaps = [LossSnapshot(1.0, 0), LossSnapshot(2.0, 3), LossSnapshot(3.0, 3),
             LossSnapshot(4.0, 10)]
    # 3 lost between 1 and 2 s (no window there), 7 between 3 and 4 s (window 3.5-3.8 s);
    # 20 on the link at the pull; 2 received but not published.
    loss = account_losses(sent=1000, received=970, published=968, snapshots=snaps,
                          windows=[(3.5, 3.8)], link_capacity_frames=100)
    assert loss == LossAccount(1000, 968, 32, 27, 5)


def test_link_losses_beyond_the_buffers_count_outside() -> None:
    loss = account_losses(1000, 800, 800, [], [(1.0, 2.0)], link_capacity_frames=50)
    assert (loss.lost_in_windows, loss.lost_outside) == (50, 150)
    no_unplug = account_losses(1000, 990, 990, [], [], link_capacity_frames=50)
    assert no_unplug.lost_outside == 10


def test_losses_refuse_counters_that_go_backwards_or_negative() -> None:
    with pytest.raises(ValueError, match="backwards"):
        account_losses(10, 10, 10, [LossSnapshot(1.0, 5), LossSnapshot(2.0, 4)], [], 0)
    with pytest.raises(ValueError, match=">= 0"):
        account_losses(-1, 0, 0, [], [], 0)


@settings(deadline=None)  # a loaded machine, not the code, sets the time
@given(st.lists(st.integers(0, 50), min_size=1, max_size=30), st.integers(0, 100),
       st.integers(0, 100), st.integers(0, 5))
def test_losses_add_up(increases: list[int], link: int, unpublished: int,
                       unplugs: int) -> None:
    cumulative, snaps = 0, []
    for i, inc in enumerate(increases):
        cumulative += inc
        snaps.append(LossSnapshot(float(i), cumulative))
    published = 10_000
    received = published + unpublished
    sent = received + cumulative + link
    windows = [(float(k) * 3 + 0.5, float(k) * 3 + 1.0) for k in range(unplugs)]
    loss = account_losses(sent, received, published, snaps, windows, 40)
    assert loss.lost_in_windows + loss.lost_outside == loss.lost_total == sent - published
    assert loss.lost_in_windows >= 0 and loss.lost_outside >= unpublished
    if not unplugs:
        assert loss.lost_in_windows == 0


@settings(deadline=None)  # a loaded machine, not the code, sets the time
@given(st.floats(-100.0, 100.0), st.floats(0.0, 1e3), st.integers(0, 3))
def test_growth_is_the_slope_after_warmup_despite_outliers(slope_per_h: float, base: float,
                                                           outliers: int) -> None:
    samples = [(t, base + slope_per_h * t / 3600.0) for t in range(0, 600, 10)]
    samples[0] = (0.0, base + 500.0)  # start-up growth before the warm-up
    for k in range(outliers):  # a few spikes after it
        t, v = samples[20 + 7 * k]
        samples[20 + 7 * k] = (t, v + 1000.0)
    assert growth_per_hour(samples, 60.0) == pytest.approx(slope_per_h, abs=1e-6)


def test_growth_needs_two_samples_after_warmup() -> None:
    assert math.isnan(growth_per_hour([(0.0, 1.0), (100.0, 2.0)], 50.0))
    assert growth_per_hour([(60.0, 1.0), (120.0, 2.0)], 50.0) == pytest.approx(60.0)


def test_goals_fail_on_each_kind_of_problem() -> None:
    clean = LossAccount(100, 90, 10, 10, 0)
    goals = evaluate_goals(clean, 90, 90, [], {"driver": 0.1, "model": math.nan})
    assert all(g.passed for g in goals)
    assert "too few samples" in goals[3].detail
    bad = evaluate_goals(LossAccount(100, 89, 11, 10, 1), 88, 89, ["adc_unplug at 10 s"],
                         {"driver": 6.0})
    assert [g.passed for g in bad] == [False, False, False, False]
    assert "over: driver" in bad[3].detail


def test_device_stats_are_read_from_the_last_line() -> None:
    log = ("mock adc: ok DeviceStats(frames_generated=5, frames_written=5, frames_dropped=0, "
           "frames_unplugged=0, bytes_lost=0, garbage_bytes=0, unplugs=0, plugged=True)\n"
           "mock adc: stopped; DeviceStats(frames_generated=9, frames_written=7, "
           "frames_dropped=0, frames_unplugged=2, bytes_lost=0, garbage_bytes=0, unplugs=1, "
           "plugged=True)\n")
    stats = parse_device_stats(log)
    assert stats["frames_generated"] == 9 and stats["frames_unplugged"] == 2
    assert "plugged" not in stats
    with pytest.raises(ValueError, match="no DeviceStats"):
        parse_device_stats("mock adc: 1000 Hz on /tmp/x\n")
