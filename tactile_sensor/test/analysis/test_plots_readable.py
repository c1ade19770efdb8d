"""`tactile-sensor analyze`'s figures as a reader sees them: titles inside the figure,
cycles counted in whole numbers, numbers readable on their cells, labels apart."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import to_hex
from matplotlib.figure import Figure
from press_recordings import FOUR_PRESSES as PROTOCOL

from tactile_sensor.analysis import cli, plots
from tactile_sensor.analysis.array.excursions import excursion_metrics
from tactile_sensor.analysis.synthetic import (
    SensorTruth,
    press_signals,
    write_press_bag,
)


def test_titles_fit_and_the_cycle_axis_counts_whole_cycles(tmp_path, monkeypatch):
    drawn: dict[str, tuple[Figure, object]] = {}
    save = Figure.savefig

    def keep(self: Figure, path: object, *args: object, **kwargs: object) -> None:
        save(self, path, *args, **kwargs)
        canvas = FigureCanvasAgg(self)
        canvas.draw()
        drawn[str(path).rsplit("/", 1)[-1]] = (self, canvas.get_renderer())

    monkeypatch.setattr(Figure, "savefig", keep)
    bag = write_press_bag(tmp_path / "bag", press_signals(PROTOCOL, SensorTruth(), seed=1),
                          "mcap")
    assert cli.main([str(bag), "--out", str(tmp_path / "out"), "--prediction", "none",
                     "--quiet"]) == 0
    assert "cycles.png" in drawn and len(drawn) >= 5
    for name, (fig, renderer) in drawn.items():
        frame = fig.bbox
        titles = [t for t in [fig._suptitle, *(ax.title for ax in fig.axes)]
                  if t is not None and t.get_text()]
        for title in titles:
            box = title.get_window_extent(renderer)
            assert frame.x0 - 1 <= box.x0 and box.x1 <= frame.x1 + 1, (name, title.get_text())
            assert box.y1 <= frame.y1 + 1, (name, title.get_text())
    fig, _ = drawn["cycles.png"]
    cycle_axis = next(ax for ax in fig.axes if ax.get_xlabel() == "cycle")
    low, high = cycle_axis.get_xlim()
    ticks = [t for t in cycle_axis.get_xticks() if low <= t <= high]
    assert ticks and all(t == round(t) for t in ticks), ticks


def _drawn(monkeypatch) -> list[tuple[Figure, object]]:
    figures: list[tuple[Figure, object]] = []
    save = Figure.savefig

    def keep(self: Figure, *args: object, **kwargs: object) -> None:
        save(self, *args, **kwargs)
        canvas = FigureCanvasAgg(self)
        canvas.draw()
        figures.append((self, canvas.get_renderer()))

    monkeypatch.setattr(Figure, "savefig", keep)
    return figures


def test_heatmap_numbers_are_white_on_the_dark_cells(tmp_path, monkeypatch):
    drawn = _drawn(monkeypatch)
    matrix = np.array([[0.0, 1.0, 0.76], [0.0, -1.0, 0.76], [-1.0, 0.0, 0.3]])
    sensitivity = SimpleNamespace(matrix_v_per_n=matrix, faces=("front", "back", "left"))
    plots.array_crosstalk(SimpleNamespace(sensitivity=sensitivity, range_n=np.ones(3),
                                          cross_talk=np.eye(3)), tmp_path / "c.png")
    (fig, _), = drawn
    colours = {t.get_text(): to_hex(t.get_color()) for t in fig.axes[0].texts}
    assert colours["1.00"] == colours["-1.00"] == colours["0.76"] == "#ffffff"
    assert colours["0.00"] == colours["0.30"] == "#000000"


def test_shear_direction_radius_labels_do_not_pile_up(tmp_path, monkeypatch):
    drawn = _drawn(monkeypatch)
    rng = np.random.default_rng(0)
    angle = np.repeat(np.radians(np.arange(-135, 181, 45)), 200)
    size = np.tile(np.linspace(0.4, 2.0, 200), 8)
    shear = SimpleNamespace(applied_rad=angle, applied_n=size, estimated_rad=angle,
                            estimated_n=size, error_rad=rng.normal(0, 0.1, angle.size),
                            threshold_n=0.4)
    plots.array_shear_direction(SimpleNamespace(shear=shear), tmp_path / "d.png")
    (fig, renderer), = drawn
    polar = fig.axes[0]
    low, high = polar.get_ylim()
    labels = [label for label, r in zip(polar.get_yticklabels(), polar.get_yticks(),
                                        strict=True) if low < r <= high and label.get_text()]
    assert 2 <= len(labels) <= 5
    boxes = [label.get_window_extent(renderer) for label in labels]
    assert not any(a.overlaps(b) for i, a in enumerate(boxes) for b in boxes[i + 1:])


def test_force_time_legend_is_off_the_traces_and_the_reference_on_top(tmp_path, monkeypatch):
    drawn = _drawn(monkeypatch)
    t = np.linspace(0.0, 100.0, 2000)
    reference = np.stack([2 * np.sin(t / 10), 2 * np.cos(t / 10), 7.0 * (t > 5)], axis=1)
    estimate = reference * np.array([1.0, 0.5, 1.0])
    signals = SimpleNamespace(t_s=t, reference_n=reference, estimate_n=estimate)
    metrics = {"wrench_excursions": excursion_metrics(("fx", "fy", "fz"), estimate,
                                                      reference, t)}
    plots.array_force_time(SimpleNamespace(signals=signals, rmse_n=[0.1] * 3, metrics=metrics,
                                           range_n=[4.0, 4.0, 7.0]), tmp_path / "f.png")
    (fig, renderer), = drawn
    gains = [[t.get_text() for t in ax.texts] for ax in fig.axes]
    assert gains[1] and set(gains[1]) == {"0.50"} and set(gains[0]) == {"1.00"}
    top = fig.axes[0]
    legend = top.get_legend().get_window_extent(renderer)
    assert not legend.overlaps(top._left_title.get_window_extent(renderer))
    assert not legend.overlaps(top.get_window_extent(renderer))
    assert not legend.overlaps(top.title.get_window_extent(renderer))
    assert legend.x1 <= fig.bbox.x1 + 1
    for ax in fig.axes:
        lines = {line.get_label(): line for line in ax.get_lines()}
        assert (lines["reference (gauge)"].get_zorder()
                > lines["estimated (driver)"].get_zorder())


def test_torque_figures_say_which_axis_is_not_observed_and_titles_fit(tmp_path, monkeypatch):
    drawn = _drawn(monkeypatch)
    t = np.linspace(0.0, 60.0, 1500)
    reference = np.stack([0.02 * np.sin(t / 5), 0.02 * np.cos(t / 5), 0.005 * np.sin(t)],
                         axis=1)
    estimate = reference + 0.001
    estimate[:, :2] = np.nan  # a layout that observes only the twist
    signals = SimpleNamespace(t_s=t, reference_torque_nm=reference,
                              estimate_torque_nm=estimate)
    metrics = {"wrench_excursions": excursion_metrics(("tx", "ty", "tz"), estimate,
                                                      reference, t)}
    an = SimpleNamespace(signals=signals, torque_rmse_nm=[np.nan, np.nan, 0.001],
                         torque_range_nm=[0.04, 0.04, 0.01], metrics=metrics)
    plots.array_torque_time(an, tmp_path / "t.png")
    plots.array_torque_scatter(an, tmp_path / "s.png")
    for fig, renderer in drawn:
        texts = [t for t in [fig._suptitle, *(ax.title for ax in fig.axes),
                             *(ax._left_title for ax in fig.axes)]
                 if t is not None and t.get_text()]
        for text in texts:
            box = text.get_window_extent(renderer)
            assert fig.bbox.x0 - 1 <= box.x0 and box.x1 <= fig.bbox.x1 + 1, text.get_text()
            assert box.y1 <= fig.bbox.y1 + 1, text.get_text()
        said = [t.get_text() for ax in fig.axes for t in ax.texts]
        assert said.count("Tx not observed by the driver (NaN)") == 1
        assert said.count("Ty not observed by the driver (NaN)") == 1
    time_fig, renderer = drawn[0]
    top = time_fig.axes[0]
    legend = top.get_legend().get_window_extent(renderer)
    assert not legend.overlaps(top._left_title.get_window_extent(renderer))
    assert "rmse 1 mN m" in time_fig.axes[2].get_title(loc="left")
