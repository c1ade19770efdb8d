"""benchmarks/stack_figures.py: the stack benchmark's statistics, recovery time, loss count,
/proc parsing and table, on made-up inputs (no process, no clock)."""

from __future__ import annotations

import importlib
import math
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

BENCHMARKS = Path(__file__).resolve().parents[3] / "benchmarks"
sys.path.insert(0, str(BENCHMARKS))
figures = importlib.import_module("stack_figures")
Goal, Row = figures.Goal, figures.Row

WIDTH = figures.RECOVERY_WINDOW_S
BOUND = figures.RECOVERY_BOUND_S


def ages_for(windows: list[bool | None], stop_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Receipts in each window after ``stop_s``: True = under the bound, False = over it,
    None = nothing received."""
    times, ages = [], []
    for k, good in enumerate(windows):
        if good is None:
            continue
        t = stop_s + k * WIDTH + np.linspace(0.01, WIDTH - 0.01, 20)
        times += list(t)
        ages += [0.002] * 20 if good else [0.002] * 19 + [0.05]  # one late one lifts p99
    return np.array(times), np.array(ages)


@given(st.lists(st.sampled_from([True, False, None]), min_size=1, max_size=24),
       st.floats(0.0, 1e6))
def test_recovery_is_the_end_of_the_last_window_over_the_bound(windows, stop_s):
    times, ages = ages_for(windows, stop_s)
    got = figures.recovery_s(times, ages, stop_s, len(windows) * WIDTH)
    bad = [k for k, good in enumerate(windows) if not good]
    if not bad:
        assert got == 0.0
    elif bad[-1] == len(windows) - 1:
        assert got is None  # still late (or silent) when the span ends
    else:
        assert got == pytest.approx((bad[-1] + 1) * WIDTH)
        after = figures.window_p99(times, ages, stop_s + got, len(windows) * WIDTH - got)
        assert all(p < BOUND for p in after)


def test_a_relapse_after_a_good_window_still_counts_and_silence_is_not_recovery():
    times, ages = ages_for([False, True, False, True, True], 10.0)
    assert figures.recovery_s(times, ages, 10.0, 5 * WIDTH) == pytest.approx(3 * WIDTH)
    times, ages = ages_for([True, None, True], 10.0)
    assert figures.recovery_s(times, ages, 10.0, 3 * WIDTH) == pytest.approx(2 * WIDTH)
    assert figures.recovery_s([], [], 0.0, 0.1) is None  # no whole window in the span


@pytest.mark.parametrize(("call", "says"), [
    (lambda: figures.window_p99([0.0], [0.0], 0.0, 1.0, 0.0), "positive time"),
    (lambda: figures.window_p99([0.0, 1.0], [0.0], 0.0, 1.0), "2 receipt times for 1"),
    (lambda: figures.missing_samples([1, 2], 0.0), "period must be > 0"),
    (lambda: figures.cores({}, {"a": 1.0}, 0.0), "window must be > 0 s"),
    (lambda: Goal("==", 1.0), "compares with <=, >= or <"),
    (lambda: figures.task_ticks("12 (x) S 1"), "not a /proc stat line"),
])
def test_bad_input_is_one_sentence(call, says):
    with pytest.raises(ValueError, match=says):
        call()


@given(st.integers(1, 2000), st.sets(st.integers(0, 1999), max_size=300),
       st.floats(-0.24, 0.24), st.integers(0, 2**40))
def test_missing_samples_count_what_was_taken_out_between_the_first_and_last(
        n, removed, jitter, start):
    period = 1_000_000.0  # 1 kHz; device stamps jitter by far less than a quarter period
    rng = np.random.default_rng(n)
    stamps = start + np.arange(n) * period + rng.uniform(-abs(jitter), abs(jitter), n) * period
    kept = np.array([s for i, s in enumerate(stamps.astype(np.int64)) if i not in removed])
    loss = figures.missing_samples(kept, period)
    assert loss.recorded == kept.size
    if kept.size >= 2:
        first, last = (i for i in (min(set(range(n)) - removed), max(set(range(n)) - removed)))
        assert loss.missing == sum(first < i < last for i in removed)
    else:
        assert loss.missing == 0


def test_a_publish_rate_below_the_adc_rate_loses_the_samples_between():
    every_fourth = np.arange(0, 4000, 4) * 1_000_000
    loss = figures.missing_samples(every_fourth, 1e6)
    assert (loss.recorded, loss.missing) == (1000, 2997)


def test_age_summary_in_milliseconds_and_nan_without_messages():
    s = figures.age_summary(np.linspace(0.001, 0.1, 100))
    assert s.count == 100 and s.max_ms == pytest.approx(100.0)
    assert s.p50_ms == pytest.approx(50.5) and 98 < s.p99_ms < 100
    empty = figures.age_summary([])
    assert empty.count == 0 and math.isnan(empty.p99_ms)


@given(st.text(st.characters(blacklist_categories=("Cs",), blacklist_characters="\0\n"),
               max_size=15), st.integers(0, 10**9), st.integers(0, 10**9))
def test_task_ticks_read_utime_and_stime_whatever_the_name_holds(comm, utime, stime):
    stat = f"4242 ({comm}) S 1 4242 4242 0 -1 4194560 100 0 0 0 {utime} {stime} 0 0 20 0 9"
    assert figures.task_ticks(stat) == utime + stime


@given(st.dictionaries(st.integers(1, 500), st.sampled_from(["python3", "dds.ev.0", "gc"]),
                       min_size=1))
def test_thread_labels_are_unique_and_name_the_main_thread(comms):
    pid = min(comms)
    labels = figures.thread_labels(pid, comms)
    assert set(labels) == set(comms)
    assert len(set(labels.values())) == len(labels)
    assert labels[pid] == f"main ({comms[pid]})"
    for tid, label in labels.items():
        assert comms[tid] in label


# CPU times come in clock ticks (10 ms): an extra far below one is no input (8192 s plus
# 6e-12 s is not representable to the test's tolerance).
@given(st.dictionaries(st.sampled_from("abcdef"), st.floats(0, 1e4), min_size=1),
       st.one_of(st.just(0.0), st.floats(0.01, 10.0)), st.floats(0.1, 100.0))
def test_cores_count_a_thread_born_in_the_window_from_zero(before, extra, span):
    after = {k: v + extra for k, v in before.items()} | {"new": extra}
    got = figures.cores(before, after, span)
    assert set(got) == set(after)
    for key in after:
        assert got[key] == pytest.approx(extra / span)


def test_hold_goal_is_18_of_20_and_the_same_share_of_fewer():
    assert [figures.hold_goal(n) for n in (20, 5, 1, 10)] == [18, 5, 1, 9]


def test_goals_judge_and_say_nothing_without_a_value():
    assert Goal("<=", 0.05).met(0.05) and not Goal("<", 10.0).met(10.0)
    assert Goal(">=", 18).met(19) and Goal(">=", 18).met(float("nan")) is None
    assert Goal("<=", 20.0, "ms").text == "<= 20 ms"


@given(st.lists(st.tuples(st.floats(0, 2, allow_nan=False), st.floats(0, 2, allow_nan=False)),
                min_size=1, max_size=8))
def test_the_table_has_a_line_per_figure_with_its_goal_and_every_column(pairs):
    rows = [Row(f"CPU idle, node {k}", "cores", (a, b), Goal("<=", 1.0))
            for k, (a, b) in enumerate(pairs)]
    text = figures.render_table(["549bc19", "this (abc1234)"],
                                [("separate processes", rows[:1]), ("one process", rows[1:])])
    lines = text.splitlines()
    assert len(lines) == 1 + 2 + len(rows)
    assert "549bc19" in lines[0] and "this (abc1234)" in lines[0] and "goal" in lines[0]
    assert lines[1] == "separate processes"
    for row, line in zip(rows, [lines[2], *lines[4:]], strict=True):
        assert line.startswith(f"  {row.name} [cores]") and "<= 1" in line
        for value in row.values:
            assert f"{value:.3f} {'met' if value <= 1.0 else 'NOT met'}" in line


def test_the_table_shows_what_was_not_measured_and_refuses_a_short_row():
    row = Row("recovery", "s", (None, "> 5", 0.25), Goal("<=", 1.0), digits=2)
    line = figures.render_table(["a", "b", "c"], [("x", [row])]).splitlines()[-1]
    assert "n/a" in line and "> 5" in line and "0.25 met" in line
    with pytest.raises(ValueError, match="has 1 values for 2 columns"):
        figures.render_table(["a", "b"], [("x", [Row("n", "", (1,))])])


@pytest.fixture(scope="module")
def bench():
    return importlib.import_module("bench_stack")


@pytest.mark.parametrize("make", [
    lambda tmp: tmp / "never_written",
    lambda tmp: (tmp / "no_metadata").mkdir() or tmp / "no_metadata",
    lambda tmp: (tmp / "junk.mcap").write_text("junk") and tmp / "junk.mcap",
])
def test_a_recording_that_cannot_be_read_is_not_measured_and_says_why(bench, tmp_path, make):
    loss, why = bench.recording_loss(make(tmp_path), 1e6)
    assert loss is None and (why == "no bag written" or why.startswith("no readable bag"))


def test_a_run_that_failed_shows_not_measured_beside_one_that_ran(bench):
    age = figures.AgeSummary(5.0, 15.0, 40.0, 2500)
    grasp = importlib.import_module("grasp_hold").Grasp
    ran = bench.Run(idle={"driver": 0.08, "gripper": 0.04, "mock hardware": 0.2},
                    grasping={"driver": 0.09, "gripper": 0.1, "mock hardware": 0.2},
                    quiet=age, busy=age, busy_dds=age, recovery=None, recovery_span_s=5.0,
                    loss=figures.Loss(1000, 1000), driver_lost=0,
                    grasps=[grasp(1.52, 1.49, True, "contact: settled at 1.50 N"),
                            grasp(1.6, float("nan"), False, "tactile_stale: late")])
    plan = bench.Plan(10.0, 10.0, 3, 2, 5.0, 3.0)
    rows = bench.rows_of("processes", [bench.Run(error="not ready"), ran], plan)
    by_name = {r.name: r for r in rows}
    assert by_name["CPU idle, whole stack incl. mock"].values == (None, pytest.approx(0.32))
    assert by_name["CPU idle, gripper"].goal.met(0.04)
    assert by_name["after the loads stop: until p99 over 0.25 s stays < 10 ms"].values[1] == "> 5"
    assert by_name[f"grasps at {bench.TARGET_N:g} N beside the loops: tactile_stale"].values[1] == 1
    assert by_name["  true force within 5 % 0.5 s after touch"].values[1] == 1
    found = {f.name: f for f in bench.figures_of([("processes", rows)], ["old", "new"])}
    assert found["separate processes: CPU idle, gripper, new"].met is True
    assert found["separate processes: CPU idle, gripper, old"].value is None
    assert found["separate processes: CPU idle, gripper, old"].met is None
    recovered = found["separate processes: after the loads stop: until p99 over 0.25 s stays "
                      "< 10 ms, new"]
    assert recovered.value == "> 5" and recovered.met is False
