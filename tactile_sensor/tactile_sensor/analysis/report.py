"""The one-page report: measured metrics beside the paper's, and the figures (MD + HTML)."""

from __future__ import annotations

import html
from pathlib import Path
from typing import Any, Protocol

from .uncertainty import ONE_CYCLE


class _HasMetrics(Protocol):
    metrics: dict[str, Any]


def _fmt(value: Any, unit: str = "", digits: int = 3) -> str:
    if value is None:
        return "n/a"
    return f"{value:.{digits}g}{(' ' + unit) if unit else ''}"


def _cycles(n: int | None, noun: str = "cycle") -> str:
    return f"{n} {noun}{'' if n == 1 else 's'}"


def _pm(value: float | None, ci95: float | None, unit: str, n: int | None,
        digits: int = 3, noun: str = "cycle", count: bool = True) -> str:
    """A measured figure with its 95 % interval and (``count``) how many values it rests
    on; one value says it has no estimate, rather than a bare number that looks exact."""
    if value is None:
        return "n/a"
    if ci95 is not None:
        return (f"{value:.{digits}g} ± {_fmt(ci95, unit, 2)} ({_cycles(n, noun)})"
                if n and count else f"{value:.{digits}g} ± {_fmt(ci95, unit, 2)}")
    if n == 1:
        return f"{_fmt(value, unit, digits)} ({ONE_CYCLE})"
    return f"{_fmt(value, unit, digits)} (no estimate)"


def _cv(mt: dict[str, Any], n: int) -> str:
    ci = mt.get("peak_output_cv_ci95_pct")
    if mt["peak_output_cv_pct"] is None:
        return f"n/a ({ONE_CYCLE})" if n == 1 else "n/a"
    interval = f"95 %: {_fmt(ci[0])}-{_fmt(ci[1], '%')}, " if ci else ""
    return f"{_fmt(mt['peak_output_cv_pct'], '%')} ({interval}{_cycles(n)})"


def _drift(mt: dict[str, Any], n: int) -> str:
    if mt["drift_pct"] is None:
        return f"n/a ({ONE_CYCLE})" if n == 1 else "n/a"
    k = mt["drift_cycles_compared"]
    ci = mt.get("drift_ci95_pct")
    value = (f"{mt['drift_pct']:.3g} ± {_fmt(ci, '%', 2)}" if ci is not None
             else _fmt(mt["drift_pct"], "%"))
    return f"{value} (first {k} vs last {k} of {n} cycles)"


def rows(ch: _HasMetrics) -> list[tuple[str, str, str]]:
    """(metric, measured, paper) rows of the summary table; measured figures carry their
    95 % interval over cycles (metrics.json's *_ci95 keys)."""
    mt, paper = ch.metrics, ch.metrics["paper"]
    get = mt.get
    ref = mt["by_speed"].get(_ref_key(mt), {})
    n = ref.get("cycles")
    sens = _pm(mt["sensitivity_v_per_n"], get("sensitivity_ci95_v_per_n"), "V/N", n)
    if get("sensitivity_se_v_per_n") is not None:
        sens += f"; fit SE {_fmt(get('sensitivity_se_v_per_n'), 'V/N', 2)}"
    out = [
        ("Full scale force", _pm(mt["full_scale_n"], get("full_scale_ci95_n"), "N", n),
         f"~{paper['full_scale_n']:g} N at 3 mm"),
        ("Sensitivity", sens, _fmt(paper["sensitivity_v_per_n"], "V/N")),
        ("Dynamic range", _pm(mt["dynamic_range_db"], get("dynamic_range_ci95_db"), "dB", None,
                              4), _fmt(paper["dynamic_range_db"], "dB", 4)),
        ("Noise (output)", _pm(mt["noise_v"], get("noise_ci95_v"), "V", get("noise_runs"),
                               noun="rest"), "not reported"),
        ("Hysteresis", _pm(mt["hysteresis_pct_fs"], get("hysteresis_ci95_pct_fs"), "% FS", n),
         "low (not quantified)"),
        ("Peak output CV", _cv(mt, n or 0), "no change over 100 cycles"),
        ("Drift (first vs last cycles)", _drift(mt, n or 0), "none observed"),
    ]
    for key in sorted(mt["phase_lag_s"], key=float):
        speed = mt["by_speed"].get(key, {})
        out.append((f"Phase lag at {key} mm/s (onset)",
                    _pm(mt["phase_lag_s"][key], speed.get("phase_lag_ci95_s"), "s",
                        speed.get("phase_lag_cycles", speed.get("cycles"))),
                    _fmt(paper["phase_lag_s"].get(key), "s")))
    cal = mt.get("calibration_error")
    if cal:
        tag = "in-sample" if cal["in_sample"] else "held-out"
        for key in sorted(cal["by_speed"], key=float):
            e = cal["by_speed"][key]
            if e:
                out.append((f"Force error at {key} mm/s ({tag})",
                            f"RMSE {_fmt(e['rmse_pct_fs'])} % FS, max {_fmt(e['max_pct_fs'])} % FS",
                            "not reported"))
        for key in sorted(cal.get("by_speed_phase") or {}, key=float):
            for phase, e in cal["by_speed_phase"][key].items():
                out.append((f"Force RMSE at {key} mm/s, {phase}",
                            f"static {_fmt(e['static_rmse_n'], 'N')}, rate-aware "
                            f"{_fmt(e['rate_rmse_n'], 'N')}", "not reported"))
                if e.get("rate_model_rmse_n") is not None:
                    out.append((f"Force model error at {key} mm/s, {phase} (low-passed)",
                                f"static {_fmt(e['static_model_rmse_n'], 'N')}, rate-aware "
                                f"{_fmt(e['rate_model_rmse_n'], 'N')} (noise removed "
                                f"{_fmt(e['noise_rmse_n'], 'N')})", "not reported"))
        for key in sorted(cal.get("held_out_rmse_n") or {}, key=float):
            out.append((f"Force RMSE at {key} mm/s held out of the rate fit",
                        f"rate-aware {_fmt(cal['held_out_rmse_n'][key], 'N')}, static "
                        f"{_fmt(cal['static_held_out_rmse_n'][key], 'N')}", "not reported"))
    pred = mt.get("prediction")
    out.append(("Model vs measured output (RMSE)",
                _fmt(pred["rmse_v"], "V") if pred else "n/a", "\"agreed well\""))
    return out


def _ref_key(mt: dict[str, Any]) -> str | None:
    ref = mt.get("reference_speed_mm_s")
    return None if ref is None else str(float(ref))


def speed_rows(mt: dict[str, Any]) -> list[tuple[str, ...]]:
    """(speed, cycles, depth, peak force, peak output, sensitivity) per speed: the peaks
    of Fig. 9, each with its 95 % interval over the speed's cycles (the depth says what the
    paper's "7 N at 3 mm" compares with)."""
    out = []
    for key in sorted(mt["by_speed"], key=float):
        s = mt["by_speed"][key]
        n = s["cycles"]
        cells = [_pm(s[name], s.get(ci), unit, n, count=False) for name, ci, unit in (
            ("peak_force_n", "peak_force_ci95_n", "N"),
            ("peak_output_v", "peak_output_ci95_v", "V"),
            ("sensitivity_v_per_n", "sensitivity_ci95_v_per_n", "V/N"))]
        depth = s.get("peak_indentation_m")
        out.append((f"{key} mm/s", str(n), _fmt(None if depth is None else depth * 1e3, "mm"),
                    *cells))
    return out


def speed_lines(mt: dict[str, Any]) -> list[str]:
    """The per-speed table (Markdown); empty without presses."""
    found = speed_rows(mt)
    if not found:
        return []
    return ["", "Peaks at each speed (median over the speed's cycles ± 95 % interval):", "",
            "| speed | cycles | depth | peak force | peak output | sensitivity |",
            "|---|---|---|---|---|---|"] + [f"| {' | '.join(r)} |" for r in found]


def array_fit_lines(fit: dict[str, Any] | None) -> list[str]:
    """The array calibration fitted from the recording: held-out error per component."""
    if not fit:
        return []
    out = ["", f"Array calibration fitted from this recording (calibration.json; degree "
           f"{fit['degree']}, both sides low-passed at {fit['quasi_static_hz']} Hz; every "
           f"{fit['hold_every']}th {fit['block_s']} s block held out, "
           f"{fit['held_out_samples']} of {fit['samples']} samples):", "",
           "| component | held-out RMSE | range | RMSE / range |", "|---|---|---|---|"]
    for name, c in fit["components"].items():
        error = (f"{_fmt(c['rmse'], c['unit'])} | {_fmt(c['range'], c['unit'])} | "
                 f"{_fmt(c['rmse_pct_range'], '%')}" if name in fit["observed"] else
                 f"not excited, left out of observed | {_fmt(c['range'], c['unit'])} | n/a")
        out.append(f"| {name} | {error} |")
    if len(fit["components"]) == 3:
        out.append("| tx, ty, tz | the gauge measures no torque (force-only calibration) | "
                   "n/a | n/a |")
    return out


def array_lines(mt: dict[str, Any]) -> list[str]:
    """The array section (Markdown): force error per axis, sensitivity matrix, cross-talk
    and shear direction; empty for a single module."""
    ar = mt.get("array")
    if not ar:
        return []
    rmse, span, pct = mt["force_rmse_n"], mt["force_range_n"], mt["force_rmse_pct_range"]
    out = ["", "## Module array", "",
           f"{len(ar['faces'])} modules ({', '.join(ar['faces']) or 'no per-module outputs'}); "
           f"detected because {ar['detected_by']}. The driver's wrench on "
           f"{ar['topics']['estimate']} against the gauge on {ar['topics']['reference']}, "
           f"{ar['samples']} samples over {ar['duration_s']} s at {ar['sample_rate_hz']} Hz.",
           "", "| axis | force RMSE | reference range | RMSE / range | goal |",
           "|---|---|---|---|---|"]
    goals = {"x": "<= 10 %", "y": "<= 10 %", "z": "<= 5 %"}
    for a in ("x", "y", "z"):
        out.append(f"| F{a} | {_fmt(rmse[a], 'N')} | {_fmt(span[a], 'N')} | "
                   f"{_fmt(pct[a], '%')} | {goals[a]} |")
    if "torque_rmse_nm" in mt:
        out += ["", "| axis | torque RMSE | reference range | RMSE / range |", "|---|---|---|---|"]
        t_rmse, t_span = mt["torque_rmse_nm"], mt["torque_range_nm"]
        for a in ("x", "y", "z"):
            error = (f"{_fmt(t_rmse[a], 'N m')} | {_fmt(t_span[a], 'N m')} | "
                     f"{_fmt(mt['torque_rmse_pct_range'][a], '%')}")
            if a in ar.get("torque_unobserved_axes", []):
                error = (f"not observed (the driver publishes NaN) | {_fmt(t_span[a], 'N m')} "
                         "| n/a")
            out.append(f"| T{a} | {error} |")
    out += array_fit_lines(mt.get("array_calibration_fit"))
    sens = ar["sensitivity_matrix"]
    if sens:
        out += ["", "Sensitivity matrix S [V/N] (least squares outputs = S F + c over the "
                "recording):", "", "| face | " + " | ".join(f"F{a}" for a in sens["axes"])
                + " | offset | R² |", "|---" * (len(sens["axes"]) + 3) + "|"]
        for face, row, off, r2 in zip(sens["faces"], sens["values_v_per_n"], sens["offset_v"],
                                      sens["r2"], strict=True):
            out.append(f"| {face} | " + " | ".join(_fmt(v) for v in row)
                       + f" | {_fmt(off, 'V')} | {_fmt(r2)} |")
    talk = ar["force_cross_talk"]
    out += ["", "Cross-talk K [N/N] (estimated = K reference + b; ideal: identity):", "",
            "| estimated (rows) / reference (columns) | Fx | Fy | Fz |", "|---|---|---|---|"]
    for a, row in zip(talk["axes"], talk["values"], strict=True):
        out.append(f"| F{a} | " + " | ".join(_fmt(v) for v in row) + " |")
    sd = ar["shear_direction"]
    out += [""]
    if sd:
        out.append(f"Shear direction (where the applied lateral force is at least "
                   f"{_fmt(sd['threshold_n'], 'N')}, {sd['samples']} samples): error RMS "
                   f"{_fmt(sd['rmse_deg'], 'deg')}, median |error| "
                   f"{_fmt(sd['median_abs_deg'], 'deg')}, max {_fmt(sd['max_abs_deg'], 'deg')}.")
    else:
        out.append("Shear direction: no lateral reference force large enough to define one.")
    return out


def write_report(ch: _HasMetrics, figures: dict[str, Path], out_dir: Path
                 ) -> tuple[Path, Path]:
    """report.md and report.html in out_dir, linking the figures by file name."""
    mt = ch.metrics
    title = f"Tactile sensor characterisation: {Path(mt['bag']).name}"
    lines = [f"# {title}", "",
             f"{mt['cycles']} cycles, {mt['duration_s']} s at {mt['sample_rate_hz']} Hz "
             f"({mt['storage']}); reference speed {mt['reference_speed_mm_s']} mm/s. "
             "± is the half-width of a 95 % interval over the cycles (docs/analysis-metrics.md "
             "gives every definition).", "",
             "| metric | measured | paper |", "|---|---|---|"]
    lines += [f"| {a} | {b} | {c} |" for a, b, c in rows(ch)]
    speeds_md = speed_lines(mt)
    lines += speeds_md
    section = array_lines(mt)
    lines += section
    lines += [""] + [f"![{name}]({p.name})" for name, p in figures.items()]
    if mt["notes"]:
        lines += ["", "Notes:"] + [f"- {n}" for n in mt["notes"]]
    md = out_dir / "report.md"
    md.write_text("\n".join(lines) + "\n", encoding="utf-8")

    table = "".join(f"<tr><td>{html.escape(a)}</td><td>{html.escape(b)}</td>"
                    f"<td>{html.escape(c)}</td></tr>" for a, b, c in rows(ch))
    imgs = "".join(f'<img src="{html.escape(p.name)}" alt="{html.escape(n)}">'
                   for n, p in figures.items())
    notes = "".join(f"<li>{html.escape(n)}</li>" for n in mt["notes"])
    speed_html = ("<h2>Peaks at each speed</h2><table><tr><th>speed</th><th>cycles</th>"
                  "<th>depth</th><th>peak force</th><th>peak output</th><th>sensitivity</th></tr>"
                  + "".join("<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in r)
                            + "</tr>" for r in speed_rows(mt)) + "</table>"
                  if speeds_md else "")
    array_html = (f"<h2>Module array</h2><pre>{html.escape(chr(10).join(section[3:]))}</pre>"
                  if section else "")
    page = (f"<!doctype html><html><head><meta charset='utf-8'><title>{html.escape(title)}"
            "</title><style>body{font-family:sans-serif;max-width:1100px;margin:auto}"
            "table{border-collapse:collapse}td,th{border:1px solid #ccc;padding:2px 8px}"
            "img{max-width:49%;margin:2px}</style></head><body>"
            f"<h1>{html.escape(title)}</h1><p>{html.escape(lines[2])}</p>"
            f"<table><tr><th>metric</th><th>measured</th><th>paper</th></tr>{table}</table>"
            f"{speed_html}{array_html}<div>{imgs}</div><ul>{notes}</ul></body></html>\n")
    page_path = out_dir / "report.html"
    page_path.write_text(page, encoding="utf-8")
    return md, page_path
