"""Module noise at an output bandwidth, the study keys that use it, boards and zipped designs."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tactile_sensor.physics.errors import PhysicsError
from tactile_sensor.physics.observability import component_noise
from tactile_sensor.physics.output_noise import (
    SAMPLE_NOISE_V,
    butterworth_enbw_hz,
    noise_at_bandwidth,
)
from tactile_sensor.physics.wrench import WRENCH_AXES
from tactile_sensor.sensing.filters import Butterworth
from tactile_sensor.sim.adc_device import white_noise_for_dynamic_range
from tactile_sensor.studies.run import run_study
from tactile_sensor.studies.spec import BOARDS, parse_spec

EIGHT = ",".join(f"{f}@{s * 0.0055}" for f in ("front", "back", "left", "right")
                 for s in (-1, 1))


def test_the_sample_noise_is_the_mock_adcs():
    assert white_noise_for_dynamic_range() == pytest.approx(SAMPLE_NOISE_V, rel=1e-3)


def test_the_noise_bandwidth_of_the_drivers_filter():
    """ENBW 1.11 fc for order 2, and the digital filter's own white-noise gain agrees."""
    assert butterworth_enbw_hz(10.0) == pytest.approx(10.0 * (math.pi / 4) / math.sin(
        math.pi / 4))
    assert butterworth_enbw_hz(10.0) == pytest.approx(11.107, rel=1e-4)
    assert butterworth_enbw_hz(10.0, order=1) == pytest.approx(10.0 * math.pi / 2)
    fs, fc = 1000.0, 10.0
    f = Butterworth(fs, order=2, cutoff_hz=fc)
    f.update(0.0)                                         # at rest from the first sample
    impulse = np.array([f.update(x) for x in [1.0] + [0.0] * 3000])
    gain = float(np.sqrt(np.sum(impulse ** 2)))           # sigma_out / sigma_in
    assert noise_at_bandwidth(fc, 1.0, fs) == pytest.approx(gain, rel=0.01)
    assert noise_at_bandwidth(10.0) == pytest.approx(0.0391 * 0.149, rel=0.01)


@pytest.mark.parametrize("args, match", [
    ((0.0,), "must be positive finite numbers"),
    ((10.0, math.nan), "must be positive finite numbers"),
    ((500.0,), "not below the Nyquist frequency of 1000 Hz sampling"),
])
def test_a_bad_bandwidth_is_one_sentence(args, match):
    with pytest.raises(PhysicsError, match=match):
        noise_at_bandwidth(*args)


def test_the_estimate_noise_is_the_least_squares_covariance():
    s = np.diag([2.0, 0.5])
    np.testing.assert_allclose(component_noise(s, 0.1), [0.05, 0.2])
    assert np.all(np.isinf(component_noise(np.array([[1.0, 1.0], [1.0, 1.0]]), 0.1)))


def test_the_spec_takes_the_noise_at_its_bandwidth():
    base = {"vary": {"modules": [EIGHT]}, "metrics": ["wrench_observability"]}
    assert parse_spec(base).output_noise_v == 0.013
    spec = parse_spec({**base, "bandwidth_hz": 10})
    assert spec.output_noise_v == pytest.approx(noise_at_bandwidth(10.0))
    assert parse_spec({**base, "bandwidth_hz": 10, "sample_noise_v": 0.01,
                       "sample_rate_hz": 500}).output_noise_v == pytest.approx(
        noise_at_bandwidth(10.0, 0.01, 500.0))
    for hz in (1, 10, 100):
        assert f"noise_tz_pct_fs_{hz}hz" in spec.columns
    assert {a: f"noise_{a}_pct_fs_1hz" in spec.columns for a in WRENCH_AXES} == \
        dict.fromkeys(WRENCH_AXES, True)


def test_boards_have_their_analog_pin_counts():
    assert BOARDS == {"uno": 6, "nano": 8, "leonardo": 12, "mega": 16}


def test_a_zip_design_pairs_the_lists():
    spec = parse_spec({"vary": {"modules": ["front", EIGHT], "board": ["uno", "nano"],
                                "window_pigment_gradient": [0, 50]}, "design": "zip"})
    assert [(d["board"], d["window_pigment_gradient"]) for d in spec.designs()] == \
        [("uno", 0.0), ("nano", 50.0)]


def test_a_layout_with_more_modules_than_channels_is_refused_before_solving(tmp_path,
                                                                           monkeypatch):
    sent: list[dict] = []

    def run(task, args, **kwargs):             # records what would be solved
        sent.extend(a[0] for a in args)
        return iter(())

    monkeypatch.setattr("tactile_sensor.studies.run.run", run)
    spec = parse_spec({"vary": {"modules": [EIGHT, "front,back,left,right"],
                                "board": ["uno", "uno"]}, "design": "zip",
                       "metrics": ["wrench_observability"]})
    rows = run_study(spec, workers=1, cache_dir=tmp_path)
    assert rows[1].error == ("rejected: The layout needs 8 modules but board 'uno' has 6 "
                             "analog channels; use fewer modules or a board with at least 8.")
    assert rows[2].error == "" and rows[0].error == ""
    assert sorted(v["modules"] for v in sent) == ["front", "front,back,left,right"]
