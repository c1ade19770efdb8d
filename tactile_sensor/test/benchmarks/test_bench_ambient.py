"""benchmarks/bench_ambient.py: the driver's defaults read a held-out lit room (a 120 Hz lamp
and a lamp switched off at rest, scenes no setting was chosen on) press by press within
1.5 x the dark room's RMSE, and the defaults are what a driver started with no setting
changed runs."""

from __future__ import annotations

import importlib
import sys
from pathlib import Path

import pytest

pytest.importorskip("rclpy")  # the driver's declared defaults (nodes/driver_parameters.py)

BENCHMARKS = Path(__file__).resolve().parents[3] / "benchmarks"
sys.path.insert(0, str(BENCHMARKS))
bench_ambient = importlib.import_module("bench_ambient")


def test_the_defaults_are_the_notch_and_the_re_tare_at_rest():
    from tactile_sensor.sensing.chain import ChainConfig

    config = bench_ambient.default_config()
    assert config == ChainConfig()
    assert config.filter_name == "savgol_mains" and config.rest_retare_time_constant_s > 0


def test_a_held_out_lit_room_reads_as_the_dark_room_press_by_press():
    dark = bench_ambient.run("dark", 1, driver="defaults")
    lit = bench_ambient.run("kitchen", 1, driver="defaults")
    plain = bench_ambient.run("kitchen", 1, bench_ambient.PLAIN_FILTER)
    assert lit["scene"].flicker_hz == 120.0 and lit["scene"].steps
    for (rmse, blind), (dark_rmse, _), (plain_rmse, _) in zip(
            lit["phases"], dark["phases"], plain["phases"], strict=True):
        assert blind == 0.0
        assert rmse <= bench_ambient.HELD_OUT_GOAL * dark_rmse < plain_rmse
