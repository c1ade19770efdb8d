"""Play compensation in the rate-aware calibration: the direction tracker, the two static
branches, file version 3 and the refusal by an older reader."""

from __future__ import annotations

import itertools
import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tactile_sensor.sensing import calibration as calibration_module
from tactile_sensor.sensing.calibration import Calibration
from tactile_sensor.sensing.chain import ChainConfig, SignalChain
from tactile_sensor.sensing.errors import CalibrationError
from tactile_sensor.sensing.rate_calibration import (
    DirectionTracker,
    Play,
    RateCalibration,
    RateTerm,
    load_file,
)
from tactile_sensor.sim.bench_world import play as play_operator

STATIC = Calibration.from_curve([0.0, 0.1, 0.3, 0.5], [0.0, 1.0, 3.5, 7.0], "test:curve")
TERMS = (RateTerm(0.05, 0.1), RateTerm(0.04, 1.5))
GAP = (0.0, 0.05, 0.1, 0.15)
PLAYED = RateCalibration(STATIC, TERMS, Play(GAP, 0.01, 10.0))
INSTANT = 1e6  # Hz: a smoothing this fast is no smoothing at 1 kHz (alpha == 1.0)


def estimate(cal: RateCalibration, t: np.ndarray, output: np.ndarray) -> np.ndarray:
    est = cal.estimator()
    return np.array([est.update(float(o), float(s))[0]
                     for o, s in zip(output, t, strict=True)])


outputs = st.lists(st.floats(-0.1, 0.6), min_size=2, max_size=80)


@settings(max_examples=60, deadline=None)
@given(out=outputs, steps=st.lists(st.floats(0.0, 0.05), min_size=80, max_size=80),
       band=st.floats(1e-4, 0.1), smoothing=st.floats(0.1, 100.0))
def test_zero_play_is_todays_model_exactly(out, steps, band, smoothing):
    """All half-gaps 0: whatever the tracker decides, both branches are the curve, so every
    force (and saturation flag) equals the play-less estimator's bit for bit."""
    t = np.cumsum(steps[:len(out)])
    zero = RateCalibration(STATIC, TERMS, Play((0.0,) * 4, band, smoothing))
    plain, split = RateCalibration(STATIC, TERMS).estimator(), zero.estimator()
    for o, s in zip(out, t.tolist(), strict=True):
        assert split.update(o, s) == plain.update(o, s)


def linear_world(w_m: float) -> tuple[RateCalibration, float, float]:
    """Output 100 V/m of the played indentation, force 2000 N/m of the indentation: the
    unloading branch 20 N/V x output, the loading one that plus 2000 x ``w_m``."""
    out = [0.0, 0.5]
    down = [20.0 * v for v in out]
    half = 1000.0 * w_m
    cal = RateCalibration(Calibration([*out], [f + half for f in down], "linear"),
                          [RateTerm(0.0, 1.0)], Play((half, half), 1e-9, INSTANT))
    return cal, 100.0, 2000.0


@settings(max_examples=40, deadline=None)
@given(w_um=st.floats(10.0, 200.0), turns=st.lists(st.floats(0.5e-3, 3e-3), min_size=2,
                                                    max_size=6),
       speed=st.floats(0.5e-3, 20e-3))
def test_a_played_record_is_recovered_wherever_the_output_moves(w_um, turns, speed):
    """Indentation up and down through random turning points, the output through the
    mock's play operator (noise-free): on every sample where the output moves, and in the
    final hold, the estimate is the true force. Only the dead zone after each reversal,
    where the output stands still while the force changes, is out of reach."""
    w = w_um * 1e-6
    cal, volts_per_m, newtons_per_m = linear_world(w)
    knots = [0.0, *turns, turns[-1]]
    times = [0.0]
    for a, b in itertools.pairwise(knots[:-1]):
        times.append(times[-1] + abs(b - a) / speed)
    times.append(times[-1] + 0.5)  # hold
    t = np.arange(0.0, times[-1], 1e-3)
    d = np.interp(t, times, knots)
    played = play_operator(d, w)
    output = volts_per_m * played
    force = estimate(cal, t, output)
    # moved by more than the band (a dead zone's end may move it by a rounding error)
    moving = np.concatenate(([False], np.abs(np.diff(output)) > 1e-6))
    on_branch = (played == d) | (played == d - w)  # not stuck in a last dead zone
    held = (t > times[-2] + 1e-3) & on_branch[-1]
    check = (moving | held) & (output > 0.0)
    assert np.any(check)
    assert np.allclose(force[check], newtons_per_m * d[check], rtol=1e-9, atol=1e-9)


@settings(max_examples=60, deadline=None)
@given(level=st.floats(0.05, 0.45), noise=st.lists(st.floats(-0.5, 0.5), min_size=1,
                                                   max_size=300),
       band=st.floats(1e-3, 0.05), smoothing=st.floats(1.0, 1000.0), rising=st.booleans())
def test_noise_within_the_band_never_flips_the_direction(level, noise, band, smoothing,
                                                         rising):
    """After a ramp (up or down) to ``level``, any output within a window narrower than the
    band keeps the ramp's direction: the smoothed output stays in that window, so it can
    never leave its extreme by more than the band."""
    tracker = DirectionTracker(band, smoothing)
    start = level - 0.2 if rising else level + 0.2
    for k, v in enumerate(np.linspace(start, level, 500).tolist()):
        tracker.update(v, 0.0 if k == 0 else 1e-3)
    assert tracker.rising == rising
    for x in noise:
        assert tracker.update(level + 0.99 * band * x, 1e-3) == rising


def test_a_reversal_beyond_the_band_switches_the_branch_and_back():
    est = PLAYED.estimator()
    t = 0.0
    for v in np.linspace(0.0, 0.3, 301).tolist():
        est.update(v, t)
        t += 1e-3
    assert est.loading
    relaxed = None
    for _ in range(20000):  # 20 s hold: terms relaxed, loading branch
        relaxed, _ = est.update(0.3, t)
        t += 1e-3
    assert relaxed == pytest.approx(3.5 + 0.1, abs=1e-6)
    for v in np.linspace(0.3, 0.2, 101).tolist():
        est.update(v, t)
        t += 1e-3
    assert not est.loading
    for _ in range(20000):
        relaxed, _ = est.update(0.2, t)
        t += 1e-3
    assert relaxed == pytest.approx(STATIC.force(0.2) - 0.075, abs=1e-6)
    for v in np.linspace(0.2, 0.3, 101).tolist():
        est.update(v, t)
        t += 1e-3
    assert est.loading


def test_reset_a_nan_and_a_clock_going_back_start_loading_again():
    for restart in ("reset", "nan", "clock"):
        est = PLAYED.estimator()
        for k, v in enumerate(np.linspace(0.3, 0.1, 201).tolist()):
            est.update(v, k * 1e-3)
        assert not est.loading
        if restart == "reset":
            est.reset()
        elif restart == "nan":
            assert math.isnan(est.update(float("nan"), 0.3)[0])
        first = est.update(0.1, 0.0 if restart == "clock" else 0.4)
        assert est.loading, restart
        assert first == (STATIC.force(0.1) + 0.05, False)


def test_the_chain_starts_the_direction_afresh_at_a_tare():
    chain = SignalChain(ChainConfig(filter_name="none", auto_tare=False), PLAYED)
    estimator = chain._estimator
    assert estimator is not None and estimator.calibration is PLAYED
    estimator.update(0.3, 0.0)
    estimator.update(0.1, 0.001)
    assert not estimator.loading
    chain.set_baseline(2.0)
    assert estimator.loading


# -- file format ----------------------------------------------------------------------------

def test_version_3_round_trip(tmp_path):
    path = tmp_path / "cal.json"
    PLAYED.to_file(path)
    data = json.loads(path.read_text())
    assert data["version"] == 3
    assert data["play"] == {"half_gap_n": list(GAP), "band_v": 0.01, "smoothing_hz": 10.0}
    loaded = load_file(path)
    assert isinstance(loaded, RateCalibration)
    assert loaded.play == PLAYED.play and loaded.terms == TERMS
    assert [b.force_n for b in loaded.branches] == [b.force_n for b in PLAYED.branches]
    assert loaded.source == f"file:{path} (test:curve)"
    assert "play: half-gap up to 0.15 N, band 10 mV" in loaded.describe()
    RateCalibration(STATIC, TERMS).to_file(path)
    assert json.loads(path.read_text())["version"] == 2  # without play: as before


def test_an_older_reader_refuses_a_play_file_in_one_sentence(tmp_path, monkeypatch):
    """A version-2 reader (FILE_VERSION 2) would run the mid curve alone, wrong by the
    half-gap everywhere; it refuses the version-3 file instead."""
    path = tmp_path / "cal.json"
    PLAYED.to_file(path)
    monkeypatch.setattr(calibration_module, "FILE_VERSION", 2)
    with pytest.raises(CalibrationError) as info:
        load_file(path)
    assert str(info.value) == (f"file:{path}: calibration file version 3 is newer than this "
                               "tactile_sensor reads (up to 2); update tactile_sensor.")


def _write(tmp_path, data):
    path = tmp_path / "cal.json"
    path.write_text(json.dumps(data))
    return path


V3 = {**PLAYED.to_dict(), "source": "x"}
PLAY = V3["play"]


@pytest.mark.parametrize(("data", "match"), [
    ({**V3, "version": 2}, "version-2 calibration file cannot hold play"),
    ({**V3, "version": 4}, "version 4 is newer than this tactile_sensor reads \\(up to 3\\)"),
    ({**V3, "play": {"band_v": 0.01}}, "play must be an object with a list 'half_gap_n'"),
    ({**V3, "play": [1, 2]}, "play must be an object"),
    ({**V3, "play": {**PLAY, "half_gap_n": [0.0, 0.1]}}, "play has 2 half-gaps but the "
                                                         "curve has 4 points"),
    ({**V3, "play": {**PLAY, "half_gap_n": [0.0, 0.1, float("nan"), 0.1]}},
     "half_gap_n contains NaN"),
    ({**V3, "play": {**PLAY, "band_v": 0.0}}, "play's band_v is 0.0"),
    ({**V3, "play": {**PLAY, "smoothing_hz": -1.0}}, "play's smoothing_hz is -1.0"),
    ({**V3, "play": {**PLAY, "half_gap_n": [0.0, 2.0, 0.0, 0.0]}}, "make a branch's force "
                                                                   "decrease"),
])
def test_bad_play_files_are_refused_with_a_reason(tmp_path, data, match):
    with pytest.raises(CalibrationError, match=match):
        load_file(_write(tmp_path, data))


def test_the_static_reader_refuses_play_rather_than_dropping_it(tmp_path):
    data = {**STATIC.to_dict(), "version": 3, "play": PLAY}
    with pytest.raises(CalibrationError, match="holds rate terms or play"):
        load_file(_write(tmp_path, data))
