"""``model array-calibration --plot`` as a reader sees it: the modules' legend covers no
curve."""

from __future__ import annotations

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from tactile_sensor.physics.cli import main

TINY_GRID = ["--set", "mesh_nx=4", "mesh_ny=4", "mesh_nz=16", "max_indentation=0.002",
             "array_mesh_scale=1", "array_steps=3", "array_directions=4",
             "array_shear_levels=2", "--workers", "1"]


def test_the_outputs_legend_sits_beside_the_curves(tmp_path, monkeypatch, capsys):
    drawn: list[tuple[Figure, object]] = []
    save = Figure.savefig

    def keep(self: Figure, *args: object, **kwargs: object) -> None:
        save(self, *args, **kwargs)
        canvas = FigureCanvasAgg(self)
        canvas.draw()
        drawn.append((self, canvas.get_renderer()))

    monkeypatch.setattr(Figure, "savefig", keep)
    code = main(["array-calibration", *TINY_GRID, "--degree", "2", "--quiet", "--plot",
                 str(tmp_path / "fit.png"), "--cache-dir", str(tmp_path / "cache")])
    assert code == 0, capsys.readouterr().err
    (fig, renderer), = drawn
    outputs = fig.axes[3]
    legend = outputs.get_legend().get_window_extent(renderer)
    assert not legend.overlaps(outputs.get_window_extent(renderer))
    assert fig.bbox.x0 <= legend.x0 and legend.x1 <= fig.bbox.x1 + 1
