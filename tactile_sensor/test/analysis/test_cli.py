"""`tactile-sensor analyze`: outputs on good bags, one clear sentence on every bad input."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
from press_recordings import FOUR_PRESSES as PROTOCOL

from tactile_sensor import cli as top_cli
from tactile_sensor.analysis.synthetic import (
    PressProtocol,
    SensorTruth,
    press_signals,
    write_press_bag,
)

TRUTH = SensorTruth(noise_v=0.005, lag_s={10.0: 0.0}, hysteresis_frac=0.0,
                    rate_gain_per_decade=0.0)
EXPECTED_KEYS = {"sensitivity_v_per_n", "dynamic_range_db", "hysteresis_pct_fs",
                 "peak_output_cv_pct", "drift_pct", "phase_lag_s", "full_scale_n"}


@pytest.fixture(scope="module")
def bags(tmp_path_factory):
    root = tmp_path_factory.mktemp("bags")
    a = write_press_bag(root / "a", press_signals(PROTOCOL, TRUTH, seed=1), "sqlite3")
    b = write_press_bag(root / "b", press_signals(PROTOCOL, TRUTH, seed=2), "mcap")
    return a, b


@pytest.mark.slow
def test_fit_on_one_bag_evaluate_on_another_with_prediction_overlay(run, bags, tmp_path, capsys):
    a, b = bags
    d = np.linspace(0, PROTOCOL.depth_m, 50)
    model = TRUTH.sensitivity_v_per_n * TRUTH.elastic_force_n(d, PROTOCOL.depth_m)
    pred = tmp_path / "sweep.json"
    pred.write_text(json.dumps({"indentation_m": d.tolist(), "output_v": model.tolist(),
                                "force_n": []}))
    out_a = tmp_path / "a"
    code, err = run([str(a), "--out", str(out_a), "--fit-calibration", "--prediction",
                     str(pred)], capsys)
    assert code == 0, err
    names = {p.name for p in out_a.iterdir()}
    assert {"metrics.json", "calibration.json", "report.md", "report.html",
            "force_vs_indentation.png", "output_vs_indentation.png", "output_vs_force.png",
            "cycles.png", "first_last_cycles.png", "speeds.png"} <= names
    metrics = json.loads((out_a / "metrics.json").read_text())
    assert metrics.keys() >= EXPECTED_KEYS
    assert list(metrics["phase_lag_s"]) == ["10.0"]
    assert metrics["prediction"]["rmse_v"] < 0.01  # model == truth; only noise remains
    assert "0.07 V/N" in (out_a / "report.md").read_text()

    calibration = json.loads((out_a / "calibration.json").read_text())
    assert calibration["format"] == "tactile_sensor/calibration"
    assert np.all(np.diff(calibration["output_v"]) > 0)
    assert np.all(np.diff(calibration["force_n"]) >= 0)
    # the fitted curve is the inverse of output = 0.07 F (within 2 % of full scale)
    out_v = np.array(calibration["output_v"])
    mid = (out_v > 0.05) & (out_v < 0.45)
    np.testing.assert_allclose(np.array(calibration["force_n"])[mid], out_v[mid] / 0.07,
                               atol=0.02 * 7.0)

    out_b = tmp_path / "b"
    code, err = run([str(b), "--out", str(out_b), "--calibration",
                     str(out_a / "calibration.json"), "--prediction", "none", "--no-figures"],
                    capsys)
    assert code == 0, err
    held_out = json.loads((out_b / "metrics.json").read_text())["calibration_error"]
    assert held_out["in_sample"] is False
    noise_n = TRUTH.noise_v / TRUTH.sensitivity_v_per_n
    assert held_out["by_speed"]["10.0"]["rmse_n"] == pytest.approx(noise_n, rel=0.3)


def test_prediction_offset_shows_in_the_comparison(run, bags, tmp_path, capsys):
    d = np.linspace(0, PROTOCOL.depth_m, 50)
    model = TRUTH.sensitivity_v_per_n * TRUTH.elastic_force_n(d, PROTOCOL.depth_m) + 0.05
    pred = tmp_path / "sweep.json"
    pred.write_text(json.dumps({"indentation_m": d.tolist(), "output_v": model.tolist()}))
    code, err = run([str(bags[0]), "--out", str(tmp_path / "o"), "--prediction", str(pred),
                     "--no-figures"], capsys)
    assert code == 0, err
    assert not list((tmp_path / "o").glob("*.png"))
    metrics = json.loads((tmp_path / "o" / "metrics.json").read_text())
    assert metrics["prediction"]["rmse_v"] == pytest.approx(0.05, abs=0.01)


def test_top_level_command_dispatches_to_analyze(assert_one_sentence, bags, tmp_path, capsys):
    code = top_cli.main(["analyze", str(bags[1]), "--out", str(tmp_path), "--prediction",
                         "none", "--reading-topic", "/nope", "--quiet"])
    assert_one_sentence(code, capsys.readouterr().err, "/nope", "--reading-topic")


def test_missing_bag(run, assert_one_sentence, tmp_path, capsys):
    code, err = run([str(tmp_path / "absent"), "--out", str(tmp_path / "o"),
                     "--prediction", "none"], capsys)
    assert_one_sentence(code, err, "does not exist")


@pytest.mark.parametrize("storage", ["sqlite3", "mcap"])
@pytest.mark.parametrize("damage", ["garbage", "truncate"])
def test_corrupt_or_truncated_bag(run, assert_one_sentence, tmp_path, capsys, storage, damage):
    bag = write_press_bag(tmp_path / "bag", press_signals(PROTOCOL, TRUTH), storage)
    (data,) = [p for p in bag.iterdir() if p.suffix in (".db3", ".mcap")]
    raw = data.read_bytes()
    data.write_bytes(b"\x13garbage" * 64 if damage == "garbage" else raw[: len(raw) // 2])
    code, err = run([str(bag), "--out", str(tmp_path / "o"), "--prediction", "none"], capsys)
    assert_one_sentence(code, err, "cannot read the bag")


def test_missing_topic(run, assert_one_sentence, bags, tmp_path, capsys):
    code, err = run([str(bags[0]), "--out", str(tmp_path), "--prediction", "none",
                     "--position-topic", "/stage/none"], capsys)
    assert_one_sentence(code, err, "/stage/none", "--position-topic", "/driver/reading")


def test_topic_of_the_wrong_type(run, assert_one_sentence, bags, tmp_path, capsys):
    code, err = run([str(bags[0]), "--out", str(tmp_path), "--prediction", "none",
                     "--reading-topic", "/bench/gauge/wrench"], capsys)
    assert_one_sentence(code, err, "WrenchStamped", "no field output")


def _cut(signals, n):
    return dataclasses.replace(signals, t_s=signals.t_s[:n],
                               indentation_m=signals.indentation_m[:n],
                               force_n=signals.force_n[:n], output_v=signals.output_v[:n])


@pytest.mark.parametrize("case", ["flat", "cut_mid_press"])
def test_empty_segment(run, assert_one_sentence, tmp_path, capsys, case):
    signals = press_signals(PressProtocol(speeds_mm_s=(10.0,), cycles=(1,), rate_hz=200.0),
                            TRUTH)
    if case == "flat":
        signals = dataclasses.replace(signals, indentation_m=np.zeros_like(signals.t_s))
        expected = "no press"
    else:
        signals = _cut(signals, int(np.argmax(signals.indentation_m)) + 20)
        expected = "empty segment"
    bag = write_press_bag(tmp_path / "bag", signals, "mcap")
    code, err = run([str(bag), "--out", str(tmp_path / "o"), "--prediction", "none"], capsys)
    assert_one_sentence(code, err, expected)


BAD_CALIBRATIONS = {
    "not_json": ("{output_v: [", "not valid JSON"),
    "wrong_format": (json.dumps({"format": "other", "version": 1}),
                     "not a calibration file"),
    "wrong_version": (json.dumps({"format": "tactile_sensor/calibration", "version": 7,
                                  "output_v": [0, 1], "force_n": [0, 1]}), "version 7"),
    "short": (json.dumps({"format": "tactile_sensor/calibration", "version": 1,
                          "output_v": [0.1], "force_n": [1.0]}), "at least 2 points"),
    "text": (json.dumps({"format": "tactile_sensor/calibration", "version": 1,
                         "output_v": ["a", "b"], "force_n": [0, 1]}), "must hold numbers"),
    "unpaired": (json.dumps({"format": "tactile_sensor/calibration", "version": 1,
                             "output_v": [0, 1, 2], "force_n": [0, 1]}), "pair up"),
    "not_increasing": (json.dumps({"format": "tactile_sensor/calibration", "version": 1,
                                   "output_v": [0, 0, 2], "force_n": [0, 1, 2]}),
                       "strictly increasing"),
    "force_decreasing": (json.dumps({"format": "tactile_sensor/calibration", "version": 1,
                                     "output_v": [0, 1, 2], "force_n": [0, 2, 1]}),
                         "non-decreasing"),
}


@pytest.mark.parametrize("case", sorted(BAD_CALIBRATIONS))
def test_bad_calibration_file(run, assert_one_sentence, bags, tmp_path, capsys, case):
    text, fragment = BAD_CALIBRATIONS[case]
    path = tmp_path / "cal.json"
    path.write_text(text)
    code, err = run([str(bags[0]), "--out", str(tmp_path / "o"), "--prediction", "none",
                     "--calibration", str(path)], capsys)
    assert_one_sentence(code, err, fragment)


def test_missing_calibration_file(run, assert_one_sentence, bags, tmp_path, capsys):
    code, err = run([str(bags[0]), "--out", str(tmp_path / "o"), "--prediction", "none",
                     "--calibration", str(tmp_path / "nope.json")], capsys)
    assert_one_sentence(code, err, "nope.json does not exist")


@pytest.mark.parametrize(("text", "fragment"), [
    ("[1, 2", "not valid JSON"),
    (json.dumps({"indentation_m": [0, 1e-3]}), "output_v"),
    (json.dumps({"indentation_m": [1e-3, 0], "output_v": [0, 1]}), "strictly increasing"),
])
def test_bad_prediction_file(run, assert_one_sentence, bags, tmp_path, capsys, text, fragment):
    path = tmp_path / "p.json"
    path.write_text(text)
    code, err = run([str(bags[0]), "--out", str(tmp_path / "o"), "--prediction", str(path)],
                    capsys)
    assert_one_sentence(code, err, fragment)


def test_bad_noise_window(run, assert_one_sentence, bags, tmp_path, capsys):
    code, err = run([str(bags[0]), "--out", str(tmp_path / "o"), "--prediction", "none",
                     "--noise-window", "0"], capsys)
    assert_one_sentence(code, err, "--noise-window")
