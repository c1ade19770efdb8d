"""``tactile-sensor model sweep`` with shear and several modules, and ``model
array-calibration``, in-process on coarse meshes."""

from __future__ import annotations

import json

import numpy as np
import pytest

from tactile_sensor.physics.cli import main
from tactile_sensor.sensing.array_calibration import ArrayCalibration

SMALL = ["--set", "mesh_nx=4", "mesh_ny=4", "mesh_nz=16", "max_indentation=0.002"]
TINY_GRID = [*SMALL, "array_mesh_scale=1", "array_steps=3", "array_directions=4",
             "array_shear_levels=2", "--workers", "1"]


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_shear_sweep_json_has_lateral_forces_and_every_module(capsys, tmp_path):
    path = tmp_path / "shear.json"
    code, out, err = run(capsys, "sweep", *SMALL, "steps=3", "max_shear_x=0.001",
                         "modules=front,left,right", "--json", str(path), "--cache-dir",
                         str(tmp_path / "cache"))
    assert code == 0, err
    data = json.loads(path.read_text())
    assert data["shear_x_m"] == pytest.approx([0.0, 1e-3 / 3, 2e-3 / 3, 1e-3])
    assert data["shear_y_m"] == [0.0] * 4 and data["force_y_n"] == [0.0] * 4
    assert all(f > 0 for f in data["force_x_n"][1:])
    assert set(data["module_outputs_v"]) == {"front", "left", "right"}
    assert data["module_outputs_v"]["right"][-1] > data["module_outputs_v"]["left"][-1]
    assert data["module_outputs_v"]["front"] == data["output_v"]
    assert "lateral force" in out and "right" in out


def test_a_sweep_without_indentation_is_refused(capsys, tmp_path):
    code, _, err = run(capsys, "sweep", "--set", "max_indentation=0", "max_shear_x=0.001",
                       "--cache-dir", str(tmp_path))
    assert code == 2 and "needs max_indentation > 0" in err


@pytest.mark.slow
def test_array_calibration_writes_grid_fit_calibration_and_plot(capsys, tmp_path):
    paths = {name: tmp_path / name for name in ("grid.json", "cal.json", "fit.png")}
    code, out, err = run(capsys, "array-calibration", *TINY_GRID, "--degree", "2",
                         "--json", str(paths["grid.json"]), "--calibration",
                         str(paths["cal.json"]), "--plot", str(paths["fit.png"]),
                         "--cache-dir", str(tmp_path / "cache"))
    assert code == 0, err
    assert "path 3/3" in err and "[100.0%]" in err                 # progress shown
    assert "error x" in out and "miss (computed" in out
    data = json.loads(paths["grid.json"].read_text())
    assert data["fit"]["held_out_points"] == 4
    assert set(data["fit"]["held_out_rmse_n"]) == {"x", "y", "z"}
    grid = data["grid"]
    cal = ArrayCalibration.from_file(paths["cal.json"])
    assert cal.faces == ("front", "back", "left", "right") and cal.degree == 2
    outputs = np.stack([grid["outputs_v"][f] for f in cal.faces], axis=1)
    forces = np.stack([grid["force_x_n"], grid["force_y_n"], grid["force_n"]], axis=1)
    assert np.sqrt(np.mean((cal.forces(outputs) - forces) ** 2)) < 0.02 * np.ptp(forces)
    assert paths["fit.png"].read_bytes().startswith(b"\x89PNG")
    code, out, _ = run(capsys, "array-calibration", *TINY_GRID, "--degree", "2", "--quiet",
                       "--cache-dir", str(tmp_path / "cache"))
    assert code == 0 and "hit (digest" in out


@pytest.mark.parametrize("extra, match", [
    (["--degree", "0"], "--degree and --workers must be at least 1"),
    (["--degree", "6"], "lower the degree"),
    (["--set", "modules=top"], "'modules' is 'top'"),
])
def test_array_calibration_bad_input_is_one_sentence(capsys, tmp_path, extra, match):
    code, _, err = run(capsys, "array-calibration", *TINY_GRID, *extra, "--quiet",
                       "--cache-dir", str(tmp_path))
    assert code == 2 and match in err and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1


def test_array_calibration_refuses_an_output_folder_that_is_missing(capsys, tmp_path):
    code, _, err = run(capsys, "array-calibration", *TINY_GRID, "--calibration",
                       str(tmp_path / "no" / "cal.json"))
    assert code == 2 and "does not exist; create it first" in err


EIGHT_GRID = [*TINY_GRID[:-2], "modules=front@-0.0055,front@0.0055,back@-0.0055,"
              "back@0.0055,left@-0.0055,left@0.0055,right@-0.0055,right@0.0055", "--workers",
              "1"]


@pytest.mark.slow
def test_array_calibration_with_wrench_writes_six_columns_and_observed(capsys, tmp_path):
    cal_path = tmp_path / "six.json"
    code, out, err = run(capsys, "array-calibration", *EIGHT_GRID, "--degree", "1",
                         "--wrench", "--torque-noise", "0.001", "--calibration",
                         str(cal_path), "--cache-dir", str(tmp_path / "cache"))
    assert code == 0, err
    data = json.loads(cal_path.read_text())
    assert data["version"] == 2 and data["observed"] == ["fx", "fy", "fz", "tx", "ty", "tz"]
    assert data["fit"]["grid_torque"] == "fem"
    assert all(v < 10.0 for v in data["fit"]["torque_held_out_rmse_percent_of_range"].values())
    assert "error tz" in out and "observed        fx, fy, fz, tx, ty, tz" in out
    cal = ArrayCalibration.from_file(cal_path)
    assert cal.has_torque and cal.faces[0] == "front@-0.0055"
    # the cached wrench set serves the next run; at the paper's 13 mV (a driver without the
    # torque's low-pass) this tiny mesh observes no torque
    code, out, err = run(capsys, "array-calibration", *EIGHT_GRID, "--degree", "1",
                         "--wrench", "--torque-noise", "0.013", "--cache-dir",
                         str(tmp_path / "cache"))
    assert code == 0 and "path 1/4" not in err
    assert "observed        fx, fy, fz (wrench_observability at 13.0 mV" in out


def test_torque_noise_needs_the_wrench_fit(capsys, tmp_path):
    code, _, err = run(capsys, "array-calibration", "--torque-noise", "0.001",
                       "--cache-dir", str(tmp_path))
    assert code == 2 and "--torque-noise needs --wrench and a noise in (0, 1] V." in err
