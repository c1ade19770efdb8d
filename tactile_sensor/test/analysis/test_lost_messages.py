"""Recordings that lost messages, as a starved recorder or publisher does on a busy machine
(a 10 mm/s press lasts 0.6 s, about as long as the gaps seen in such bags): the analysis
must not count an interpolated stage motion as a press, and must say what was lost."""

from __future__ import annotations

import numpy as np
import pytest

from tactile_sensor.analysis import characterise as ch
from tactile_sensor.analysis.synthetic import (
    PressProtocol,
    SensorTruth,
    press_signals,
    write_press_bag,
)

PROTOCOL = PressProtocol(speeds_mm_s=(1.0, 10.0), cycles=(2, 4), hold_s=0.0, rest_s=1.0,
                         rate_hz=1000.0)


@pytest.fixture(scope="module")
def signals():
    return press_signals(PROTOCOL, SensorTruth(noise_v=0.005), seed=1)


def presses(signals) -> list[tuple[float, float]]:
    """(start, stop) [s] of every press in the synthetic truth."""
    moving = np.concatenate(([0], (signals.indentation_m > 0).astype(np.int8), [0]))
    edges = np.flatnonzero(np.diff(moving))
    return [(signals.t_s[a], signals.t_s[b - 1]) for a, b in zip(edges[::2], edges[1::2],
                                                                  strict=True)]


def analyse(tmp_path, signals, lost):
    bag = write_press_bag(tmp_path / "bag", signals, storage="mcap", lost=lost)
    return ch.analyse_bag(str(bag), ch.Options()).metrics


def test_complete_bag_has_every_press(tmp_path, signals):
    mt = analyse(tmp_path, signals, None)
    assert {k: v["cycles"] for k, v in mt["by_speed"].items()} == {"1.0": 2, "10.0": 4}
    assert not any("gap" in n for n in mt["notes"])


def test_stage_gap_inside_a_press_leaves_it_out_and_says_so(tmp_path, signals):
    start, stop = presses(signals)[3]  # the second 10 mm/s press
    middle = 0.5 * (start + stop)
    mt = analyse(tmp_path, signals, {"position": [(middle - 0.05, middle + 0.05)]})
    # the interpolated stage motion has a flat top, not the press's: it is not a cycle
    assert {k: v["cycles"] for k, v in mt["by_speed"].items()} == {"1.0": 2, "10.0": 3}
    note = next(n for n in mt["notes"] if "/bench/stage/joint_states" in n)
    assert "1 gap(s)" in note
    assert any("1 press(es) were left out because messages are missing" in n
               for n in mt["notes"])


def test_a_press_lost_entirely_is_reported(tmp_path, signals):
    start, stop = presses(signals)[4]
    mt = analyse(tmp_path, signals, {"position": [(start - 0.1, stop + 0.1)]})
    assert mt["by_speed"]["10.0"]["cycles"] == 3
    assert any("cannot be found" in n and "/bench/stage/joint_states" in n
               for n in mt["notes"])


def test_short_reading_gap_is_noted_with_the_cycles_it_touches(tmp_path, signals):
    start, _ = presses(signals)[0]  # 1 mm/s: 6 s long, so 0.2 s is under 5 %
    mt = analyse(tmp_path, signals, {"reading": [(start + 1.0, start + 1.2)]})
    assert mt["cycles"] == 6
    note = next(n for n in mt["notes"] if "/driver/reading" in n)
    assert "1 analysed cycle(s) overlap them" in note


def test_long_reading_gap_leaves_the_press_out(tmp_path, signals):
    start, _ = presses(signals)[2]  # 10 mm/s: 0.2 s is a third of it
    mt = analyse(tmp_path, signals, {"reading": [(start + 0.1, start + 0.3)]})
    assert mt["by_speed"]["10.0"]["cycles"] == 3
    assert any("1 press(es) were left out" in n for n in mt["notes"])


def test_streams_ending_early_cut_the_last_presses(tmp_path, signals):
    """What a bringup that stops recording before its streams caught up leaves behind."""
    start, _ = presses(signals)[4]
    mt = analyse(tmp_path, signals, {"reading": [(start + 0.2, signals.t_s[-1] + 1.0)]})
    assert mt["by_speed"]["10.0"]["cycles"] == 2
    assert any("1 press(es) cut off" in n for n in mt["notes"])
