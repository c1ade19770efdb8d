from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from tactile_sensor.sensing.calibration import Calibration
from tactile_sensor.sensing.errors import CalibrationError

CAL = Calibration.from_curve([0.0, 0.1, 0.5], [0.0, 1.0, 7.0], "test")


def test_interpolates_linearly_and_flags_saturation():
    assert CAL.force(0.05) == pytest.approx(0.5)
    assert CAL.force(0.3) == pytest.approx(4.0)
    assert CAL.evaluate(0.5) == (7.0, False)
    assert CAL.evaluate(0.6) == (7.0, True)
    assert CAL.evaluate(-0.02) == (0.0, False)
    force, saturated = CAL.evaluate(float("nan"))
    assert np.isnan(force) and not saturated


def test_the_full_scale_is_the_most_force_the_curve_reports():
    assert CAL.full_scale_force_n == 7.0
    assert CAL.max_output_v == 0.5
    assert repr(CAL) == "Calibration(3 points, output 0..0.500 V, source='test')"
    assert max(CAL.force(x) for x in (0.4, 0.5, 0.6, 10.0)) == CAL.full_scale_force_n


@given(st.floats(-1.0, 1.0))
def test_agrees_with_numpy_interp(x):
    assert CAL.force(x) == pytest.approx(float(np.interp(x, CAL.output_v, CAL.force_n)))


def test_file_round_trip_reports_its_source(tmp_path):
    path = tmp_path / "cal.json"
    CAL.to_file(path, fit={"rmse_n": 0.1})
    loaded = Calibration.from_file(path)
    assert loaded.output_v == CAL.output_v and loaded.force_n == CAL.force_n
    assert loaded.source == f"file:{path} (test)"
    assert json.loads(path.read_text())["fit"] == {"rmse_n": 0.1}


def test_from_prediction_curve_names_the_digest():
    curve = SimpleNamespace(digest="abc123",
                            calibration=lambda: (np.array([0.0, 0.4]), np.array([0.0, 6.0])))
    cal = Calibration.from_prediction_curve(curve)
    assert cal.source == "fem:abc123"
    assert cal.force(0.2) == pytest.approx(3.0)


def _write(tmp_path, content):
    path = tmp_path / "cal.json"
    path.write_text(content if isinstance(content, str) else json.dumps(content))
    return path


BASE = {"format": "tactile_sensor/calibration", "version": 1, "output_v": [0.0, 1.0],
        "force_n": [0.0, 5.0], "source": "x"}


@pytest.mark.parametrize(("content", "match"), [
    ("{not json", "not valid JSON"),
    ([1, 2], "JSON object"),
    ({**BASE, "format": "other"}, "not a calibration file"),
    ({**BASE, "version": 4}, "version 4 is newer than this tactile_sensor reads"),
    ({**BASE, "version": None}, "not a version"),
    ({k: v for k, v in BASE.items() if k != "force_n"}, "missing array"),
    ({**BASE, "output_v": [0.0, "a"]}, "numbers"),
    ({**BASE, "output_v": [1.0, 0.0]}, "strictly increasing"),
    ({**BASE, "output_v": [0.0, 0.0]}, "strictly increasing"),
    ({**BASE, "force_n": [5.0, 0.0]}, "non-decreasing"),
    ({**BASE, "force_n": [0.0]}, "pair up"),
    ({**BASE, "output_v": [0.0], "force_n": [0.0]}, "at least 2"),
])
def test_bad_files_are_refused_with_a_reason(tmp_path, content, match):
    with pytest.raises(CalibrationError, match=match):
        Calibration.from_file(_write(tmp_path, content))


def test_missing_file(tmp_path):
    with pytest.raises(CalibrationError, match="does not exist"):
        Calibration.from_file(tmp_path / "nope.json")


def test_non_finite_curve_is_refused():
    with pytest.raises(CalibrationError, match="NaN"):
        Calibration.from_curve([0.0, float("nan")], [0.0, 1.0], "model")
