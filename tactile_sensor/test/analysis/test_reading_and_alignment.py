"""Progress while reading, and the alignment's handling of sign and stamps."""

from __future__ import annotations

import dataclasses
import itertools
from pathlib import Path

import numpy as np
import pytest

from tactile_sensor.analysis import characterise as ch
from tactile_sensor.analysis.bag_reader import Recording, Series, read_recording
from tactile_sensor.analysis.errors import SegmentError
from tactile_sensor.analysis.synthetic import (
    PressProtocol,
    SensorTruth,
    press_signals,
    write_press_bag,
)

PROTOCOL = PressProtocol(speeds_mm_s=(10.0,), cycles=(3,), rate_hz=200.0, rest_s=0.5)
TRUTH = SensorTruth(noise_v=0.005)


def in_memory(signals, force_scale=1.0, position_shift_s=0.0):
    ns = np.round(signals.t_s * 1e9).astype(np.int64)

    def series(name, values, shift_s=0.0):
        return Series(f"/{name}", "x", ns + int(shift_s * 1e9), {name: values}, "header")

    return Recording(path=Path("mem"), storage="none", series={
        "reading": series("output_v", signals.output_v),
        "reference": series("force_n", force_scale * signals.force_n),
        "position": series("indentation_m", signals.indentation_m, position_shift_s)})


def test_progress_rises_to_one(tmp_path):
    bag = write_press_bag(tmp_path / "b", press_signals(PROTOCOL, TRUTH), "mcap")
    seen = []
    read_recording(bag, ch.Topics().specs(), seen.append)
    assert seen[-1] == 1.0
    assert len(seen) >= 10
    assert all(a <= b for a, b in itertools.pairwise(seen))


def test_negative_gauge_force_is_flipped_and_noted():
    signals = press_signals(PROTOCOL, TRUTH)
    result = ch.characterise(in_memory(signals, force_scale=-1.0), ch.Options())
    assert result.aligned.force_flipped
    expected = TRUTH.sensitivity_v_per_n / TRUTH.rate_factor(10.0)  # force 10 % up at 10 mm/s
    assert result.metrics["sensitivity_v_per_n"] == pytest.approx(expected, rel=0.04)
    assert any("flipped" in n for n in result.metrics["notes"])


def test_topics_that_do_not_overlap_in_time():
    signals = press_signals(PROTOCOL, TRUTH)
    recording = in_memory(signals, position_shift_s=float(signals.t_s[-1]) + 1.0)
    with pytest.raises(SegmentError, match="do not overlap"):
        ch.characterise(recording, ch.Options())


def test_single_cycle_gives_null_repeatability():
    signals = press_signals(dataclasses.replace(PROTOCOL, cycles=(1,)), TRUTH)
    mt = ch.characterise(in_memory(signals), ch.Options()).metrics
    assert mt["cycles"] == 1
    assert mt["peak_output_cv_pct"] is None
    assert mt["drift_pct"] is None
    assert mt["sensitivity_v_per_n"] is not None
