"""The workflow pages' figures, drawn from the committed benchmark results with the
package's own plot functions: ``make docs`` runs this before Sphinx.

Each figure comes from the series a benchmark keeps in its results file
(``benchmarks/results/<name>.json``, written by ``make bench-publish``), never from a file
copied by hand. For every page this writes ``docs/_generated/<page>.md`` (ignored by git),
which the page includes: the figures with a caption naming the benchmark, its commit and
date, or, where the result or its series is missing, one sentence saying so and how to
measure it.

    python benchmarks/docs_figures.py [--results DIR] [--out DIR]
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from results import PUBLISHED, ROOT, ResultsError, read_results

sys.path.insert(0, str(ROOT / "tactile_sensor"))

OUT = ROOT / "docs" / "_generated"
Series = dict[str, np.ndarray]


def array_analysis(series: Series) -> Any:
    """The array analysis of a benchmark's kept (decimated) signals, as the command's own
    analysis computes it from the recording."""
    from tactile_sensor.analysis.array.analysis import ArraySignals, analyse_signals

    t_s = series["t_s"]
    torque = "estimate_torque_nm" in series
    signals = ArraySignals(
        t_s=t_s, estimate_n=series["estimate_n"], reference_n=series["reference_n"],
        outputs_v=np.zeros((t_s.size, 0)), faces=(),
        rate_hz=float((t_s.size - 1) / (t_s[-1] - t_s[0])) if t_s.size > 1 else 0.0,
        start_ns=0, reference_flipped=False,
        estimate_torque_nm=series["estimate_torque_nm"] if torque else None,
        reference_torque_nm=series["reference_torque_nm"] if torque else None)
    return analyse_signals(signals, "a benchmark's kept signals", {}, [])


def shear_direction(series: Series, path: Path) -> Path:
    from tactile_sensor.analysis.plots import array_shear_direction

    return array_shear_direction(array_analysis(series), path)


def torque_time(series: Series, path: Path) -> Path:
    from tactile_sensor.analysis.plots import array_torque_time

    return array_torque_time(array_analysis(series), path)


#: The study the design-studies page runs, whose Pareto front the page shows.
STUDY_SPEC = ROOT / "tactile_sensor" / "config" / "studies" / "window_placement.yaml"


def study_name() -> str:
    """The results file of bench_study's default study (``study_<spec file's stem>``)."""
    return f"study_{STUDY_SPEC.stem}"


def pareto(series: Series, path: Path) -> Path:
    """The study's own Pareto plot of the designs the benchmark solved (paper's first)."""
    from tactile_sensor.studies.report import write_pareto_plot
    from tactile_sensor.studies.run import DesignRow
    from tactile_sensor.studies.spec import load_spec

    spec = load_spec(STUDY_SPEC)
    rows = [DesignRow(design=str(name), values={}, error=str(series["error"][k]),
                      metrics={c: float(series[c][k]) for c in spec.columns if c in series})
            for k, name in enumerate(series["design"])]
    write_pareto_plot(rows, spec, path)
    return path


def compression(series: Series, path: Path) -> Path:
    """The analysis's own compression curve (Fig. 7a) of the benchmark's 1 mm/s presses."""
    from tactile_sensor.analysis.plots import compression_curve

    unloading = series["unloading"] > 0.5
    ramps = {"load": (series["indentation_m"][~unloading], series["force_n"][~unloading]),
             "unload": (series["indentation_m"][unloading], series["force_n"][unloading])}
    return compression_curve(ramps, "1.0", path)


def pyplot() -> Any:
    """Matplotlib's pyplot on the Agg backend: the figure step draws files, no windows."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def saved(fig: Any, path: Path) -> Path:
    fig.savefig(path, dpi=100)
    pyplot().close(fig)
    return path


def grasp_trace(series: Series, path: Path) -> Path:
    """One whole grasp as the mock's world felt it: the true and the sensed force closing
    on the target, holding there, and falling to zero as the release opens the fingers
    (the package draws no plot of a grasp; the demo prints a summary)."""
    plt = pyplot()
    t = series["t_s"]
    target = float(series["target_n"][0])
    release = float(series["release_start_s"][0])
    released = float(series["release_end_s"][0])
    touched = t[np.nonzero(series["true_force_n"] > 0.02)[0]]
    contact = float(touched[0]) if touched.size else float("nan")
    fig, (force, opening) = plt.subplots(2, 1, figsize=(8, 5), sharex=True)
    force.plot(t, series["sensed_force_n"], lw=0.6, color="0.6", label="sensed (what the goal saw)")
    force.plot(t, series["true_force_n"], lw=1.2, color="tab:red", label="true force, finger A")
    force.axhline(target, color="k", ls="--", lw=0.9, label=f"target {target:g} N")
    opening.plot(t, series["opening_m"] * 1e3, lw=1.2, color="tab:blue")
    for ax in (force, opening):
        for x0, x1, name, shade in ((t[0], contact, "close", "0.97"),
                                    (contact, release, "hold", "#e8f4e8"),
                                    (release, released, "release", "#fdebd8")):
            if np.isfinite(x0) and np.isfinite(x1) and x1 > x0:
                ax.axvspan(x0, x1, color=shade, zorder=0)
                if ax is force:
                    ax.text((x0 + x1) / 2, target * 1.22, name, ha="center", fontsize=9)
    force.set(ylabel="force [N]", ylim=(-0.1, target * 1.35),
              title="Grasp, hold and release: the force settles on the target, then falls to 0")
    force.legend(fontsize=8, loc="center left")
    opening.set(xlabel="time from the grasp goal [s]", ylabel="opening [mm]")
    fig.subplots_adjust(left=0.1, right=0.97, bottom=0.1, top=0.92, hspace=0.12)
    return saved(fig, path)


def recording_costs(records: dict[str, dict[str, Any]], path: Path) -> Path:
    """What a recording costs and risks: the time a kill -9 loses against the recorder's
    0.5 s flush, and the time to read and analyse a 2.4 M-message recording per storage."""
    plt = pyplot()
    def value(name: str, figure: str) -> float:
        for f in records[name]["figures"]:
            if f["name"] == figure and f["value"] is not None:
                return float(f["value"])
        return float("nan")

    fig, (kill, read) = plt.subplots(1, 2, figsize=(9, 3.6))
    lost = [value("recording_kill", "time lost per kill: median"),
            value("recording_kill", "time lost per kill: max")]
    kill.bar(["median", "max"], lost, color="tab:red", width=0.5)
    kill.axhline(0.5, color="k", ls="--", lw=0.9, label="flush period 0.5 s")
    kill.set(ylabel="recording lost per kill -9 [s]", title="A killed recorder loses")
    kill.legend(fontsize=8, loc="lower right")
    storages = ("sqlite3", "mcap")
    x = np.arange(len(storages))
    for offset, part, colour in ((-0.2, "rosbags read + deserialize", "0.6"),
                                 (0.2, "full analysis", "tab:blue")):
        read.bar(x + offset, [value("analysis", f"{s}: {part}") for s in storages], 0.4,
                 color=colour, label=part)
    read.set_xticks(x, storages)
    read.set(ylabel="time [s]", title="2.4 M messages: read, then analyse")
    read.legend(fontsize=8)
    fig.subplots_adjust(left=0.09, right=0.98, bottom=0.12, top=0.88, wspace=0.3)
    return saved(fig, path)


def goal_overview(records: dict[str, dict[str, Any]], path: Path) -> Path:
    """Every published benchmark's figures with a goal, met and not met, beside those
    without one (the page's tables hold the values)."""
    plt = pyplot()
    names = sorted(records)
    met = [sum(f.get("met") is True for f in records[n]["figures"]) for n in names]
    missed = [sum(f.get("met") is False for f in records[n]["figures"]) for n in names]
    plain = [len(records[n]["figures"]) - a - b for n, a, b in zip(names, met, missed,
                                                                    strict=True)]
    y = np.arange(len(names))
    fig, ax = plt.subplots(figsize=(9, 0.25 * len(names) + 1.2))
    ax.barh(y, met, color="tab:green", label="goal met")
    ax.barh(y, missed, left=met, color="tab:red", label="goal NOT met")
    ax.barh(y, plain, left=np.add(met, missed), color="0.8", label="no goal (a measurement)")
    ax.set_yticks(y, [f"{n} ({str(records[n]['date'])[:10]})" for n in names], fontsize=8)
    ax.invert_yaxis()
    ax.set_xscale("symlog", linthresh=10)
    ax.set(xlabel="figures (log scale past 10)",
           title="Published benchmarks: red marks a goal not met")
    ax.legend(fontsize=8, loc="lower right")
    fig.subplots_adjust(left=0.3, right=0.98, bottom=0.5 / (0.25 * len(names) + 1.2) + 0.04,
                        top=1 - 0.5 / (0.25 * len(names) + 1.2))
    return saved(fig, path)


def rate_errors(series: Series, path: Path) -> Path:
    """Static against rate-aware model error for each speed and phase of the held-out
    recording, beside the goal's share of full scale (the package draws the force traces,
    not this table)."""
    from rate_goal import GOAL_SHARE_FS

    plt = pyplot()
    labels = [f"{v:g} mm/s\n{p}" for v, p in zip(series["speed_mm_s"], series["phase"],
                                                 strict=True)]
    x = np.arange(len(labels))
    fig, ax = plt.subplots(figsize=(9, 4))
    ax.bar(x - 0.2, series["static_model_rmse_n"], 0.4, color="tab:blue", label="static curve")
    ax.bar(x + 0.2, series["rate_model_rmse_n"], 0.4, color="tab:red", label="rate-aware")
    ax.axhline(GOAL_SHARE_FS * float(series["full_scale_n"][0]), color="k", ls="--", lw=0.8,
               label=f"goal: {GOAL_SHARE_FS:.1%} of full scale")
    ax.set_xticks(x, labels, fontsize=8)
    ax.set(ylabel="model error rmse [N]", title="Held-out force error per speed and phase")
    ax.legend(fontsize=8)
    fig.subplots_adjust(left=0.08, right=0.98, bottom=0.2, top=0.9)
    return saved(fig, path)


#: The module layouts the array page describes: (configuration file, title).
LAYOUTS = (("array.yaml", "array"), ("wrench.yaml", "six-axis wrench"))


def module_layouts(_series: Series, path: Path) -> Path:
    """The skin block seen from above with each layout's modules, as the configurations
    place them (``modules`` of the bench) on the model's default block: a short run of the
    package's own layout parsing, no benchmark needed."""
    import yaml

    from tactile_sensor.configurations import config_dir
    from tactile_sensor.physics.params import FACES, PhysicsParams

    plt = pyplot()
    fig, axes = plt.subplots(1, len(LAYOUTS), figsize=(9, 4.2))
    for ax, (name, title) in zip(axes, LAYOUTS, strict=True):
        modules = yaml.safe_load((config_dir() / name).read_text())["/**/bench"][
            "ros__parameters"]["modules"]
        params = PhysicsParams().replace(modules=modules)
        w, d, ww = params.width * 1e3, params.depth * 1e3, params.window_width * 1e3
        ax.add_patch(plt.Rectangle((-w / 2, -d / 2), w, d, color="0.85", label="skin block"))
        for channel, (face, offset) in enumerate(params.module_windows):
            axis, sign = FACES[face]
            along = offset * 1e3 - ww / 2  # the window's extent along its face
            if axis == 1:  # front/back: a face of constant y, running along x
                xy, size = (along, sign * d / 2 - (ww / 4 if sign < 0 else 0)), (ww, ww / 4)
            else:  # left/right: a face of constant x, running along y
                xy, size = (sign * w / 2 - (ww / 4 if sign < 0 else 0), along), (ww / 4, ww)
            ax.add_patch(plt.Rectangle(xy, *size, color="tab:red"))
            centre = np.array([xy[0] + size[0] / 2, xy[1] + size[1] / 2])
            outward = np.array([0.0, sign]) if axis == 1 else np.array([sign, 0.0])
            ax.annotate(f"{channel}", centre + outward * 2.5, ha="center", va="center",
                        fontsize=8)
        ax.annotate("", (w / 2 * 0.6, 0), (0, 0), arrowprops={"arrowstyle": "->"})
        ax.annotate("", (0, d / 2 * 0.6), (0, 0), arrowprops={"arrowstyle": "->"})
        ax.text(w / 2 * 0.62, 0.5, "x", fontsize=9)
        ax.text(0.5, d / 2 * 0.62, "y", fontsize=9)
        ax.set(xlim=(-w / 2 - 5, w / 2 + 5), ylim=(-d / 2 - 5, d / 2 + 5), aspect="equal",
               xlabel="x [mm]", ylabel="y [mm]", title=f"{title} ({name})")
    fig.suptitle("Modules on the skin block, seen from above (numbers: ADC channel)",
                 fontsize=10)
    fig.subplots_adjust(left=0.08, right=0.98, bottom=0.12, top=0.85, wspace=0.3)
    return saved(fig, path)


def slip_trace(series: Series, path: Path) -> Path:
    """One slip as the study computes it: finger A's tangential force, true and as the
    array layout senses it, against the friction limit, and the margin detector's filtered
    margin crossing its threshold before the onset (the package draws no such plot)."""
    plt = pyplot()
    t = series["t_s"] * 1e3
    fig, (force, margin) = plt.subplots(2, 1, figsize=(8, 5.5), sharex=True)
    force.plot(t, series["ft_sensed_n"], lw=0.4, color="0.7", label="sensed Ft (1 kHz)")
    force.plot(t, series["ft_true_n"], lw=1.2, color="tab:blue", label="true Ft")
    force.plot(t, series["limit_n"], lw=1.0, ls="--", color="k", label="mu_k Fn")
    margin.plot(t, series["margin_n"], lw=1.0, color="tab:green", label="filtered margin")
    margin.plot(t, series["threshold_n"], lw=1.0, ls="--", color="tab:red",
                label="threshold (1 false alarm / h)")
    for ax in (force, margin):
        for key, style in (("onset_s", "tab:purple"), ("alarm_s", "tab:red")):
            value = float(series[key][0])
            if np.isfinite(value):
                ax.axvline(value * 1e3, color=style, lw=0.8)
        ax.legend(fontsize=8, loc="upper left")
    force.set(ylabel="force along the fingers [N]",
              title="A slip: the load doubles from t = 0 (purple: onset, red: alarm)")
    margin.set(xlabel="time from the load's doubling [ms]", ylabel="margin [N]",
               xlim=(-200, 300))
    fig.subplots_adjust(left=0.1, right=0.97, bottom=0.1, top=0.93, hspace=0.12)
    return saved(fig, path)


def ambient_trace(series: Series, path: Path) -> Path:
    """The office scenario's presses as the gauge and each driver read them: today's driver
    with the lamps' flicker and a lamp switched on while press 1 loads and off while press
    2 unloads, the stock module notched and re-tared at rest, the modulated module."""
    plt = pyplot()
    t = series["t_s"]
    fig, ax = plt.subplots(figsize=(9, 4))
    for key, label, style in (("today_n", "today's driver", "0.65"),
                              ("stock_n", "stock + notch + re-tare at rest", "tab:orange"),
                              ("modulated_n", "modulated + notch + gain", "tab:blue")):
        ax.plot(t, series[key], lw=0.7, color=style, label=label)
    ax.plot(t, series["gauge_n"], lw=1.2, ls="--", color="k", label="gauge")
    ax.set(xlabel="time from the protocol's start [s]", ylabel="force [N]",
           title="Office light: flicker 0.2 at 100 Hz, a lamp +0.3 in press 1, -0.3 in press 2")
    ax.legend(fontsize=8, loc="upper right")
    fig.subplots_adjust(left=0.08, right=0.98, bottom=0.13, top=0.9)
    return saved(fig, path)


@dataclass(frozen=True)
class PageFigure:
    """One figure of a docs page: the benchmark result it is drawn from (empty: drawn from
    the package's configuration alone), what it shows, what to look at in it, and the plot
    that draws it (None: the benchmark keeps no series for it yet). ``records`` names the
    results a plot of their figures (not of a series) reads; ``("*",)`` is every one."""

    page: str
    name: str
    result: str
    shows: str
    look: str
    draw: Callable[[Series, Path], Path] | None = None
    records: tuple[str, ...] = ()
    draw_records: Callable[[dict[str, dict[str, Any]], Path], Path] | None = None


FIGURES = (
    PageFigure("array", "module_layouts", "", "the module layouts",
               "Each red bar is a module's window on a side face, numbered by its ADC "
               "channel: the array layout has one per face, the wrench layout two per face "
               "at +-5.5 mm, which is what lets it read torque.", module_layouts),
    PageFigure("bench-calibration", "compression", "analysis",
               "the compression curve beside the paper's",
               "Loading and unloading lie on one curve (the mock's skin has no hysteresis) "
               "and end at the star, the paper's 7 N at 3 mm; the grey band is the paper's "
               "nonlinear toe.", compression),
    PageFigure("array", "array_shear_direction", "array_shear",
               "the shear direction, estimated against applied",
               "Left: the red estimates lie on the grey spokes of the eight applied "
               "directions. Right: the error per direction stays within about +-15 deg, "
               "centred on 0 (no direction is biased).", shear_direction),
    PageFigure("array", "array_torque_time", "bench_wrench",
               "the torque, estimated against the gauge",
               "The red estimate follows the black gauge on each axis; the number over each "
               "shaded excursion is its gain (1.00 is exact), and the title of each panel "
               "gives its RMSE over the range.", torque_time),
    PageFigure("design-studies", "pareto", study_name(), "the Pareto front",
               "The red line joins the designs no other beats on both full-scale force and "
               "sensitivity; the star is the paper's design, left of the front: more range "
               "is available at about the same sensitivity.", pareto),
    PageFigure("rate-calibration", "rate_errors", "rate_calibration",
               "the rate errors per speed",
               "In every speed and phase the red bar (rate-aware) is below the blue (static "
               "curve); the dashed line is the goal, and a red bar above it is a goal not "
               "met.", rate_errors),
    PageFigure("gripper-workflow", "grasp", "grasp_trace",
               "one grasp, its hold and its release",
               "The true force (red) rises at contact, settles on the dashed target and "
               "stays there through the green hold; in the orange release it falls to 0 as "
               "the opening returns to 60 mm. The grey sensed force is noisier and a few ms "
               "late.", grasp_trace),
    PageFigure("ambient", "ambient_office", "bench_ambient",
               "the force under office light, today's driver beside each kind of module",
               "Where the grey line (the stock module tared once) leaves the dashed gauge, "
               "room light is read as force: the lamp switched on in press 1 and off in "
               "press 2. The blue modulated module stays on the gauge through both.",
               ambient_trace),
    PageFigure("gripper-slip", "slip_study", "slip_study",
               "a slip's tangential force and the detector's alarm",
               "Top: the blue tangential force reaches the dashed friction limit at the "
               "purple onset. Bottom: the green margin crosses the red threshold at the red "
               "alarm line; an alarm left of the onset warns before the slip starts.",
               slip_trace),
    PageFigure("recordings", "recording_costs", "", "what a recording risks and costs",
               "Left: a kill -9 loses at most about the 0.5 s the recorder flushes at "
               "(dashed). Right: in both storages reading and deserialising the bag (grey) "
               "takes longer than the analysis after it (blue).",
               records=("recording_kill", "analysis"), draw_records=recording_costs),
    PageFigure("benchmarks", "goal_overview", "", "every published benchmark's goals",
               "A red segment is a figure that missed its goal; grey ones are measurements "
               "without a goal. The date beside each name says how old its run is.",
               records=("*",), draw_records=goal_overview),
    PageFigure("benchmarks", "grasp", "grasp_trace", "one grasp, its hold and its release",
               "The force settles on the dashed target, holds, and falls to 0 at the release.",
               grasp_trace),
    PageFigure("benchmarks", "slip_study", "slip_study",
               "a slip's tangential force and the detector's alarm",
               "The alarm (red line) against the slip's onset (purple).", slip_trace),
    PageFigure("benchmarks", "ambient_office", "bench_ambient",
               "the force under office light",
               "Grey leaving the dashed gauge is room light read as force; blue, the "
               "modulated module, stays on it.", ambient_trace),
    PageFigure("benchmarks", "rate_errors", "rate_calibration", "the rate errors per speed",
               "Red (rate-aware) below blue (static) in every row; the dashed line is the "
               "goal.", rate_errors),
    PageFigure("benchmarks", "array_torque_time", "bench_wrench",
               "the torque, estimated against the gauge",
               "The red estimate on the black gauge; the numbers are each excursion's gain.",
               torque_time),
)


def caption(figure: PageFigure, source: str) -> list[str]:
    """The figure's caption: what it shows, what to look at, then where it came from."""
    return [f"**{figure.shows[0].upper()}{figure.shows[1:]}.** {figure.look} {source}", ":::",
            ""]


def records_lines(figure: PageFigure, results: Path, out: Path) -> list[str]:
    """A figure drawn from the figures of several results (``*``: every published one)."""
    assert figure.draw_records is not None
    names = ([p.stem for p in sorted(results.glob("*.json"))] if figure.records == ("*",)
             else list(figure.records))
    records: dict[str, dict[str, Any]] = {}
    for name in names:
        path = results / f"{name}.json"
        if not path.exists():
            return [f"*No figure of {figure.shows}: the result {name} is not published "
                    "yet; run its benchmark at a clean commit, then `make bench-publish`.*", ""]
        try:
            records[name] = read_results(path)
        except ResultsError as exc:
            return [f"*No figure of {figure.shows}: {exc}*", ""]
    if not records:
        return [f"*No figure of {figure.shows}: no result is published yet.*", ""]
    image = figure.draw_records(records, out / f"{figure.name}.png")
    sources = ", ".join(f"{r['benchmark']} (commit `{r['commit']}`, {str(r['date'])[:10]})"
                        for r in records.values()) if len(records) <= 3 else (
        f"{len(records)} results in `benchmarks/results`")
    return [f":::{{figure}} _generated/{image.name}", f":alt: {figure.shows}", "",
            *caption(figure, f"Drawn from the figures of {sources}.")]


def column(values: list[object]) -> np.ndarray:
    """A kept column as numbers (``null`` as NaN), or as text where it names things."""
    if any(isinstance(v, str) for v in values):
        return np.asarray(values, dtype=str)
    return np.asarray(values, dtype=float)


def figure_lines(figure: PageFigure, results: Path, out: Path) -> list[str]:
    """The Markdown of one figure: the image and its caption, or the sentence why not."""
    if figure.draw_records is not None:
        return records_lines(figure, results, out)
    if not figure.result and figure.draw is not None:
        image = figure.draw({}, out / f"{figure.name}.png")
        return [f":::{{figure}} _generated/{image.name}", f":alt: {figure.shows}", "",
                *caption(figure, "This figure is drawn by `make docs` from the package's "
                                 "configuration files.")]
    path = results / f"{figure.result}.json"
    if not path.exists():
        return [f"*No figure of {figure.shows}: the result {figure.result} is not published "
                "yet; run its benchmark at a clean commit, then `make bench-publish`.*", ""]
    try:
        record = read_results(path)
    except ResultsError as exc:
        return [f"*No figure of {figure.shows}: {exc}*", ""]
    series = record.get("series")
    if figure.draw is None or not isinstance(series, dict) or not series:
        return [f"*No figure of {figure.shows}: the result {figure.result} (commit "
                f"`{record['commit']}`) keeps no series to draw it from; rerun "
                f"`{record['command']}` at a clean commit, then `make bench-publish`.*", ""]
    columns = {k: column(v) for k, v in series.items()}
    image = figure.draw(columns, out / f"{figure.name}.png")
    return [f":::{{figure}} _generated/{image.name}", f":alt: {figure.shows}", "",
            *caption(figure, f"Measured by benchmark {record['benchmark']} "
                             f"(`{record['command']}`), "
                             f"commit `{record['commit']}`, {str(record['date'])[:10]}.")]


def write_pages(results: Path, out: Path) -> list[Path]:
    """``<page>.md`` for every page with a figure; returns the files written."""
    out.mkdir(parents=True, exist_ok=True)
    pages: dict[str, list[str]] = {}
    for figure in FIGURES:
        pages.setdefault(figure.page, []).extend(figure_lines(figure, results, out))
    written = []
    for page, lines in pages.items():
        target = out / f"{page}.md"
        target.write_text("\n".join(lines).rstrip("\n") + "\n")
        written.append(target)
    return written


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--results", type=Path, default=PUBLISHED,
                        help="folder of results files (default: benchmarks/results)")
    parser.add_argument("--out", type=Path, default=OUT,
                        help="folder the pages include (default: docs/_generated)")
    args = parser.parse_args(argv)
    written = write_pages(args.results, args.out)
    print(f"docs figures: {len(written)} page(s) -> {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
