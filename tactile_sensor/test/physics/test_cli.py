"""``tactile-sensor model sweep`` end to end, in-process and once as a real process.

Sweeps use coarse meshes and the 'frictionless' boundary (homogeneous compression, robust
while the bonded solver is still being tuned) with a per-test cache folder.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from tactile_sensor import cli as top_cli
from tactile_sensor.physics import fem
from tactile_sensor.physics.cli import main
from tactile_sensor.physics.errors import ConvergenceError

SOURCE = Path(__file__).resolve().parents[2]
COARSE = ["--boundary", "frictionless", "--set", "mesh_nx=2", "mesh_ny=2", "mesh_nz=4",
          "steps=4"]


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def one_sentence(err: str) -> str:
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1, err
    assert "Traceback" not in err
    return lines[0]


def test_model_help_lists_sweep(capsys):
    assert top_cli.main(["model", "--help"]) == 0
    assert "sweep" in capsys.readouterr().out
    code, out, _ = run(capsys, "sweep", "--help")
    assert code == 0 and "--set" in out and "max_indentation" in out


@pytest.mark.slow
def test_sweep_writes_json_and_plot_then_hits_the_cache(capsys, tmp_path):
    json_path, png_path = tmp_path / "curve.json", tmp_path / "curve.figure"  # PNG anyway
    code, out, err = run(capsys, "sweep", *COARSE, "--json", str(json_path), "--plot",
                         str(png_path), "--cache-dir", str(tmp_path / "cache"))
    assert code == 0, err
    data = json.loads(json_path.read_text())
    arrays = ("indentation_m", "force_n", "bulge_m", "distance_m", "voltage_v", "output_v")
    assert all(len(data[k]) == 5 for k in arrays)
    assert data["indentation_m"][-1] == pytest.approx(3e-3)
    assert data["force_n"][-1] > data["force_n"][1] > 0
    assert data["output_v"][-1] > 0
    assert data["nodes"] > 0 and data["seconds"] >= 0
    assert data["params"]["boundary"] == "frictionless" and data["params"]["mesh_nz"] == 4
    png = png_path.read_bytes()
    assert png.startswith(b"\x89PNG\r\n\x1a\n") and len(png) > 5000
    assert "%]" in err and "load step 4/4" in err  # progress of the cold sweep
    assert f"force           {data['force_n'][-1]:.3f} N" in out
    sensitivity = data["output_v"][-1] / data["force_n"][-1]
    assert f"sensitivity     {sensitivity:.4f} V/N" in out
    assert f"nodes           {data['nodes']}" in out
    assert "cache           miss" in out

    code, out, err = run(capsys, "sweep", *COARSE, "--cache-dir", str(tmp_path / "cache"))
    assert code == 0
    assert "cache           hit" in out
    assert "load step" not in err  # nothing computed


def test_no_cache_computes_and_stores_nothing(capsys, tmp_path):
    code, out, _ = run(capsys, "sweep", *COARSE, "--no-cache", "--quiet",
                       "--cache-dir", str(tmp_path / "cache"))
    assert code == 0
    assert "cache           off" in out
    assert not (tmp_path / "cache").exists()


def test_steps_flag_overrides_set(capsys, tmp_path):
    path = tmp_path / "c.json"
    code, _, _ = run(capsys, "sweep", *COARSE, "--steps", "2", "--quiet", "--json", str(path),
                     "--cache-dir", str(tmp_path))
    assert code == 0
    assert len(json.loads(path.read_text())["force_n"]) == 3


@pytest.mark.parametrize(("args", "match"), [
    (["--set", "foo=1"], "unknown physics parameter 'foo'"),
    (["--set", "height=abc"], "'height' must be a float"),
    (["--set", "mesh_nx=2.5"], "'mesh_nx' must be"),
    (["--set", "height=-0.01"], "'height' is -0.01"),
    (["--set", "gap=nan"], "'gap' must be a finite number"),
    (["--set", "max_indentation=0.02"], "exceeds 60 %"),
    (["--set", "height"], "expects NAME=VALUE"),
    (["--set", "=3"], "expects NAME=VALUE"),
    (["--boundary", "glued"], "invalid choice"),
    (["--steps", "many"], "invalid int value"),
    (["--bogus"], "unrecognized arguments"),
])
def test_bad_command_line_exits_2_with_one_sentence(capsys, tmp_path, args, match):
    code, out, err = run(capsys, "sweep", *args, "--cache-dir", str(tmp_path))
    assert code == 2
    assert match in one_sentence(err)
    assert out == ""
    assert not list(tmp_path.iterdir())  # refused before any sweep


def test_missing_command_exits_2(capsys):
    code, _, err = run(capsys)
    assert code == 2 and "required" in one_sentence(err)


def test_output_in_missing_folder_is_refused_before_the_sweep(capsys, tmp_path):
    code, _, err = run(capsys, "sweep", *COARSE, "--json", str(tmp_path / "no" / "c.json"),
                       "--cache-dir", str(tmp_path / "cache"))
    assert code == 2 and "does not exist" in one_sentence(err)
    assert not (tmp_path / "cache").exists()


def write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


def test_flat_config_file(capsys, tmp_path):
    config = write(tmp_path / "physics.yaml",
                   "# flat form\ngap: 0.0025\nboundary: frictionless\nmesh_nx: 2\n"
                   "mesh_ny: 2\nmesh_nz: 4\nsteps: 3\npigment_white: 50\n")
    path = tmp_path / "c.json"
    code, _, err = run(capsys, "sweep", "--config", str(config), "--quiet", "--json",
                       str(path), "--cache-dir", str(tmp_path / "cache"))
    assert code == 0, err
    data = json.loads(path.read_text())
    assert data["distance_m"][0] == pytest.approx(0.0025)
    assert data["params"]["pigment_white"] == 50.0
    assert len(data["force_n"]) == 4


def test_ros_params_config_file_with_set_on_top(capsys, tmp_path):
    config = write(tmp_path / "physics.yaml", """\
/**:
  ros__parameters:
    gap: 0.0024
    boundary: frictionless
    mesh_nx: 2
    mesh_ny: 2
    mesh_nz: 4
    steps: 3
    use_sim_time: false         # not a physics parameter: ignored
/**/model:
  ros__parameters:
    cache_dir: ""               # not a physics parameter: ignored
    pigment_white: 100.0
""")
    path = tmp_path / "c.json"
    code, _, err = run(capsys, "sweep", "--config", str(config), "--set", "steps=2",
                       "--quiet", "--json", str(path), "--cache-dir", str(tmp_path / "cache"))
    assert code == 0, err
    data = json.loads(path.read_text())
    assert data["distance_m"][0] == pytest.approx(0.0024)
    assert data["params"]["pigment_white"] == 100.0
    assert len(data["force_n"]) == 3  # --set beats the file


def test_repository_physics_config_is_accepted(capsys, tmp_path):
    config = SOURCE / "config" / "physics.yaml"
    if not config.is_file():
        pytest.skip("config/physics.yaml is not written yet")
    code, _, err = run(capsys, "sweep", "--config", str(config), *COARSE, "--quiet",
                       "--cache-dir", str(tmp_path))
    assert code == 0, err


@pytest.mark.parametrize(("text", "match"), [
    ("gap: [0.002\n", "not valid YAML at line"),
    ("gap: 0.002\n\tsteps: 3\n", "not valid YAML"),
    ("- gap\n- 0.002\n", "must hold a mapping"),
    ("gapp: 0.002\n", "Unknown physics parameter 'gapp'"),
    ("gap: wide\n", "'gap' must be a float"),
    ("/**:\n  ros__parameters:\n    gap: 0.002\nsteps: 3\n", "mixes ROS params"),
    ("/**:\n  ros__parameters: [1, 2]\n", "is not a mapping"),
    ("/**:\n  ros__parameters:\n    steps: 0\n", "'steps' is 0"),
])
def test_bad_config_file_exits_2_with_one_sentence(capsys, tmp_path, text, match):
    config = write(tmp_path / "bad.yaml", text)
    code, _, err = run(capsys, "sweep", "--config", str(config), "--cache-dir", str(tmp_path))
    assert code == 2
    assert match in one_sentence(err)


def test_unreadable_config_file_exits_2(capsys, tmp_path):
    code, _, err = run(capsys, "sweep", "--config", str(tmp_path / "missing.yaml"))
    assert code == 2 and "cannot read the config file" in one_sentence(err)
    binary = tmp_path / "binary.yaml"
    binary.write_bytes(b"\xff\xfe\x00\x01")
    code, _, err = run(capsys, "sweep", "--config", str(binary))
    assert code == 2 and "not UTF-8" in one_sentence(err)


def test_empty_config_file_means_defaults(capsys, tmp_path):
    config = write(tmp_path / "empty.yaml", "# nothing set\n")
    path = tmp_path / "c.json"
    code, _, err = run(capsys, "sweep", "--config", str(config), *COARSE, "--quiet",
                       "--json", str(path), "--cache-dir", str(tmp_path / "cache"))
    assert code == 0, err
    assert json.loads(path.read_text())["params"]["gap"] == 0.002


def test_physics_error_during_the_sweep_exits_1(capsys, tmp_path):
    # a 10 um gap: the skin bulges past the photoreflector
    code, out, err = run(capsys, "sweep", *COARSE, "gap=1e-5", "--quiet",
                         "--cache-dir", str(tmp_path))
    assert code == 1
    assert "increase 'gap'" in one_sentence(err)
    assert out == ""


@pytest.mark.skipif(not Path("/proc/version").is_file(), reason="needs Linux /proc")
def test_unwritable_output_exits_1(capsys, tmp_path):
    # /proc/version refuses writes even for root (tmp_path permissions would not)
    code, _, err = run(capsys, "sweep", *COARSE, "--quiet", "--cache-dir", str(tmp_path),
                       "--json", "/proc/version")
    assert code == 1
    assert "cannot write /proc/version" in one_sentence(err)


def test_convergence_error_exits_1(capsys, tmp_path, monkeypatch):
    def diverge(self: fem.SkinModel, progress: object = None) -> fem.SweepResult:
        raise ConvergenceError("The FEM Newton solve did not converge; use more load steps.")

    monkeypatch.setattr(fem.SkinModel, "sweep", diverge)  # the CLI's error path only
    code, _, err = run(capsys, "sweep", *COARSE, "--quiet", "--cache-dir", str(tmp_path))
    assert code == 1
    assert "did not converge" in one_sentence(err)


@pytest.mark.slow
def test_real_process_prints_one_sentence_not_a_traceback():
    proc = subprocess.run(
        [sys.executable, "-m", "tactile_sensor.physics.cli", "sweep", "--set", "widht=0.02"],
        cwd=SOURCE, capture_output=True, text=True, timeout=60, check=False)
    assert proc.returncode == 2
    assert "unknown physics parameter 'widht'" in one_sentence(proc.stderr)


_CHURN = """
import resource, sys
import numpy as np
from tactile_sensor.physics.cli import keep_freed_memory
if sys.argv[1] == "hint":
    assert keep_freed_memory()
def churn():
    arrays = [np.ones(1_700_000) for _ in range(3)]   # three 13.6 MB arrays, then freed
    del arrays
churn()
before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
for _ in range(10):
    churn()
print(resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before)
"""


@pytest.mark.slow  # a fresh process, whose page faults are counted
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's allocator")
def test_the_allocator_keeps_freed_memory_for_the_next_arrays():
    """Arrays of a sweep's size, freed and allocated again: with the hint they reuse the
    heap; without it glibc trims the heap and faults pages back in (measured: ~10 600
    page faults over ten rounds without it, none with it)."""
    def faults(mode: str) -> int:
        out = subprocess.run([sys.executable, "-c", _CHURN, mode], capture_output=True,
                             text=True, check=True).stdout
        return int(out)

    plain, hinted = faults("plain"), faults("hint")
    assert plain > 3_000
    assert hinted < plain / 10
