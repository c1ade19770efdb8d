"""benchmarks/docs_figures.py: a published result with its series gives a page a PNG and a
caption naming the benchmark, commit and date; one without gives one sentence instead."""

from __future__ import annotations

import importlib
import sys
from pathlib import Path

import numpy as np
import pytest

# The scripts in benchmarks/ import each other by file name, as `python benchmarks/x.py` does.
BENCHMARKS = Path(__file__).resolve().parents[3] / "benchmarks"
sys.path.insert(0, str(BENCHMARKS))
docs_figures = importlib.import_module("docs_figures")
results = importlib.import_module("results")


@pytest.fixture(autouse=True)
def measured_at_a_commit(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(results, "STARTED_ON", "0123abc")


def shear_series(samples: int = 5_000) -> dict[str, np.ndarray]:
    """A press held while the probe sweeps sideways: the lateral force turns a full circle
    and the estimate follows it with a little noise."""
    t = np.linspace(0.0, 100.0, samples)
    angle = 2 * np.pi * t / 100.0
    reference = np.column_stack([0.4 * np.cos(angle), 0.4 * np.sin(angle), np.full(samples, 3.0)])
    estimate = reference + np.random.default_rng(0).normal(0.0, 0.01, reference.shape)
    return {"t_s": t, "estimate_n": estimate, "reference_n": reference}


def test_series_are_kept_decimated_with_nan_as_null(tmp_path):
    series = shear_series()
    series["estimate_torque_nm"] = np.full((5_000, 3), np.nan)
    path = results.write_results("array_shear", [], argv=["benchmarks/bench_array_shear.py"],
                                 directory=tmp_path, series=series)
    kept = results.read_results(path)["series"]
    assert len(kept["t_s"]) <= results.SERIES_POINTS
    assert len({len(column) for column in kept.values()}) == 1
    assert kept["estimate_torque_nm"][0] == [None, None, None]


def test_a_result_with_its_series_draws_a_png_with_its_caption(tmp_path):
    published, out = tmp_path / "results", tmp_path / "generated"
    results.write_results("array_shear", [], argv=["benchmarks/bench_array_shear.py"],
                          directory=published, series=shear_series())
    docs_figures.write_pages(published, out)
    png = out / "array_shear_direction.png"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    page = (out / "array.md").read_text()
    assert ":::{figure} _generated/array_shear_direction.png" in page
    assert "benchmark array_shear" in page and "commit `0123abc`" in page


def test_a_result_without_its_series_gives_one_sentence_and_no_image(tmp_path):
    published, out = tmp_path / "results", tmp_path / "generated"
    results.write_results("array_shear", [results.Figure("bringup", 1.0, "s")],
                          argv=["benchmarks/bench_array_shear.py"], directory=published)
    docs_figures.write_pages(published, out)
    page = (out / "array.md").read_text()
    assert "array_shear_direction" not in page
    assert not (out / "array_shear_direction.png").exists()
    shear = [line for line in page.splitlines() if "shear direction" in line]
    assert len(shear) == 1 and "keeps no series" in shear[0]
    assert "bench_array_shear.py" in shear[0]
    # a page whose result is not published at all says that
    assert "is not published yet" in (out / "gripper-workflow.md").read_text()


def test_a_column_of_names_draws_beside_columns_of_numbers(tmp_path):
    """The rate page's errors come per speed and phase: the phase column is text."""
    published, out = tmp_path / "results", tmp_path / "generated"
    results.write_results("rate_calibration", [], argv=["benchmarks/bench_rate_calibration.py"],
                          directory=published,
                          series={"speed_mm_s": [0.3, 0.3, 20.0], "phase": ["loading", "hold",
                                                                            "unloading"],
                                  "static_model_rmse_n": [0.2, 0.1, 0.4],
                                  "rate_model_rmse_n": [0.05, 0.04, 0.08],
                                  "full_scale_n": [7.0, 7.0, 7.0]})
    docs_figures.write_pages(published, out)
    assert (out / "rate_errors.png").stat().st_size > 0
    assert "benchmark rate_calibration" in (out / "rate-calibration.md").read_text()


def test_the_module_layouts_are_drawn_from_the_configurations_without_a_result(tmp_path):
    published, out = tmp_path / "results", tmp_path / "generated"
    docs_figures.write_pages(published, out)
    assert (out / "module_layouts.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "drawn by `make docs` from the package's configuration" in (
        out / "array.md").read_text()


def test_the_slip_study_draws_its_trace_on_the_gripper_page(tmp_path):
    published, out = tmp_path / "results", tmp_path / "generated"
    t = np.arange(-0.2, 0.3, 0.001)
    n = t.size
    ft = np.where(t < 0.05, 1.5 + 10 * np.clip(t, 0, None), 2.0)
    series = {"t_s": t, "ft_true_n": ft, "ft_sensed_n": ft + 0.1, "limit_n": np.full(n, 2.0),
              "margin_n": 2.0 - ft, "threshold_n": np.full(n, 0.3), "slip_mm": np.zeros(n),
              "onset_s": np.full(n, 0.05), "alarm_s": np.full(n, 0.03)}
    results.write_results("slip_study", [], argv=["benchmarks/bench_slip_study.py"],
                          directory=published, series=series)
    docs_figures.write_pages(published, out)
    assert (out / "slip_study.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "benchmark slip_study" in (out / "gripper-slip.md").read_text()


def test_the_office_scenario_draws_each_driver_beside_the_gauge_with_blind_gaps(tmp_path):
    bench_ambient = importlib.import_module("bench_ambient")
    published, out = tmp_path / "results", tmp_path / "generated"
    t = np.arange(-1.0, 10.0, 0.001)
    truth = np.clip(np.sin(t), 0.0, None) * 5.0
    blind = np.where((t > 2.0) & (t < 2.5), np.nan, truth + 0.2)
    half = t[::2]  # the modulated module samples at 500 Hz
    runs = {"today": {"trace": (t, truth, blind)}, "stock": {"trace": (t, truth, truth)},
            "modulated": {"trace": (half, truth[::2], truth[::2] - 0.1)}}
    series = bench_ambient.trace_series(runs)
    assert np.isnan(series["today_n"][(series["t_s"] > 2.05) & (series["t_s"] < 2.45)]).all()
    assert np.allclose(series["modulated_n"], series["gauge_n"] - 0.1, atol=0.02)
    results.write_results("bench_ambient", [], argv=["benchmarks/bench_ambient.py"],
                          directory=published, series=series)
    docs_figures.write_pages(published, out)
    assert (out / "ambient_office.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "benchmark bench_ambient" in (out / "ambient.md").read_text()


def test_every_figure_says_what_to_look_at():
    """A caption says what to look for in its figure, not only where it came from."""
    for figure in docs_figures.FIGURES:
        assert len(figure.look.split()) >= 8, f"{figure.page}/{figure.name}: no look text"


def test_a_whole_grasp_draws_contact_hold_and_release_with_its_target(tmp_path):
    published, out = tmp_path / "results", tmp_path / "generated"
    t = np.arange(0.0, 5.0, 0.002)
    force = np.clip((t - 2.0) * 5.0, 0.0, 1.5) * (t < 4.0)
    series = {"t_s": t, "true_force_n": force, "sensed_force_n": force + 0.01,
              "opening_m": np.where(t < 4.0, 0.06 - 0.01 * np.clip(t, 0, 2), 0.06),
              "target_n": np.full(t.size, 1.5), "release_start_s": np.full(t.size, 3.9),
              "release_end_s": np.full(t.size, 4.5)}
    results.write_results("grasp_trace", [], argv=["benchmarks/bench_grasp_trace.py"],
                          directory=published, series=series)
    docs_figures.write_pages(published, out)
    assert (out / "grasp.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    page = (out / "gripper-workflow.md").read_text()
    assert "benchmark grasp_trace" in page and "target" in page and "release" in page


def test_figures_drawn_from_several_results_name_them_or_say_which_is_missing(tmp_path):
    published, out = tmp_path / "results", tmp_path / "generated"
    results.write_results("recording_kill",
                          [results.Figure("time lost per kill: median", 0.3, "s"),
                           results.Figure("time lost per kill: max", 0.5, "s", "<= 1 s", True)],
                          argv=["benchmarks/bench_recording_kill.py"], directory=published)
    docs_figures.write_pages(published, out)
    recordings = (out / "recordings.md").read_text()
    assert "the result analysis is not published yet" in recordings
    assert not (out / "recording_costs.png").exists()
    assert "goal_overview.png" in (out / "benchmarks.md").read_text()  # every result: one
    results.write_results("analysis", [results.Figure("mcap: full analysis", 12.0, "s")],
                          argv=["benchmarks/bench_analysis.py"], directory=published)
    docs_figures.write_pages(published, out)
    recordings = (out / "recordings.md").read_text()
    assert "recording_costs.png" in recordings and "recording_kill (commit `0123abc`" in recordings
