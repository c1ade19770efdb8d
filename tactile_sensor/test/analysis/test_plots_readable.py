"""`tactile-sensor analyze`'s figures as a reader sees them: titles inside the figure,
cycles counted in whole numbers."""

from __future__ import annotations

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from tactile_sensor.analysis import cli
from tactile_sensor.analysis.synthetic import (
    PressProtocol,
    SensorTruth,
    press_signals,
    write_press_bag,
)

PROTOCOL = PressProtocol(speeds_mm_s=(10.0,), cycles=(4,), rate_hz=200.0, rest_s=0.5,
                         hold_s=0.5)


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
