"""The study's figures as a reader sees them: nothing covers the paper's star, whole-number
metrics read in whole numbers, labels and titles stay apart and inside the figure."""

from __future__ import annotations

from pathlib import Path

import matplotlib
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.text import Text

from tactile_sensor.studies.report import write_metrics_plot, write_pareto_plot
from tactile_sensor.studies.run import DesignRow
from tactile_sensor.studies.spec import load_spec

matplotlib.use("Agg")

STUDIES = Path(__file__).resolve().parents[2] / "config" / "studies"
FOUR = "front,back,left,right"
EIGHT = ",".join(f"{f}@{s}0.0055" for f in ("front", "back", "left", "right") for s in "-+")


RENDERERS: dict[int, object] = {}


@pytest.fixture
def drawn(monkeypatch: pytest.MonkeyPatch) -> list[Figure]:
    """Every figure the code under test saves, drawn again at its own dpi and kept with
    that renderer for measuring."""
    figures: list[Figure] = []
    save = Figure.savefig

    def keep(self: Figure, *args: object, **kwargs: object) -> None:
        save(self, *args, **kwargs)
        canvas = FigureCanvasAgg(self)  # closing the figure dropped its own
        canvas.draw()
        RENDERERS[id(self)] = canvas.get_renderer()
        figures.append(self)

    monkeypatch.setattr(Figure, "savefig", keep)
    return figures


def torque_rows(observed: list[int]) -> list[DesignRow]:
    """The paper's design first, as run_study orders them; whole-number metrics."""
    rows = []
    for k, n in enumerate(observed):
        modules = FOUR if k % 2 == 0 else EIGHT
        rows.append(DesignRow("paper" if k == 0 else str(k - 1), {"modules": modules}, "x",
                              {"observed_torques": float(n), "wrench_rank": 3.0 + n}))
    return rows


def window_rows() -> list[DesignRow]:
    spec = load_spec(STUDIES / "window_placement.yaml")
    rows = []
    for k, design in enumerate([{"module_height": 0.006, "window_center_z": 0.003},
                                *spec.designs()]):
        rows.append(DesignRow("paper" if k == 0 else str(k - 1), design, "x", {
            "sensitivity_v_per_n": 0.07 + 0.003 * k, "full_scale_n": 10.0 - 0.3 * k,
            "linearity_pct_fs": 1.0 + 0.1 * k, "dynamic_range_db": 30.0 + 0.1 * k}))
    rows[0].metrics.update(sensitivity_v_per_n=0.098, full_scale_n=9.9)  # top right
    return rows


def extent(artist: object, fig: Figure) -> object:
    return artist.get_window_extent(RENDERERS[id(fig)])  # type: ignore[attr-defined]


def inside(fig: Figure, text: Text) -> bool:
    box, frame = extent(text, fig), fig.bbox
    return (box.x0 >= frame.x0 - 1 and box.x1 <= frame.x1 + 1
            and box.y0 >= frame.y0 - 1 and box.y1 <= frame.y1 + 1)


@pytest.mark.parametrize("case", ["window", "torque"])
def test_the_pareto_legend_covers_no_design_and_least_of_all_the_paper_star(
        tmp_path, drawn, case):
    if case == "window":
        spec, rows = load_spec(STUDIES / "window_placement.yaml"), window_rows()
    else:
        spec, rows = load_spec(STUDIES / "torque_layout.yaml"), torque_rows([0, 0, 1])
    write_pareto_plot(rows, spec, tmp_path / "pareto.png")
    (fig,) = drawn
    ax = fig.axes[0]
    legend = extent(ax.get_legend(), fig)
    assert not legend.overlaps(extent(ax, fig))  # beside the axes, not on them
    star = next(line for line in ax.get_lines() if line.get_marker() == "*")
    x, y = ax.transData.transform((star.get_xdata()[0], star.get_ydata()[0]))
    assert not legend.contains(x, y)
    words = [ax.title, ax.xaxis.label, ax.yaxis.label, *ax.texts, *ax.get_legend().get_texts()]
    assert all(inside(fig, t) for t in words)


def test_whole_number_objectives_have_whole_number_ticks_and_one_label_per_point(
        tmp_path, drawn):
    spec = load_spec(STUDIES / "torque_layout.yaml")
    # every design on one point: (0 torques, rank 3)
    write_pareto_plot(torque_rows([0, 0, 0]), spec, tmp_path / "pareto.png")
    (fig,) = drawn
    ax = fig.axes[0]
    for axis, (low, high) in ((ax.xaxis, ax.get_xlim()), (ax.yaxis, ax.get_ylim())):
        ticks = [t for t in axis.get_majorticklocs() if low <= t <= high]
        assert ticks and all(t == round(t) for t in ticks), ticks
        assert high - low >= 1.0  # not +/-0.05 around a single value
    labels = [t for t in ax.texts if t.get_text()]
    assert [t.get_text() for t in labels] == ["paper, 0, 1"]


def test_the_metrics_title_and_tick_labels_fit_inside_a_narrow_figure(tmp_path, drawn):
    spec = load_spec(STUDIES / "torque_layout.yaml")  # one varied parameter: one column
    write_metrics_plot(torque_rows([0, 1, 0]), spec, tmp_path / "metrics.png")
    (fig,) = drawn
    title = fig._suptitle
    assert title is not None and inside(fig, title)
    for ax in fig.axes:
        ticks = [t for t in ax.get_xticklabels() if t.get_text()]
        assert len(ticks) == 2 and all(inside(fig, t) for t in ticks)
        assert not extent(ticks[0], fig).overlaps(extent(ticks[1], fig))
        low, high = ax.get_ylim()
        assert all(t == round(t) for t in ax.get_yticks() if low <= t <= high)


def test_the_metrics_title_fits_a_two_parameter_study(tmp_path, drawn):
    spec = load_spec(STUDIES / "window_placement.yaml")
    write_metrics_plot(window_rows(), spec, tmp_path / "metrics.png")
    (fig,) = drawn
    assert inside(fig, fig._suptitle)


def test_the_metrics_plot_draws_a_varied_board_the_paper_design_lacks(tmp_path, drawn):
    spec = load_spec(STUDIES / "wrench_layout_wide.yaml")
    rows = [DesignRow("paper", {name: 0.022 for name in ("window_width", "width", "depth",
                                                         "height")} | {"modules": "front"},
                      "x", {"observed_torques": 0.0, "noise_tz_pct_fs_10hz": 50.0,
                            "noise_tx_pct_fs_10hz": 50.0})]
    for k, design in enumerate(spec.designs()[:3]):
        rows.append(DesignRow(str(k), design, "x", {"observed_torques": 3.0,
                                                     "noise_tz_pct_fs_10hz": 18.0 - k,
                                                     "noise_tx_pct_fs_10hz": 19.0 - k}))
    write_metrics_plot(rows, spec, tmp_path / "metrics.png")
    (fig,) = drawn
    board_axes = [ax for ax in fig.axes if ax.get_xlabel() == "board"]
    assert board_axes
    assert all(t.get_text() == "nano" for t in board_axes[0].get_xticklabels()
               if t.get_text())
