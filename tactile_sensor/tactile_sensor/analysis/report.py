"""The one-page report: measured metrics beside the paper's, and the figures (MD + HTML)."""

from __future__ import annotations

import html
from pathlib import Path
from typing import Any

from .characterise import Characterisation


def _fmt(value: Any, unit: str = "", digits: int = 3) -> str:
    if value is None:
        return "n/a"
    return f"{value:.{digits}g}{(' ' + unit) if unit else ''}"


def rows(ch: Characterisation) -> list[tuple[str, str, str]]:
    """(metric, measured, paper) rows of the summary table."""
    mt, paper = ch.metrics, ch.metrics["paper"]
    out = [
        ("Full scale force", _fmt(mt["full_scale_n"], "N"),
         f"~{paper['full_scale_n']:g} N at 3 mm"),
        ("Sensitivity", _fmt(mt["sensitivity_v_per_n"], "V/N"),
         _fmt(paper["sensitivity_v_per_n"], "V/N")),
        ("Dynamic range", _fmt(mt["dynamic_range_db"], "dB", 4),
         _fmt(paper["dynamic_range_db"], "dB", 4)),
        ("Noise (output)", _fmt(mt["noise_v"], "V"), "not reported"),
        ("Hysteresis", _fmt(mt["hysteresis_pct_fs"], "% FS"), "low (not quantified)"),
        ("Peak output CV", _fmt(mt["peak_output_cv_pct"], "%"), "no change over 100 cycles"),
        ("Drift (first vs last cycles)", _fmt(mt["drift_pct"], "%"), "none observed"),
    ]
    for key in sorted(mt["phase_lag_s"], key=float):
        sem = mt["by_speed"].get(key, {}).get("phase_lag_sem_s")
        out.append((f"Phase lag at {key} mm/s (onset)",
                    _fmt(mt["phase_lag_s"][key], "s")
                    + (f" ± {_fmt(sem, 's')}" if sem is not None else ""),
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
    pred = mt.get("prediction")
    out.append(("Model vs measured output (RMSE)",
                _fmt(pred["rmse_v"], "V") if pred else "n/a", "\"agreed well\""))
    return out


def write_report(ch: Characterisation, figures: dict[str, Path], out_dir: Path
                 ) -> tuple[Path, Path]:
    """report.md and report.html in out_dir, linking the figures by file name."""
    mt = ch.metrics
    title = f"Tactile sensor characterisation: {Path(mt['bag']).name}"
    lines = [f"# {title}", "",
             f"{mt['cycles']} cycles, {mt['duration_s']} s at {mt['sample_rate_hz']} Hz "
             f"({mt['storage']}); reference speed {mt['reference_speed_mm_s']} mm/s. "
             "Definitions: docs/analysis-metrics.md.", "",
             "| metric | measured | paper |", "|---|---|---|"]
    lines += [f"| {a} | {b} | {c} |" for a, b, c in rows(ch)]
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
    page = (f"<!doctype html><html><head><meta charset='utf-8'><title>{html.escape(title)}"
            "</title><style>body{font-family:sans-serif;max-width:1100px;margin:auto}"
            "table{border-collapse:collapse}td,th{border:1px solid #ccc;padding:2px 8px}"
            "img{max-width:49%;margin:2px}</style></head><body>"
            f"<h1>{html.escape(title)}</h1><p>{html.escape(lines[2])}</p>"
            f"<table><tr><th>metric</th><th>measured</th><th>paper</th></tr>{table}</table>"
            f"<div>{imgs}</div><ul>{notes}</ul></body></html>\n")
    page_path = out_dir / "report.html"
    page_path.write_text(page, encoding="utf-8")
    return md, page_path
