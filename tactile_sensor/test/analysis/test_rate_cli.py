"""`tactile-sensor analyze --fit-calibration` on a recording at several speeds writes the
rate terms (file version 2); `--calibration` reports static vs rate-aware per speed and
phase. The bag's gauge force comes from physics' RateDependentForce."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from tactile_sensor.analysis import cli
from tactile_sensor.analysis.synthetic import (
    PressProtocol,
    SensorTruth,
    press_signals,
    write_press_bag,
)
from tactile_sensor.physics.viscoelastic import RateDependentForce
from tactile_sensor.sensing.rate_calibration import RateCalibration, load_file

PROTOCOL = PressProtocol(speeds_mm_s=(1.0, 10.0), cycles=(1, 2), rate_hz=200.0, rest_s=1.0,
                         hold_s=1.5)
TRUTH = SensorTruth(noise_v=0.002, lag_s={1.0: 0.0, 10.0: 0.0}, hysteresis_frac=0.0,
                    rate_gain_per_decade=0.0)
PHASES = {"loading", "hold", "unloading"}


@pytest.fixture(scope="module")
def bag(tmp_path_factory):
    signals = press_signals(PROTOCOL, TRUTH, seed=3)
    force = RateDependentForce((0.05, 0.04), (0.1, 1.5)).force_history(signals.t_s,
                                                                       signals.force_n)
    path = tmp_path_factory.mktemp("bags") / "speeds"
    return write_press_bag(path, dataclasses.replace(signals, force_n=force), "mcap")


def analyze(argv, capsys):
    code = cli.main([*map(str, argv), "--quiet", "--no-figures", "--prediction", "none"])
    err = capsys.readouterr().err
    assert code == 0, err
    return json.loads((argv[argv.index("--out") + 1] / "metrics.json").read_text())


def test_fit_writes_rate_terms_and_evaluating_the_file_reports_each_phase(bag, tmp_path,
                                                                          capsys):
    fit_dir = tmp_path / "fit"
    metrics = analyze([str(bag), "--out", fit_dir, "--fit-calibration"], capsys)
    data = json.loads((fit_dir / "calibration.json").read_text())
    assert data["version"] in (2, 3) and 1 <= len(data["rate_terms"]) <= 3  # 3: with play
    assert set(data["fit"]["held_out_rmse_n"]["1"]) == {"1.0", "10.0"}
    cal = load_file(fit_dir / "calibration.json")
    assert isinstance(cal, RateCalibration)
    assert cal.instant_gain == pytest.approx(1.09, abs=0.03)
    table = metrics["calibration_error"]["by_speed_phase"]
    assert set(table) == {"1.0", "10.0"} and set(table["10.0"]) == PHASES
    fast = table["10.0"]["loading"]
    assert fast["rate_rmse_n"] < 0.5 * fast["static_rmse_n"]

    eval_dir = tmp_path / "eval"
    again = analyze([str(bag), "--out", eval_dir, "--calibration",
                     fit_dir / "calibration.json"], capsys)
    err = again["calibration_error"]
    assert not err["in_sample"] and err["rate_terms"] == data["rate_terms"]
    assert err["by_speed_phase"] == table  # same recording, same forces
    report = (eval_dir / "report.md").read_text()
    assert "Force RMSE at 10.0 mm/s, hold" in report


def test_a_static_calibration_file_gets_no_phase_table(bag, tmp_path, capsys):
    signals = press_signals(dataclasses.replace(PROTOCOL, speeds_mm_s=(1.0,), cycles=(2,)),
                            TRUTH, seed=4)
    one = write_press_bag(tmp_path / "one", signals, "mcap")
    fit_dir = tmp_path / "fit"
    metrics = analyze([str(one), "--out", fit_dir, "--fit-calibration"], capsys)
    assert json.loads((fit_dir / "calibration.json").read_text())["version"] == 1
    assert metrics["calibration_error"]["rate_terms"] is None
    assert "by_speed_phase" not in metrics["calibration_error"]
    assert np.isfinite(metrics["calibration_error"]["by_speed"]["1.0"]["rmse_n"])
