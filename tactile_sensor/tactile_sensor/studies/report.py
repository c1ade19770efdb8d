"""A study's results for people: the table (CSV), the Pareto summary (JSON), plots and a
report whose sentences are computed from the rows.

CSV, not Parquet: a study's table has thousands of rows at most, and pyarrow would add a
60+ MB dependency to read what the csv module and any spreadsheet read already.
"""

from __future__ import annotations

import csv
import json
import math
import textwrap
from pathlib import Path
from typing import Any

import numpy as np

from tactile_sensor.physics.observability import NOISE_BANDWIDTHS_HZ, OBSERVE_SNR
from tactile_sensor.physics.params import PhysicsParams
from tactile_sensor.physics.wrench import WRENCH_AXES

from .pareto import pareto_mask
from .run import REFERENCE, DesignRow, metric_value
from .spec import WRENCH_METRIC, StudySpec

TORQUE_NOTE = ("The sensitivity matrix covers Fx, Fy, Fz only; torque (twist about z, tilt "
               "about x and y) is the metric wrench_observability, which solves the wrench "
               "paths (physics/wrench.py) and tells which of Fx, Fy, Fz, Tx, Ty, Tz a layout "
               "resolves above the noise.")
_UNITS = {name: meta["unit"] for name, meta in PhysicsParams.describe().items()}
NAMES = {"sensitivity_v_per_n": "sensitivity", "full_scale_n": "full-scale force",
         "linearity_pct_fs": "non-linearity", "dynamic_range_db": "dynamic range",
         "condition_number": "condition number of S", "crosstalk": "cross-talk",
         "shear_sensitivity_v_per_n": "shear sensitivity",
         "observed_torques": "torques observed", "wrench_rank": "wrench directions resolved"}
#: Axis labels (with units) of the plots.
LABELS = {"sensitivity_v_per_n": "sensitivity [V/N]", "full_scale_n": "full-scale force [N]",
          "linearity_pct_fs": "non-linearity [% FS]", "dynamic_range_db": "dynamic range [dB]",
          "condition_number": "condition number of S", "crosstalk": "cross-talk (max |cos|)",
          "shear_sensitivity_v_per_n": "shear sensitivity [V/N]",
          "observed_torques": "torques observed (of Tx, Ty, Tz)",
          "wrench_rank": "wrench directions resolved (of 6)"}


def headline_columns(spec: StudySpec) -> list[str]:
    """The metric columns worth a plot and a sentence (not S's twelve entries, nor the
    wrench metric's per-component detail)."""
    return [c for c in spec.columns if not c.startswith((
        "s_", "singular_value_", "wrench_singular_value_", "observes_", "distinct_",
        "full_scale_f", "full_scale_t", "noise_", "output_noise_v"))]


def pareto_rows(rows: list[DesignRow], spec: StudySpec) -> list[DesignRow]:
    objectives = list(spec.objectives)
    values = [[metric_value(r, c) for c in objectives] for r in rows]
    if not rows:
        return []
    mask = pareto_mask(np.array(values, float).reshape(len(rows), len(objectives)),
                       [spec.objectives[c] for c in objectives])
    return [r for r, keep in zip(rows, mask, strict=True) if keep]


def fmt_param(name: str, value: Any) -> str:
    """A parameter value for a sentence: lengths in mm, others in their SI unit."""
    if isinstance(value, str):
        return value
    unit = _UNITS.get(name, "")
    if unit == "m":
        return f"{value * 1e3:.3g} mm"
    return f"{value:.4g}" + (f" {unit}" if unit not in ("", "1", "-") else "")


def fmt_metric(column: str, value: float) -> str:
    if math.isnan(value):
        return "n/a"
    if math.isinf(value):
        return "inf"
    unit = {"_v_per_n": " V/N", "_n": " N", "_pct_fs": " % FS", "_db": " dB"}
    suffix = next((u for end, u in unit.items() if column.endswith(end)), "")
    return f"{value:.3g}{suffix}"


def describe(row: DesignRow, paper: DesignRow | None = None) -> str:
    what = ", ".join(f"{k} {fmt_param(k, v)}" for k, v in row.values.items())
    name = "the paper's design" if row.design == REFERENCE else f"design {row.design}"
    if paper is not None and row is not paper and row.digest and row.digest == paper.digest:
        name += " (the paper's design again)"
    return f"{name} ({what})" if what else name


# -- table and summary -------------------------------------------------------------------------


def _cell(value: Any) -> str:
    if isinstance(value, float):
        return "" if math.isnan(value) else f"{value:.10g}"
    return str(value)


def write_table(rows: list[DesignRow], spec: StudySpec, path: Path) -> None:
    """One row per design: id, varied parameters (SI), metrics, seconds, worker, error."""
    columns = ["design", "digest", *spec.varied, *spec.columns, "seconds", "worker", "error"]
    with path.open("w", newline="", encoding="utf-8") as handle:
        writer = csv.writer(handle)
        writer.writerow(columns)
        for r in rows:
            writer.writerow([_cell(v) for v in (
                r.design, r.digest, *(r.values.get(n, "") for n in spec.varied),
                *(r.metrics.get(c, math.nan) if r.ok else math.nan for c in spec.columns),
                round(r.seconds, 3), r.worker, r.error)])


def _plain(row: DesignRow, spec: StudySpec) -> dict[str, Any]:
    def number(v: float) -> float | str | None:
        return None if math.isnan(v) else ("inf" if math.isinf(v) else v)

    return {"design": row.design, "digest": row.digest, "values": row.values,
            "metrics": {c: number(metric_value(row, c)) for c in spec.columns},
            "seconds": row.seconds, "worker": row.worker, "error": row.error or None}


def summary(rows: list[DesignRow], spec: StudySpec) -> dict[str, Any]:
    """Counts, the paper's row, the Pareto designs and the best design per objective."""
    ok = [r for r in rows if r.ok]
    best = {}
    for column, sense in spec.objectives.items():
        scored = [r for r in ok if not math.isnan(metric_value(r, column))]
        if scored:
            pick = (max if sense == "max" else min)(scored, key=lambda r: metric_value(r, column))
            best[column] = _plain(pick, spec)
    return {"name": spec.name, "designs": len(rows), "solved": len(ok),
            "failed": len(rows) - len(ok), "objectives": spec.objectives,
            "varied": list(spec.varied), "fixed": spec.fixed, "noise_v": spec.output_noise_v,
            "paper": _plain(rows[0], spec),
            "pareto": [_plain(r, spec) for r in pareto_rows(rows, spec)],
            "best": best,
            "torque": (wrench_finding(rows, spec) if WRENCH_METRIC in spec.metrics
                       else TORQUE_NOTE)}


# -- lessons -----------------------------------------------------------------------------------


def _numeric(values: list[Any]) -> np.ndarray | None:
    try:
        return np.array([float(v) for v in values])
    except (TypeError, ValueError):
        return None


def trend(rows: list[DesignRow], param: str, column: str) -> tuple[float, list[tuple[Any, float]]]:
    """(Spearman rho of the metric against the parameter, median metric per parameter
    value in increasing order) over the solved designs; rho NaN for a non-numeric one."""
    from scipy.stats import spearmanr

    pairs = [(r.values[param], metric_value(r, column)) for r in rows
             if r.ok and param in r.values and math.isfinite(metric_value(r, column))]
    if len(pairs) < 2:
        return math.nan, []
    xs = [p[0] for p in pairs]
    numeric = _numeric(xs)
    keys = sorted(set(xs), key=lambda v: (float(v) if numeric is not None else str(v)))
    medians = [(k, float(np.median([m for x, m in pairs if x == k]))) for k in keys]
    if numeric is None or np.ptp(numeric) == 0:
        return math.nan, medians
    ys = np.array([p[1] for p in pairs])
    if np.ptp(ys) == 0:
        return 0.0, medians
    rho = float(spearmanr(numeric, ys).statistic)
    return rho, medians


def lessons(rows: list[DesignRow], spec: StudySpec) -> list[str]:
    """One computed sentence per headline metric: the varied parameter whose values move
    its median most, which way (Spearman rho) and the medians along that parameter."""
    out = []
    for column in headline_columns(spec):
        label = NAMES.get(column, column)
        candidates = []
        for param in spec.varied:
            rho, medians = trend(rows, param, column)
            if len(medians) >= 2:
                finite = [m for _, m in medians if math.isfinite(m)]
                spread = max(finite) - min(finite) if finite else 0.0
                candidates.append((spread, param, rho, medians))
        if not candidates:
            out.append(f"{label}: too few solved designs to tell what moves it.")
            continue
        _, param, rho, medians = max(candidates, key=lambda c: c[0])
        path = " -> ".join(f"{fmt_metric(column, m)} at {fmt_param(param, v)}"
                           for v, m in medians)
        if math.isnan(rho):
            out.append(f"{label} depends most on {param}: median {path}.")
        elif abs(rho) < 0.3:
            out.append(f"{label}: no varied parameter moves it consistently (most: {param}, "
                       f"Spearman rho {rho:+.2f}): median {path}.")
        else:
            verb = "rises" if rho > 0 else "falls"
            out.append(f"{label} {verb} with {param} (Spearman rho {rho:+.2f}, the largest "
                       f"change of any varied parameter): median {path}.")
    return out


def _comparison(row: DesignRow, paper: DesignRow, spec: StudySpec) -> str:
    parts = []
    for column in headline_columns(spec):
        mine, ref = metric_value(row, column), metric_value(paper, column)
        ratio = f" ({mine / ref:.2f}x)" if math.isfinite(mine) and math.isfinite(ref) and \
            ref != 0 else ""
        parts.append(f"{NAMES.get(column, column)} {fmt_metric(column, mine)} vs "
                     f"{fmt_metric(column, ref)}{ratio}")
    return "; ".join(parts)


def report_markdown(rows: list[DesignRow], spec: StudySpec, seconds: float,
                    plots: list[str]) -> str:
    """report.md: the best designs beside the paper's and what the study teaches."""
    paper = rows[0]
    ok = [r for r in rows if r.ok]
    failed = [r for r in rows if not r.ok]
    front = pareto_rows(rows, spec)
    lines = [f"# Design study: {spec.name}", "",
             f"{len(rows)} designs ({spec.sampler}"
             + (f", {spec.points} points, seed {spec.seed}" if spec.sampler != "grid" else "")
             + f"; the paper's first), {len(ok)} solved, {len(failed)} failed; "
             f"{seconds:.0f} s wall time. Varied: "
             + ", ".join(spec.varied) + ". Fixed: "
             + (", ".join(f"{k} {fmt_param(k, v)}" for k, v in spec.fixed.items()) or "none")
             + ".", ""]
    lines += ["## The paper's design", ""]
    if paper.ok:
        lines.append(f"{describe(paper)}: " + ", ".join(
            f"{NAMES.get(c, c)} {fmt_metric(c, metric_value(paper, c))}"
            for c in headline_columns(spec)) + ".")
    else:
        lines.append(f"The paper's design failed: {paper.error}")
    lines += ["", "## Best designs beside the paper's", ""]
    for column, sense in spec.objectives.items():
        scored = [r for r in ok if math.isfinite(metric_value(r, column))]
        if not scored:
            continue
        pick = (max if sense == "max" else min)(scored, key=lambda r: metric_value(r, column))
        same = pick is paper or (pick.digest and pick.digest == paper.digest)
        lines.append(f"- {'Highest' if sense == 'max' else 'Lowest'} "
                     f"{NAMES.get(column, column)}: {describe(pick, paper)}"
                     + (": the paper's design is the best here" if same else
                        ". " + _comparison(pick, paper, spec) if paper.ok else "") + ".")
    lines += ["", f"## Pareto front ({', '.join(f'{k} {v}' for k, v in spec.objectives.items())})",
              ""]
    paper_on = any(r is paper for r in front)
    lines.append(f"{len(front)} of {len(ok)} solved designs are non-dominated; the paper's "
                 f"design is {'on' if paper_on else 'not on'} the front.")
    lines.append("")
    for r in sorted(front, key=lambda r: [metric_value(r, c) for c in spec.objectives]):
        lines.append(f"- {describe(r, paper)}: " + ", ".join(
            f"{fmt_metric(c, metric_value(r, c))}" for c in spec.objectives))
    lines += ["", "## What the study teaches about placement", ""]
    lines += [f"- {s}" for s in lessons(rows, spec)]
    if failed:
        lines += ["", "## Failed designs", ""]
        lines += [f"- {describe(r)}: {r.error}" for r in failed]
    if WRENCH_METRIC in spec.metrics:
        lines += ["", "## Torque: which wrench components each layout observes", ""]
        lines += wrench_lines(rows, spec)
    elif "condition_number" in spec.columns:
        lines += ["", f"Note: {TORQUE_NOTE}"]
    lines += ["", "## Files", "", "- results.csv: one row per design", "- summary.json: "
              "Pareto designs and the best per objective"] + [f"- {p}" for p in plots]
    return "\n".join(lines) + "\n"


# -- torque ------------------------------------------------------------------------------------


def _observed(row: DesignRow) -> list[str]:
    return [a.upper() for a in WRENCH_AXES if metric_value(row, f"observes_{a}") == 1.0]


def wrench_finding(rows: list[DesignRow], spec: StudySpec) -> str:
    """One computed sentence: which designs observe a torque, or that none does and by how
    much the best torque signal falls short of the threshold."""
    threshold = OBSERVE_SNR * spec.output_noise_v
    ok = [r for r in rows if r.ok and math.isfinite(metric_value(r, "observed_torques"))]
    if not ok:
        return "No design was solved, so the study cannot tell whether a layout observes torque."
    seeing = [r for r in ok if metric_value(r, "observed_torques") > 0]
    best, axis = max(((r, a) for r in ok for a in ("tx", "ty", "tz")),
                     key=lambda ra: metric_value(ra[0], f"distinct_{ra[1]}_v"))
    signal = metric_value(best, f"distinct_{axis}_v")
    noise = (f"the noise at {spec.bandwidth_hz:g} Hz" if spec.bandwidth_hz is not None
             else "noise_v")
    rule = (f"the threshold is {OBSERVE_SNR:g} x {noise} = {threshold * 1e3:.3g} mV of "
            "output a full-scale component must move the modules by beyond what the forces "
            "explain")
    if not seeing:
        return (f"No layout within the study's bounds observes a torque: the largest "
                f"torque signal not explained by the forces is {signal * 1e3:.3g} mV "
                f"({axis.upper()}, {describe(best)}), and {rule}.")
    names = "; ".join(f"{describe(r)}: {', '.join(t for t in _observed(r) if t[0] == 'T')}"
                      for r in seeing)
    return (f"{len(seeing)} of {len(ok)} solved designs observe a torque ({names}); the "
            f"largest torque signal is {signal * 1e3:.3g} mV ({axis.upper()}, "
            f"{describe(best)}), and {rule}.")


def _noise_text(row: DesignRow) -> str:
    """Each component's estimate noise [% FS] at the reported bandwidths, e.g. Fx 0.1/0.3/1."""
    def pct(v: float) -> str:
        return f"{v:.2g}" if math.isfinite(v) else "inf"

    return ", ".join(a.upper() + " " + "/".join(
        pct(metric_value(row, f"noise_{a}_pct_fs_{hz}hz")) for hz in NOISE_BANDWIDTHS_HZ)
        for a in WRENCH_AXES)


def wrench_lines(rows: list[DesignRow], spec: StudySpec) -> list[str]:
    """Per solved design: the components observed, the singular values of the full-scale
    output patterns [V] and each torque's signal beyond the forces; then the finding."""
    out = []
    for r in rows:
        if not r.ok or not math.isfinite(metric_value(r, "wrench_rank")):
            continue
        values = ", ".join(f"{metric_value(r, f'wrench_singular_value_{k}_v') * 1e3:.3g}"
                           for k in range(1, 7))
        torques = ", ".join(f"{a.upper()} {metric_value(r, f'distinct_{a}_v') * 1e3:.3g}"
                            for a in ("tx", "ty", "tz"))
        out.append(f"- {describe(r)}: observes {', '.join(_observed(r)) or 'nothing'} "
                   f"({metric_value(r, 'wrench_rank'):.0f} of 6 directions resolved); "
                   f"singular values {values} mV; torque signal beyond the forces "
                   f"{torques} mV; noise in % of full scale at "
                   f"{', '.join(f'{hz:g}' for hz in NOISE_BANDWIDTHS_HZ)} Hz: "
                   f"{_noise_text(r)}.")
    out += ["", wrench_finding(rows, spec),
            "(Singular values of S6 with each column scaled to the load the wrench paths "
            "reach, full_scale_* in results.csv; a direction counts when it exceeds the "
            "threshold.)"]
    return out


# -- plots -------------------------------------------------------------------------------------


def _axes_pair(spec: StudySpec) -> tuple[str, str]:
    """(x, y) of the Pareto plot: full scale and sensitivity when measured."""
    if "full_scale_n" in spec.columns and "sensitivity_v_per_n" in spec.columns:
        return "full_scale_n", "sensitivity_v_per_n"
    objectives = list(spec.objectives) + [c for c in headline_columns(spec)
                                          if c not in spec.objectives]
    return objectives[0], objectives[1] if len(objectives) > 1 else objectives[0]


def _integer_axis(axis: Any, values: list[float]) -> None:
    """Whole-number metrics (observed_torques, wrench_rank) get whole-number ticks, and a
    span of at least one either side: Matplotlib's default puts 0.2 steps between 3 and 4,
    and a single value in the middle of +/-0.05."""
    from matplotlib.ticker import MaxNLocator, MultipleLocator

    finite = [v for v in values if math.isfinite(v)]
    if not finite or any(v != round(v) for v in finite):
        return
    low, high = min(finite), max(finite)
    # MaxNLocator(integer=True) falls back to fractions on a span of a few units
    axis.set_major_locator(MultipleLocator(1) if high - low <= 10
                           else MaxNLocator(integer=True))
    if high - low < 2:
        set_limits = axis.axes.set_xlim if axis is axis.axes.xaxis else axis.axes.set_ylim
        set_limits(low - 0.5, high + 0.5)


def _short(text: str, width: int = 18) -> str:
    """A category's tick label: long module lists run into each other (results.csv holds
    them in full)."""
    return text if len(text) <= width else text[:width - 1] + "…"


def _fitted_title(fig: Any, text: str, fontsize: float = 10.0) -> None:
    """A figure title wrapped to the figure's width: centred, a long one otherwise runs off
    both edges of a narrow figure (one varied parameter: one column of plots)."""
    chars = max(20, int(fig.get_figwidth() * 72 / (0.6 * fontsize)))
    fig.suptitle(textwrap.fill(text, chars), fontsize=fontsize)


def write_pareto_plot(rows: list[DesignRow], spec: StudySpec, path: Path) -> None:
    """Sensitivity against full scale: every design, the Pareto front, the paper's star.
    The legend sits outside the axes, so it covers no design; designs on the same point
    share one label."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    x_col, y_col = _axes_pair(spec)
    ok = [r for r in rows if r.ok and math.isfinite(metric_value(r, x_col))
          and math.isfinite(metric_value(r, y_col))]
    front = [r for r in pareto_rows(rows, spec) if r in ok]
    fig, ax = plt.subplots(figsize=(7, 5), constrained_layout=True)
    ax.scatter([metric_value(r, x_col) for r in ok], [metric_value(r, y_col) for r in ok],
               s=22, color="0.6", label=f"designs ({len(ok)} solved)")
    front.sort(key=lambda r: metric_value(r, x_col))
    ax.plot([metric_value(r, x_col) for r in front], [metric_value(r, y_col) for r in front],
            "o-", color="tab:red", ms=6, label="non-dominated (Pareto)")
    at: dict[tuple[float, float], list[str]] = {}
    for r in front:
        at.setdefault((metric_value(r, x_col), metric_value(r, y_col)), []).append(r.design)
    for (x, y), names in at.items():
        label = ", ".join(names) if len(names) <= 4 else f"{', '.join(names[:3])} +{len(names) - 3}"
        ax.annotate(label, (x, y), textcoords="offset points", xytext=(4, 4), fontsize=8)
    paper = rows[0]
    if paper in ok:
        ax.plot(metric_value(paper, x_col), metric_value(paper, y_col), "*", color="black",
                ms=16, label="paper's design")
    ax.set(xlabel=LABELS.get(x_col, x_col), ylabel=LABELS.get(y_col, y_col),
           title=f"{spec.name}: Pareto front")
    ax.title.set_fontsize(10)
    ax.grid(True, alpha=0.3)
    _integer_axis(ax.xaxis, [metric_value(r, x_col) for r in ok])
    _integer_axis(ax.yaxis, [metric_value(r, y_col) for r in ok])
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0)
    try:
        fig.savefig(path, dpi=120, format="png")
    finally:
        plt.close(fig)


def write_metrics_plot(rows: list[DesignRow], spec: StudySpec, path: Path) -> None:
    """Each headline metric against each varied parameter (paper's design starred)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    metrics, params = headline_columns(spec), list(spec.varied)
    fig, axes = plt.subplots(len(metrics), len(params), squeeze=False,
                             figsize=(3.2 * len(params) + 1, 2.4 * len(metrics) + 0.6),
                             constrained_layout=True)
    for j, param in enumerate(params):
        # a varied board is no physics parameter: the paper's design has none
        ok = [r for r in rows if r.ok and param in r.values]
        raw = [r.values[param] for r in ok]
        numeric = _numeric(raw)
        cats = sorted({str(v) for v in raw})
        scale = 1e3 if _UNITS.get(param) == "m" else 1.0

        def place(v: Any, numeric: Any = numeric, cats: list[str] = cats,
                  scale: float = scale) -> float:
            return float(v) * scale if numeric is not None else float(cats.index(str(v)))

        for i, column in enumerate(metrics):
            ax = axes[i][j]
            xs = [place(r.values[param]) for r in ok]
            ax.plot(xs, [metric_value(r, column) for r in ok], "o", color="tab:blue", ms=4,
                    alpha=0.7)
            if rows[0].ok and param in rows[0].values and (
                    numeric is not None or str(rows[0].values[param]) in cats):
                ax.plot(place(rows[0].values[param]), metric_value(rows[0], column), "*",
                        color="black", ms=12)
            if numeric is None:
                ax.set_xticks(range(len(cats)), [_short(c) for c in cats], fontsize=7,
                              rotation=15)
                ax.set_xlim(-0.5, len(cats) - 0.5)
            _integer_axis(ax.yaxis, [metric_value(r, column) for r in ok])
            if i == len(metrics) - 1:
                unit = "mm" if scale == 1e3 else _UNITS.get(param, "")
                ax.set_xlabel(f"{param}" + (f" [{unit}]" if unit not in ("-", "") else ""))
            if j == 0:
                ax.set_ylabel(LABELS.get(column, column), fontsize=8)
            ax.grid(True, alpha=0.3)
    _fitted_title(fig, f"{spec.name}: metrics against the varied parameters (star: paper's "
                  "design)")
    try:
        fig.savefig(path, dpi=110, format="png")
    finally:
        plt.close(fig)


def write_results(rows: list[DesignRow], spec: StudySpec, out: Path, seconds: float
                  ) -> dict[str, Path]:
    """Every output file into ``out``: results.csv, summary.json, pareto.png, metrics.png,
    report.md."""
    out.mkdir(parents=True, exist_ok=True)
    paths = {name: out / name for name in ("results.csv", "summary.json", "pareto.png",
                                            "metrics.png", "report.md")}
    write_table(rows, spec, paths["results.csv"])
    paths["summary.json"].write_text(json.dumps(summary(rows, spec), indent=1) + "\n",
                                     encoding="utf-8")
    write_pareto_plot(rows, spec, paths["pareto.png"])
    write_metrics_plot(rows, spec, paths["metrics.png"])
    paths["report.md"].write_text(report_markdown(
        rows, spec, seconds, ["pareto.png: " + " against ".join(reversed(_axes_pair(spec)))
                              + ", Pareto front in red, the paper's design starred",
                              "metrics.png: each metric against each varied parameter"]),
        encoding="utf-8")
    return paths

