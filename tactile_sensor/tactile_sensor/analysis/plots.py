"""PNG figures in the paper's layout (Figs. 7-9), drawn with Matplotlib's Agg backend.

Long recordings are thinned to at most MAX_POINTS per line, and margins are fixed rather
than computed: the figures stay readable and drawing stays a small part of the analysis.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator

from .array.analysis import AXES, ArrayAnalysis
from .characterise import PAPER, Characterisation
from .metrics import ramp_indices
from .uncertainty import ONE_CYCLE

MAX_POINTS = 4_000
#: The paper's compression, as its text gives it (Sec. IV-A; Fig. 7a has no table): about
#: 7 N at 3 mm of indentation at 1 mm/s, nonlinear up to about 0.5 mm and linear beyond.
PAPER_FULL_SCALE_INDENTATION_M = 0.003
PAPER_NONLINEAR_UP_TO_M = 0.0005


def _thin(idx: np.ndarray) -> np.ndarray:
    step = max(1, idx.size // MAX_POINTS)
    return idx[::step]


def _save(fig: Figure, path: Path, top: float = 0.9) -> Path:
    # fixed margins: tight_layout would draw every figure twice
    fig.subplots_adjust(left=0.13, right=0.87, bottom=0.12, top=top, hspace=0.45, wspace=0.6)
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def _pm(value: float | None, ci95: float | None, unit: str, cycles: int) -> str:
    """'0.062 ± 0.01 s (5 cycles)', or the value and 'one cycle: no estimate'."""
    if value is None:
        return "n/a"
    if ci95 is None:
        return f"{value:.3g} {unit} ({ONE_CYCLE})" if cycles == 1 else f"{value:.3g} {unit}"
    return f"{value:.3g} ± {ci95:.2g} {unit} ({cycles} cycles)"


def _ref_cycles(ch: Characterisation) -> list:
    seg = ch.segmentation
    return [seg.cycles[i] for i in seg.speed_groups[seg.reference_key]]


def compression_ramps(ch: Characterisation) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Indentation [m] and force [N] of the reference speed's loading and unloading ramps,
    thinned as drawn: what the compression curve (Fig. 7a) shows."""
    sig, cycles = ch.signals, _ref_cycles(ch)
    ramps = {}
    for which in ("load", "unload"):
        idx = _thin(ramp_indices(cycles, which))
        ramps[which] = (sig.indentation_m[idx], sig.force_n[idx])
    return ramps


def force_vs_indentation(ch: Characterisation, path: Path) -> Path:
    return compression_curve(compression_ramps(ch), ch.segmentation.reference_key, path)


def compression_curve(ramps: dict[str, tuple[np.ndarray, np.ndarray]], speed: str,
                      path: Path) -> Path:
    """Force against indentation, loading and unloading, at ``speed`` [mm/s] (Fig. 7a)."""
    fig, ax = plt.subplots(figsize=(5, 4))
    for which, colour in (("load", "tab:red"), ("unload", "tab:blue")):
        indentation_m, force_n = ramps[which]
        ax.plot(indentation_m * 1e3, force_n, ".", ms=1, color=colour,
                label="loading" if which == "load" else "unloading")
    _paper_compression(ax)
    ax.set(xlabel="indentation [mm]", ylabel="force [N]",
           title=f"Force vs indentation ({speed} mm/s; cf. Fig. 7a)")
    for handle in ax.legend(loc="upper left", fontsize=8).legend_handles[:2]:
        handle.set_markersize(8)  # the ramps' dots, not the paper's star
    return _save(fig, path)


def _paper_compression(ax: Axes) -> None:
    """The paper's curve as far as its text states it: the full-scale point and the
    nonlinear toe, beside the measured ramps."""
    ax.axvspan(0.0, PAPER_NONLINEAR_UP_TO_M * 1e3, color="0.9", zorder=0,
               label="paper: nonlinear toe (< 0.5 mm)")
    ax.plot(PAPER_FULL_SCALE_INDENTATION_M * 1e3, PAPER["full_scale_n"], "k*", ms=10,
            label=f"paper: ≈{PAPER['full_scale_n']:g} N at "
                  f"{PAPER_FULL_SCALE_INDENTATION_M * 1e3:g} mm")


def output_vs_indentation(ch: Characterisation, path: Path) -> Path:
    sig, cycles = ch.signals, _ref_cycles(ch)
    fig, ax = plt.subplots(figsize=(5, 4))
    idx = _thin(ramp_indices(cycles, "load"))
    ax.plot(sig.indentation_m[idx] * 1e3, sig.output_v[idx], ".", ms=1, color="tab:red",
            label="measured (loading)")
    if ch.prediction is not None:
        ax.plot(ch.prediction.indentation_m * 1e3, ch.prediction.predicted_v, "o", ms=3,
                color="tab:blue", label="model")
    ax.set(xlabel="indentation [mm]", ylabel="output change [V]",
           title="Output vs indentation (cf. Fig. 7b)")
    ax.legend(markerscale=3)
    return _save(fig, path)


def output_vs_force(ch: Characterisation, path: Path) -> Path:
    sig, cycles = ch.signals, _ref_cycles(ch)
    fig, ax = plt.subplots(figsize=(5, 4))
    for which, colour in (("load", "tab:red"), ("unload", "tab:blue")):
        idx = _thin(ramp_indices(cycles, which))
        ax.plot(sig.force_n[idx], sig.output_v[idx], ".", ms=1, color=colour,
                label="loading" if which == "load" else "unloading")
    if ch.hysteresis is not None:
        h = ch.hysteresis
        ax.plot(h.force_bins_n, h.load_v, "-", color="darkred", lw=1)
        ax.plot(h.force_bins_n, h.unload_v, "-", color="navy", lw=1)
    if ch.evaluated is not None:
        cal = ch.evaluated
        ax.plot(cal.force_n, cal.output_v, "k--", lw=1, label="calibration")
    mt = ch.metrics
    hyst = _pm(mt.get("hysteresis_pct_fs"), mt.get("hysteresis_ci95_pct_fs"), "% FS",
               len(cycles))
    ax.set(xlabel="force [N]", ylabel="output change [V]",
           title=f"Output vs force (cf. Fig. 7c)\nhysteresis {hyst}")
    ax.title.set_fontsize(9)
    ax.legend(markerscale=8)
    return _save(fig, path)


def cycles_over_time(ch: Characterisation, path: Path) -> Path:
    sig, seg = ch.signals, ch.segmentation
    cycles = _ref_cycles(ch)
    a, b = cycles[0].window[0], cycles[-1].window[1]
    idx = _thin(np.arange(a, b))
    fig, (ax, ax2) = plt.subplots(2, 1, figsize=(8, 5), height_ratios=(2, 1))
    ax.plot(sig.t_s[idx], sig.output_v[idx], lw=0.5, color="tab:red", label="output [V]")
    ax_f = ax.twinx()
    ax_f.plot(sig.t_s[idx], sig.force_n[idx], lw=0.5, color="tab:gray", label="force [N]")
    ax.set(xlabel="time [s]", ylabel="output change [V]",
           title=f"{len(cycles)} cycles at {seg.reference_key} mm/s (cf. Fig. 8a)")
    ax_f.set_ylabel("force [N]")
    peaks = ch.repeatability.peaks_v
    cycle_no = np.arange(1, peaks.size + 1)
    mt = ch.metrics
    centre, ci = mt.get("full_scale_output_v"), mt.get("full_scale_output_ci95_v")
    if centre is not None and ci is not None:
        # where the median peak lies (95 %): a cycle outside the band is more than noise
        ax2.axhspan(centre - ci, centre + ci, color="tab:blue", alpha=0.15, lw=0,
                    label="median ± 95 %")
        ax2.axhline(centre, color="tab:blue", lw=0.8)
        ax2.legend(fontsize=7, loc="lower right")
    ax2.plot(cycle_no, peaks, "o-", ms=3)
    ax2.xaxis.set_major_locator(MaxNLocator(integer=True))  # no cycle 1.25
    ax2.set(xlabel="cycle", ylabel="peak output [V]")
    ax2.set_title(f"peak output {_pm(centre, ci, 'V', peaks.size)}", fontsize=9)
    return _save(fig, path)


def first_last_cycles(ch: Characterisation, path: Path) -> Path:
    """The first and the last k cycles of the reference group on equal axes (Fig. 8b, c):
    k as in the drift metric (10 of 100), so the eye sees what drift_pct compares."""
    sig, seg = ch.signals, ch.segmentation
    cycles = _ref_cycles(ch)
    k = ch.repeatability.drift_cycles or min(10, len(cycles))
    parts = (("first", cycles[:k]), ("last", cycles[-k:]))
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.8), sharey=True)
    twins = []
    for ax, (which, group) in zip(axes, parts, strict=True):
        a, b = group[0].window[0], group[-1].window[1]
        idx = _thin(np.arange(a, b))
        t = sig.t_s[idx] - sig.t_s[a]
        ax.plot(t, sig.output_v[idx], lw=0.6, color="tab:red")
        ax.set(xlabel="time from the group's first press [s]", ylabel="output change [V]",
               title=f"{which} {len(group)} cycles (cycles "
                     f"{cycles.index(group[0]) + 1}-{cycles.index(group[-1]) + 1})")
        twin = ax.twinx()
        twin.plot(t, sig.force_n[idx], lw=0.6, color="tab:gray")
        twin.set_ylabel("force [N]")
        twins.append(twin)
    low = min(tw.get_ylim()[0] for tw in twins)
    high = max(tw.get_ylim()[1] for tw in twins)
    for twin in twins:
        twin.set_ylim(low, high)
    fig.suptitle(f"First and last cycles at {seg.reference_key} mm/s: output (red), "
                 "force (grey) (cf. Fig. 8b, c)")
    return _save(fig, path, top=0.82)


def _stacked(x: np.ndarray, starts: list[int], before: int, length: int) -> np.ndarray:
    """(cycles, length) windows of x from ``before`` samples ahead of each start."""
    return np.stack([x[a - before:a - before + length] for a in starts])


def speeds(ch: Characterisation, path: Path) -> Path:
    """Each speed's cycles laid over each other from their press's start: the mean output
    with a band of ± one standard deviation over the cycles, the mean force, and the lag
    with its 95 % interval (Fig. 9)."""
    sig, seg = ch.signals, ch.segmentation
    keys = sorted(seg.speed_groups, key=float)
    # a tenth of the press either side, but never into the next or last press
    bounds = [0, *(x for c in seg.cycles for x in c.window), sig.t_s.size]
    rest = min(b - a for a, b in zip(bounds[::2], bounds[1::2], strict=True))
    fig, axes = plt.subplots(1, len(keys), figsize=(max(6, 4 * len(keys)), 3.5),
                             squeeze=False)
    for ax, key in zip(axes[0], keys, strict=True):
        group = [seg.cycles[i] for i in seg.speed_groups[key]]
        span = min(c.window[1] - c.window[0] for c in group)
        pad = max(0, min(span // 10, rest // 2))
        starts = [c.window[0] for c in group]
        before = min(pad, *starts)
        length = min(before + span + pad, *(sig.t_s.size - a + before for a in starts))
        idx = _thin(np.arange(length))
        t = (idx - before) / ch.aligned.rate_hz
        out = _stacked(sig.output_v, starts, before, length)[:, idx]
        force = _stacked(sig.force_n, starts, before, length)[:, idx].mean(axis=0)
        mean = out.mean(axis=0)
        if len(group) > 1:
            sd = out.std(axis=0, ddof=1)
            ax.fill_between(t, mean - sd, mean + sd, color="tab:red", alpha=0.25, lw=0)
        ax.plot(t, mean, lw=0.7, color="tab:red")
        ax.set(xlabel="time from the press's start [s]", ylabel="output change [V]")
        speed = ch.metrics["by_speed"].get(key, {})
        lag = _pm(speed.get("phase_lag_s"), speed.get("phase_lag_ci95_s"), "s",
                  speed.get("phase_lag_cycles", len(group)))
        ax.set_title(f"{key} mm/s, {len(group)} cycle{'s' if len(group) > 1 else ''}\n"
                     f"lag {lag}", fontsize=9)
        axf = ax.twinx()
        axf.plot(t, force, lw=0.7, color="tab:gray")
        axf.set_ylabel("force [N]")
    fig.suptitle("Response at each speed (cf. Fig. 9): mean output (red),\nband ± 1 sd over "
                 "the cycles, mean force (grey)", fontsize=9)
    return _save(fig, path, top=0.76)


def speed_summary(ch: Characterisation, path: Path) -> Path:
    """Peak force, peak output and phase lag against speed, each with its 95 % interval
    over the speed's cycles (bars), the paper's lags beside them: what Fig. 9 says in
    numbers, and how sure each is."""
    by_speed = ch.metrics["by_speed"]
    keys = sorted(by_speed, key=float)
    v = np.array([float(k) for k in keys])
    fig, axes = plt.subplots(1, 3, figsize=(12, 3.6))
    panels = (("peak_force_n", "peak_force_ci95_n", "peak force [N]", 1.0),
              ("peak_output_v", "peak_output_ci95_v", "peak output change [V]", 1.0),
              # the lag as indentation: the paper's lags are about one distance (50-70 µm)
              # at every speed, so the three share one scale and one axis
              ("phase_lag_s", "phase_lag_ci95_s", "phase lag x speed [µm]", 1e3))
    for ax, (name, ci_name, label, scale) in zip(axes, panels, strict=True):
        factor = v * scale if name == "phase_lag_s" else np.ones_like(v)
        y = factor * np.array([np.nan if by_speed[k][name] is None else by_speed[k][name]
                               for k in keys])
        err = factor * np.array([by_speed[k].get(ci_name) or 0.0 for k in keys])
        known = np.array([by_speed[k].get(ci_name) is not None for k in keys])
        ax.errorbar(v[known], y[known], yerr=err[known], fmt="o", ms=4, capsize=3,
                    color="tab:red", label="measured ± 95 %")
        if np.any(~known):
            ax.plot(v[~known], y[~known], "o", ms=4, mfc="none", color="tab:red",
                    label=ONE_CYCLE)
        if name == "phase_lag_s":
            paper = [(float(k), 1e3 * float(k) * t) for k, t in PAPER["phase_lag_s"].items()]
            ax.plot(*zip(*paper, strict=True), "k*", ms=8, label="paper")
        ax.set_xscale("log")
        ax.set(xlabel="indentation speed [mm/s]", ylabel=label)
        ax.legend(fontsize=7)
    cycles = ", ".join(f"{by_speed[k]['cycles']} at {k}" for k in keys)
    fig.suptitle(f"Peaks and lag at each speed, 95 % intervals over the cycles ({cycles} "
                 "mm/s) (cf. Fig. 9)", fontsize=10)
    fig.subplots_adjust(left=0.07, right=0.98, bottom=0.15, top=0.85, wspace=0.35)
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def force_estimates(ch: Characterisation, path: Path) -> Path:
    """Calibration across speeds: the gauge, the static estimate and the rate-aware one
    against time, one panel per speed (its first press, hold included)."""
    sig, seg = ch.signals, ch.segmentation
    assert ch.evaluated is not None and ch.evaluated.rate is not None
    assert ch.static_reference is not None
    static_n = ch.static_reference.force_history(sig.t_s, sig.output_v)
    rate_n = ch.evaluated.force_history(sig.t_s, sig.output_v)
    keys = sorted(seg.speed_groups, key=float)
    fig, axes = plt.subplots(1, len(keys), figsize=(4 * len(keys), 3.5), squeeze=False)
    for ax, key in zip(axes[0], keys, strict=True):
        a, b = seg.cycles[seg.speed_groups[key][0]].window
        pad = (b - a) // 10
        idx = _thin(np.arange(max(0, a - pad), min(sig.t_s.size, b + pad)))
        t = sig.t_s[idx] - sig.t_s[a]
        # the gauge drawn last: under the noisy estimates the reference cannot be seen
        ax.plot(t, static_n[idx], lw=0.8, color="tab:blue", alpha=0.8, label="static curve")
        ax.plot(t, rate_n[idx], lw=0.8, color="tab:red", alpha=0.8, label="rate-aware")
        ax.plot(t, sig.force_n[idx], lw=1.4, color="black", zorder=3, label="gauge")
        ax.set(xlabel="time [s]", ylabel="force [N]", title=f"{key} mm/s")
    axes[0][0].legend(loc="upper right", fontsize=8)
    fig.suptitle("Force at each indentation speed: gauge, static and rate-aware estimates")
    return _save(fig, path, top=0.8)


def all_figures(ch: Characterisation, out_dir: Path) -> dict[str, Path]:
    """Write every figure; returns name -> file."""
    makers = {
        "force_vs_indentation": force_vs_indentation,
        "output_vs_indentation": output_vs_indentation,
        "output_vs_force": output_vs_force,
        "cycles": cycles_over_time,
        "first_last_cycles": first_last_cycles,
        "speeds": speeds,
        "speed_summary": speed_summary,
    }
    if ch.static_reference is not None and ch.evaluated is not None and ch.evaluated.rate:
        makers["force_estimates"] = force_estimates
    return {name: make(ch, out_dir / f"{name}.png") for name, make in makers.items()}


def _traces_per_axis(t_s: np.ndarray, estimate: np.ndarray, reference: np.ndarray,
                     quantity: str, unit: str, titles: list[str], noun: str, path: Path,
                     unobserved: tuple[bool, ...] = (False, False, False),
                     excursions: list[list[dict]] | None = None) -> Path:
    """Estimate (driver) and reference (gauge) per axis over the recording, one panel an
    axis; a panel of an axis the driver does not observe says so; each excursion (metrics'
    ``wrench_excursions``) shaded and labelled with its gain."""
    idx = _thin(np.arange(t_s.size))
    fig, axes = plt.subplots(3, 1, figsize=(9, 7), sharex=True)
    for j, (ax, name) in enumerate(zip(axes, AXES, strict=True)):
        # the reference drawn last: under the noisy estimate it cannot be seen
        ax.plot(t_s[idx], estimate[idx, j], lw=0.6, color="tab:red", alpha=0.8,
                label="estimated (driver)")
        ax.plot(t_s[idx], reference[idx, j], lw=0.9, color="black", zorder=3,
                label="reference (gauge)")
        ax.set_ylabel(f"{quantity}{name} [{unit}]")
        if unobserved[j]:
            _unobserved(ax, name)
        for x in (excursions or [[]] * 3)[j]:
            _mark_excursion(ax, x)
        ax.set_title(titles[j], fontsize=9, loc="left")
    # above the first panel, right of its title: inside, it covers a stretch of the trace
    axes[0].legend(fontsize=8, loc="lower right", bbox_to_anchor=(1.0, 1.0), ncols=2,
                   frameon=False, borderaxespad=0.1)
    axes[-1].set_xlabel("time [s]")
    fig.suptitle(f"Estimated vs reference {noun} per axis")
    return _save(fig, path, top=0.9)


def _mark_excursion(ax: Axes, excursion: dict) -> None:
    """Shade one excursion and write its gain above it (red outside 0.85-1.15)."""
    t0, t1, gain = excursion["start_s"], excursion["end_s"], excursion["gain"]
    ax.axvspan(t0, t1, color="tab:orange", alpha=0.12, lw=0)
    if gain is None:
        return
    ax.text(0.5 * (t0 + t1), 0.97, f"{gain:.2f}", transform=ax.get_xaxis_transform(),
            ha="center", va="top", fontsize=7, zorder=6,
            color="black" if 0.85 <= gain <= 1.15 else "tab:red")


def _excursions(an: ArrayAnalysis, kind: str) -> list[list[dict]]:
    """Per axis the excursions of the force (``kind`` f) or torque (t) in the metrics."""
    found = an.metrics.get("wrench_excursions", {})
    return [found.get(f"{kind}{name}", []) for name in AXES]


def array_force_time(an: ArrayAnalysis, path: Path) -> Path:
    """Estimated (driver) and reference (gauge) force per axis over the recording."""
    sig = an.signals
    marks = _excursions(an, "f")
    titles = [f"F{name}: rmse {an.rmse_n[j]:.3g} N over a range of {an.range_n[j]:.3g} N"
              for j, name in enumerate(AXES)]
    return _traces_per_axis(sig.t_s, sig.estimate_n, sig.reference_n, "F", "N", titles,
                            "force", path, excursions=marks)


def array_force_scatter(an: ArrayAnalysis, path: Path) -> Path:
    """Each estimated axis against each reference axis: the diagonal is the estimate's
    accuracy, the off-diagonal panels its cross-talk (slopes of force_cross_talk)."""
    sig = an.signals
    idx = _thin(np.arange(sig.t_s.size))
    fig, axes = plt.subplots(3, 3, figsize=(9, 8.5))
    for i, est in enumerate(AXES):
        for j, ref in enumerate(AXES):
            ax = axes[i, j]
            ax.plot(sig.reference_n[idx, j], sig.estimate_n[idx, i], ".", ms=1,
                    color="tab:red" if i == j else "tab:blue")
            if i == j:
                lo = float(min(sig.reference_n[:, j].min(), sig.estimate_n[:, i].min()))
                hi = float(max(sig.reference_n[:, j].max(), sig.estimate_n[:, i].max()))
                ax.plot([lo, hi], [lo, hi], "k--", lw=0.8)
            k = an.cross_talk[i, j]
            ax.set_title(f"slope {k:.3g}" if np.isfinite(k) else "slope n/a", fontsize=8)
            if i == 2:
                ax.set_xlabel(f"reference F{ref} [N]")
            if j == 0:
                ax.set_ylabel(f"estimated F{est} [N]")
    fig.suptitle("Estimated vs reference force, every axis pair (diagonal: accuracy; "
                 "off-diagonal: cross-talk)", fontsize=10)
    return _save(fig, path, top=0.92)


def _unobserved(ax: Axes, name: str) -> None:
    """Say in the panel why a torque axis has no estimate (the driver publishes NaN)."""
    # boxed: over the reference trace the bare words are hard to read
    ax.text(0.5, 0.5, f"T{name} not observed by the driver (NaN)", ha="center",
            va="center", transform=ax.transAxes, fontsize=9, color="tab:red", zorder=5,
            bbox={"facecolor": "white", "edgecolor": "tab:red", "alpha": 0.9})


def array_torque_time(an: ArrayAnalysis, path: Path) -> Path:
    """Estimated (driver) and reference (gauge) torque per axis over the recording [mN m];
    an axis the driver does not observe shows the reference and says so."""
    sig = an.signals
    est, ref = sig.estimate_torque_nm * 1e3, sig.reference_torque_nm * 1e3
    rmse, span = np.asarray(an.torque_rmse_nm) * 1e3, np.asarray(an.torque_range_nm) * 1e3
    unobserved = tuple(not np.isfinite(r) for r in rmse)
    marks = _excursions(an, "t")
    titles = [f"T{name}: rmse {rmse[j]:.3g} mN m over a range of {span[j]:.3g} mN m"
              if not unobserved[j] else
              f"T{name}: not observed (driver NaN); reference range {span[j]:.3g} mN m"
              for j, name in enumerate(AXES)]
    return _traces_per_axis(sig.t_s, est, ref, "T", "mN m", titles, "torque", path,
                            unobserved, marks)


def array_torque_scatter(an: ArrayAnalysis, path: Path) -> Path:
    """Each estimated torque against its reference [mN m], with the identity line."""
    sig = an.signals
    est, ref = sig.estimate_torque_nm * 1e3, sig.reference_torque_nm * 1e3
    rmse = np.asarray(an.torque_rmse_nm) * 1e3
    idx = _thin(np.arange(sig.t_s.size))
    fig, axes = plt.subplots(1, 3, figsize=(11, 4))
    for j, (ax, name) in enumerate(zip(axes, AXES, strict=True)):
        ax.set_xlabel(f"reference T{name} [mN m]")
        ax.set_ylabel(f"estimated T{name} [mN m]")
        if not np.isfinite(rmse[j]):
            ax.set_title(f"T{name}: not observed", fontsize=9)
            _unobserved(ax, name)
            ax.set_xticks([])
            ax.set_yticks([])
            continue
        ax.plot(ref[idx, j], est[idx, j], ".", ms=1, color="tab:red")
        both = np.concatenate([ref[:, j], est[:, j]])
        lo, hi = float(np.nanmin(both)), float(np.nanmax(both))
        ax.plot([lo, hi], [lo, hi], "k--", lw=0.8)
        ax.set_title(f"T{name}: rmse {rmse[j]:.3g} mN m", fontsize=9)
    fig.suptitle("Estimated vs reference torque (dashed: identity)", fontsize=10)
    fig.subplots_adjust(left=0.07, right=0.98, bottom=0.15, top=0.85, wspace=0.4)
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def _heatmap(ax: Axes, values: np.ndarray, rows: list[str], cols: list[str], title: str,
             vmax: float) -> None:
    shown = np.ma.masked_invalid(values)
    image = ax.imshow(shown, cmap="RdBu_r", vmin=-vmax, vmax=vmax)
    ax.set_xticks(range(len(cols)), cols)
    ax.set_yticks(range(len(rows)), rows)
    for (r, c), v in np.ndenumerate(values):
        dark = np.isfinite(v) and abs(v) > 0.6 * vmax  # black on deep red or blue is unreadable
        ax.text(c, r, f"{v:.2f}" if np.isfinite(v) else "n/a", ha="center", va="center",
                fontsize=8, color="white" if dark else "black")
    ax.set_title(title, fontsize=9)
    plt.colorbar(image, ax=ax, shrink=0.8)


def array_crosstalk(an: ArrayAnalysis, path: Path) -> Path:
    """Left: the sensitivity matrix with each column scaled by its axis' reference range and
    each row by its largest entry (which axes move each module, relative to each other).
    Right: the estimate's cross-talk matrix (ideally the identity)."""
    fig, (left, right) = plt.subplots(1, 2, figsize=(10, 4))
    sens = an.sensitivity
    if sens is not None:
        scaled = sens.matrix_v_per_n * an.range_n[None, :]
        top = np.nanmax(np.abs(scaled), axis=1, initial=0.0)
        with np.errstate(divide="ignore", invalid="ignore"):
            norm = np.where(top[:, None] > 0, scaled / top[:, None], np.nan)
        _heatmap(left, norm, list(sens.faces), [f"F{a}" for a in AXES],
                 "module output change over each axis' range\n(row-normalised S x range)", 1.0)
    else:
        left.text(0.5, 0.5, "no per-module outputs", ha="center", va="center")
        left.set_axis_off()
    _heatmap(right, an.cross_talk, [f"est F{a}" for a in AXES], [f"ref F{a}" for a in AXES],
             "estimate's cross-talk [N/N]\n(est = K ref + b; ideal: identity)", 1.0)
    return _save(fig, path, top=0.85)


def array_shear_direction(an: ArrayAnalysis, path: Path) -> Path:
    """Lateral force direction, applied (gauge) and estimated (driver), on polar axes with
    the lateral magnitude as radius, where the applied lateral force reaches the threshold."""
    fig = plt.figure(figsize=(9, 4.5))
    polar = fig.add_subplot(1, 2, 1, projection="polar")
    err_ax = fig.add_subplot(1, 2, 2)
    sh = an.shear
    if sh is None:
        polar.set_title("no lateral force above the threshold", fontsize=9)
        err_ax.set_axis_off()
    else:
        idx = _thin(np.arange(sh.applied_rad.size))
        polar.plot(sh.applied_rad[idx], sh.applied_n[idx], ".", ms=2, color="tab:gray",
                   label="applied (gauge)")
        polar.plot(sh.estimated_rad[idx], sh.estimated_n[idx], ".", ms=2, color="tab:red",
                   label="estimated (driver)")
        polar.set_title(f"lateral force direction [N radius], |F_lat,ref| >= "
                        f"{sh.threshold_n:.3g} N", fontsize=9)
        # four radius labels between two spokes of the eight-direction protocol, not
        # eight stacked on the 0 deg spoke
        polar.yaxis.set_major_locator(MaxNLocator(4))
        polar.set_rlabel_position(22.5)
        polar.legend(fontsize=7, loc="lower left", bbox_to_anchor=(-0.15, -0.15))
        err_ax.plot(np.degrees(sh.applied_rad[idx]), np.degrees(sh.error_rad[idx]), ".", ms=2)
        err_ax.axhline(0.0, color="k", lw=0.6)
        err_ax.set(xlabel="applied direction [deg] (0 = +x, 90 = +y)",
                   ylabel="estimated - applied [deg]", title="direction error")
    fig.suptitle("Shear direction, estimated vs applied")
    fig.subplots_adjust(left=0.06, right=0.97, bottom=0.14, top=0.83, wspace=0.35)
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def array_figures(an: ArrayAnalysis, out_dir: Path) -> dict[str, Path]:
    """Write the array's figures; returns name -> file."""
    makers = {
        "array_force_time": array_force_time,
        "array_force_scatter": array_force_scatter,
        "array_crosstalk": array_crosstalk,
        "array_shear_direction": array_shear_direction,
    }
    if an.torque_rmse_nm is not None:
        makers["array_torque_time"] = array_torque_time
        makers["array_torque_scatter"] = array_torque_scatter
    return {name: make(an, out_dir / f"{name}.png") for name, make in makers.items()}
