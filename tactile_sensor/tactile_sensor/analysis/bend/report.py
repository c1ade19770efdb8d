"""``tactile-sensor analyze`` on a bend recording: metrics.json, figures and report.md."""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import AnalysisError
from .metrics import phases
from .record import BendRecord, read_bend

#: The issue's goals over 0-90 deg at 0.5 Hz, and with a tip contact up to 2 N.
GOALS = {"rmse_deg": 2.0, "lag_s": 0.020, "hysteresis_pct": 3.0, "contact_rmse_deg": 3.0}


def bend_metrics(rec: BendRecord) -> dict[str, Any]:
    found = phases(rec.t_s, rec.truth_rad, rec.estimate_rad, rec.tip_force_n,
                   rec.tip_estimate_n)
    return {"configuration": "bend", "modules": rec.modules, "samples": int(rec.t_s.size),
            "duration_s": float(rec.t_s[-1]) if rec.t_s.size else 0.0, "phases": found,
            "goals": GOALS}


def _pm(entry: dict[str, Any], scale: float = 1.0, digits: int = 2) -> str:
    mean, sem = entry.get("mean"), entry.get("sem")
    if mean is None:
        return "n/a"
    text = f"{mean * scale:.{digits}f}"
    return text + (f" ± {sem * scale:.{digits}f}" if sem is not None else "")


def _hysteresis(p: dict[str, Any]) -> str:
    """The group's hysteresis beside what noise alone gives, then the per-bend figure."""
    h = p["hysteresis_pct"]
    floor = h.get("noise_floor")
    text = f"hysteresis {_pm(h)} % of range"
    if floor is not None:
        text += f" (noise floor {floor:.2f} %)"
    per_bend = p.get("hysteresis_pct_per_bend")
    if per_bend is not None:
        text += f", per bend (noise included) {_pm(per_bend)} %"
    return text


def summary_lines(metrics: dict[str, Any]) -> list[str]:
    """One line per phase: what the demo prints."""
    out = []
    for p in metrics["phases"]:
        contact = (f"with contact up to {p['max_tip_force_n']:.1f} N" if p["contact"]
                   else "without contact")
        rmse = "n/a" if p["rmse_deg"] is None else f"{p['rmse_deg']:.2f} deg"
        force = p.get("tip_force_rmse_n")
        tip = "" if not p["contact"] else (
            "; tip force NaN (not observed by this layout)" if force is None
            else f"; tip force rmse {force:.3f} N")
        out.append(f"{p['rate_hz']:g} Hz {contact} ({p['bends']} bends to "
                   f"{p['peak_deg']:.0f} deg): angle rmse {rmse}, lag "
                   f"{_pm(p['lag_s'], 1e3, 1)} ms, {_hysteresis(p)}{tip}"
                   + (f"; {p['nan_samples']} NaN samples" if p["nan_samples"] else ""))
    return out


def figures(rec: BendRecord, out: Path) -> dict[str, Path]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    paths = {}
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(9, 5.5), sharex=True)
    ax1.plot(rec.t_s, np.degrees(rec.truth_rad), label="true (mock)", lw=1.0)
    ax1.plot(rec.t_s, np.degrees(rec.estimate_rad), label="driver", lw=0.8)
    ax1.set_ylabel("joint angle [deg]")
    ax1.legend(loc="upper right")
    ax2.plot(rec.t_s, np.degrees(rec.estimate_rad - rec.truth_rad), lw=0.6, color="C3",
             label="angle error [deg]")
    ax2.set_ylabel("error [deg]")
    twin = ax2.twinx()
    twin.plot(rec.t_s, rec.tip_force_n, color="C2", lw=0.8)
    twin.set_ylabel("true tip force [N]", color="C2")
    ax2.set_xlabel("time [s]")
    fig.tight_layout()
    paths["bend_angle_time"] = out / "bend_angle_time.png"
    fig.savefig(paths["bend_angle_time"], dpi=110)
    plt.close(fig)
    fig, ax = plt.subplots(figsize=(5, 5))
    contact = rec.tip_force_n > 0.05
    for mask, label in ((~contact, "no contact"), (contact, "tip contact")):
        if mask.any():
            ax.plot(np.degrees(rec.truth_rad[mask]), np.degrees(rec.estimate_rad[mask]), ".",
                    ms=1, label=label)
    top = float(np.nanmax(np.degrees(rec.truth_rad))) if rec.t_s.size else 90.0
    ax.plot([0, top], [0, top], "k--", lw=0.8)
    ax.set_xlabel("true joint angle [deg]")
    ax.set_ylabel("driver's joint angle [deg]")
    ax.legend(loc="upper left", markerscale=8)
    fig.tight_layout()
    paths["bend_angle_scatter"] = out / "bend_angle_scatter.png"
    fig.savefig(paths["bend_angle_scatter"], dpi=110)
    plt.close(fig)
    return paths


def write_report(metrics: dict[str, Any], shown: dict[str, Path], out: Path) -> Path:
    lines = ["# Bend recording", "",
             f"{metrics['modules']} module(s), {metrics['samples']} samples over "
             f"{metrics['duration_s']:.1f} s. Means over the bends of each phase with their "
             "standard error (analysis/bend/metrics.py). The hysteresis is the phase's "
             "averaged cycle (the branches' bin means pooled over its bends) ± a bootstrap "
             "over the bends, beside its noise floor (what noise alone gives) and the mean "
             "of the bends' own figures (noise included).", "",
             "| rate [Hz] | contact | bends | angle RMSE [deg] | lag [ms] | hysteresis [% "
             "of range] | noise floor [%] | per bend, noise included [%] | tip force RMSE "
             "[N] |", "|---|---|---|---|---|---|---|---|---|"]
    for p in metrics["phases"]:
        force = p.get("tip_force_rmse_n")
        contact = f"up to {p['max_tip_force_n']:.1f} N" if p["contact"] else "none"
        rmse = "n/a" if p["rmse_deg"] is None else f"{p['rmse_deg']:.2f}"
        tip = "n/a" if force is None else f"{force:.3f}"
        floor = p["hysteresis_pct"].get("noise_floor")
        lines.append(f"| {p['rate_hz']:g} | {contact} | {p['bends']} | {rmse} | "
                     f"{_pm(p['lag_s'], 1e3, 1)} | {_pm(p['hysteresis_pct'])} | "
                     f"{'n/a' if floor is None else f'{floor:.2f}'} | "
                     f"{_pm(p.get('hysteresis_pct_per_bend', {}))} | {tip} |")
    lines += ["", "Goals at 0.5 Hz over 0-90 deg: RMSE <= 2 deg, lag <= 20 ms, hysteresis "
              "<= 3 %; with a tip contact up to 2 N (two modules) RMSE <= 3 deg.", ""]
    lines += [f"![{name}]({path.name})" for name, path in shown.items()]
    md = out / "report.md"
    md.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return md


def run_bend(bag: str | Path, out: Path, draw: bool = True, verbose: bool = True) -> int:
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise AnalysisError(f"cannot create the output directory {out} ({err.strerror}); "
                            "pass a writable --out.") from None
    rec = read_bend(bag, notify=lambda line: print(f"tactile-sensor analyze: {line}",
                                                   file=sys.stderr))
    metrics = bend_metrics(rec)
    if not metrics["phases"]:
        raise AnalysisError("the recording holds no whole bend of the finger (the true angle "
                            "never rises above half its peak and back); record a whole "
                            "protocol.")
    shown = figures(rec, out) if draw else {}
    (out / "metrics.json").write_text(json.dumps(_finite(metrics), indent=2) + "\n",
                                      encoding="utf-8")
    md = write_report(metrics, shown, out)
    if verbose:
        for line in summary_lines(metrics):
            print(f"bend: {line}", file=sys.stderr)
        print(f"bend: report {md}", file=sys.stderr)
    return 0


def _finite(value: Any) -> Any:
    """NaN as null: JSON has no NaN."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_finite(v) for v in value]
    return value
