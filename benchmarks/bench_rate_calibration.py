"""Calibration across indentation speeds: static against rate-aware, held out.

Usage (in the sourced workspace, ``DISTRO=jazzy . scripts/env.sh``):
    python benchmarks/bench_rate_calibration.py [--keep DIR] [--speeds speeds:cycles=1,hold=2]
    python benchmarks/bench_rate_calibration.py --reuse DIR   # DIR/speeds and DIR/check

Records the ``speeds`` protocol and ``rate_check`` (0.3, 3, 20 mm/s with 2 s holds)
through ``tactile-sensor bringup bench`` on mock hardware (as ``scripts/demo.sh rate``),
fits the rate-aware calibration on ``speeds`` and scores it on ``rate_check`` against a
static curve fitted on rate_check's own 3 mm/s ramps (in-sample, so the static side is
favoured). Goal, per speed and phase: rate-aware RMSE <= half the static one and <= 1.5 %
of full scale. Printed against two measures: the per-sample RMSE (with the output's white
noise, the same for both estimators) and the model error (the error low-passed at
``analysis.rate.evaluation.MODEL_CUTOFF_HZ``, zero phase); PASS/FAIL for each. Beside them, the
floors on the same recording: the simulation's exact model, with the play's state from the
stage and from the driver's tracker (``analysis/rate/floor.py``; ``bench_rate_floor.py``
gives their spread over noise seeds). Uses ROS domain $ROS_DOMAIN_ID (default 171),
discovery on this machine only.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import yaml

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tactile_sensor"))

from rate_goal import CUTOFF_TEXT, GOAL_TEXT, MODEL_ERROR_TEXT, goal_line, within_goal
from results import Figure, write_results

from tactile_sensor.analysis.characterise import Characterisation, Options, analyse_bag
from tactile_sensor.analysis.rate.evaluation import (
    PhaseError,
    phase_errors,
    phase_table,
)
from tactile_sensor.analysis.rate.fit import RateFit, fit_rate_calibration
from tactile_sensor.analysis.rate.floor import exact_force, stage_play_lag, tracker_play_lag
from tactile_sensor.analysis.rate.grid import tracker_band_v
from tactile_sensor.analysis.rate.record import RateRecord, record_from_segmentation
from tactile_sensor.configurations import config_dir
from tactile_sensor.sim.skin_response import TabulatedSkin


def record(protocol: str, bag: Path) -> float:
    """One bench run on mock hardware into ``bag``; its wall time [s]."""
    start = time.perf_counter()
    subprocess.run(["tactile-sensor", "bringup", "bench", "--protocol", protocol,
                    "--record", str(bag), "--port",
                    f"adc_port=/tmp/tactile_sensor/bench_rate_adc_{os.getpid()}"],
                   check=True)
    return time.perf_counter() - start


def physics_values() -> dict:
    return yaml.safe_load((config_dir() / "physics.yaml").read_text())["/**"]["ros__parameters"]


def true_terms() -> list[tuple[float, float]]:
    """The simulation's (g, tau [s]) from config/physics.yaml."""
    values = physics_values()
    return list(zip(values["prony_g"], values["prony_tau"], strict=True))


def true_half_gap(outputs_v: np.ndarray) -> tuple[float, np.ndarray] | None:
    """(output_play [m], half the loading-minus-unloading relaxed force [N] at each output)
    of the simulation: the mock's output reads the indentation less the play while loading
    and the indentation while unloading, on the FEM curve it serves (cached by the run)."""
    from tactile_sensor.nodes.physics_parameters import physics_from_values
    from tactile_sensor.physics.prediction import load_or_compute_curve

    params = physics_from_values(physics_values())
    try:
        curve = load_or_compute_curve(params)
    except Exception:  # the truth is a report's extra, not the measure
        return None
    d = np.interp(outputs_v, curve.output_v, curve.indentation_m)
    w = params.output_play
    force = np.interp(d + w, curve.indentation_m, curve.force_n) - np.interp(
        d, curve.indentation_m, curve.force_n)
    return w, 0.5 * force


def verdict(ok: bool) -> str:
    return "PASS" if ok else "FAIL"


def print_table(rows: list[PhaseError], full_scale_n: float,
                exact: tuple[list[PhaseError], list[PhaseError]] | None = None
                ) -> tuple[bool, bool]:
    """The per-speed, per-phase table; (every row meets the goal per sample, on the model
    error). ``exact``: the exact model's rows on the same recording (its floors)."""
    print(goal_line(full_scale_n))
    print(f"model error: RMSE of the error {CUTOFF_TEXT} (2nd-order "
          "Butterworth, forwards and backwards); 'noise' is the RMS the low-pass removed from "
          "the rate-aware estimate (the white-noise floor of the per-sample RMSE)")
    if exact is not None:
        print("exact: the simulation's own model (FEM skin inverted, true Prony terms) on this "
              "recording's output, with the play's state from the stage ('stage': what the "
              "noise and the driver's filter leave) or from the driver's direction tracker "
              "('output': what an estimator reading the output alone is left with); model "
              "error and goal (analysis/rate/floor.py)")
    extra = " | exact: stage     output" if exact else ""
    head = (f"{'speed':>6} {'phase':<9} | {'per-sample RMSE [N]':^30} | "
            f"{'model error [N]':^30} | {'noise':>5}" + extra)
    print(head)
    print(f"{'mm/s':>6} {'':<9} | {'static':>7} {'rate':>7} {'rate/st':>7} {'goal':>5} | "
          f"{'static':>7} {'rate':>7} {'rate/st':>7} {'goal':>5} | {'[N]':>5}")
    print("-" * len(head))
    all_sample = all_model = True
    for k, r in enumerate(rows):
        sample_ok, model_ok = r.meets_goal(full_scale_n, False), r.meets_goal(full_scale_n, True)
        all_sample &= sample_ok
        all_model &= model_ok
        floors = ""
        for table in exact or ():
            e = table[k].rate_model_rmse_n
            ok = within_goal(e, r.static_model_rmse_n, full_scale_n)
            floors += f" {e:>5.3f} {verdict(ok):>4}"
        print(f"{r.speed_mm_s:>6.3g} {r.phase:<9} | {r.static_rmse_n:>7.3f} {r.rate_rmse_n:>7.3f} "
              f"{r.rate_rmse_n / r.static_rmse_n:>7.2f} {verdict(sample_ok):>5} | "
              f"{r.static_model_rmse_n:>7.3f} {r.rate_model_rmse_n:>7.3f} "
              f"{r.rate_model_rmse_n / r.static_model_rmse_n:>7.2f} {verdict(model_ok):>5} | "
              f"{r.noise_rmse_n:>5.3f}" + (f" |{floors}" if floors else ""))
    return all_sample, all_model


def exact_rows(check: Characterisation, rec: RateRecord
               ) -> tuple[list[PhaseError], list[PhaseError]] | None:
    """The exact model's rows on the held-out recording, with the play's state from the
    stage and from the driver's tracker; None without the FEM curve."""
    from tactile_sensor.nodes.physics_parameters import physics_from_values
    from tactile_sensor.physics.prediction import load_or_compute_curve

    params = physics_from_values(physics_values())
    try:
        skin = TabulatedSkin.from_prediction_curve(load_or_compute_curve(params))
    except Exception:  # the floor is a report's extra, not the measure
        return None
    sig = check.signals
    lags = (stage_play_lag(params, sig.indentation_m),
            tracker_play_lag(params, sig.t_s, sig.output_v, tracker_band_v(rec)))
    stage, tracked = (exact_force(skin, params, sig.t_s, sig.output_v, lag) for lag in lags)
    return phase_errors(rec, stage, stage), phase_errors(rec, tracked, tracked)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reuse", type=Path, help="score DIR/speeds and DIR/check; record nothing")
    ap.add_argument("--keep", type=Path, help="record into DIR (kept) instead of a temporary one")
    ap.add_argument("--speeds", default="speeds:cycles=1,hold=2",
                    help="the fit's protocol (holds let it tell slow terms apart)")
    ap.add_argument("--terms", type=int, choices=(1, 2, 3),
                    help="fit this many rate terms instead of choosing by held-out error")
    ap.add_argument("--play", choices=("auto", "on", "off"), default="auto",
                    help="play compensation: chosen by held-out error (auto), always, never "
                         "(off: no play term)")
    args = ap.parse_args()
    os.environ.setdefault("ROS_DOMAIN_ID", "171")
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    with tempfile.TemporaryDirectory(prefix="bench_rate_") as tmp:
        run = args.reuse or args.keep or Path(tmp)
        if args.reuse is None:
            run.mkdir(parents=True, exist_ok=True)
            for protocol, name in ((args.speeds, "speeds"), ("rate_check", "check")):
                print(f"recorded {protocol} -> {run / name} in "
                      f"{record(protocol, run / name):.1f} s", flush=True)
        start = time.perf_counter()
        fit_run = analyse_bag(str(run / "speeds"), Options(fit_calibration=True,
                                                           fit_progress=fit_progress))
        fit_s = time.perf_counter() - start
        if fit_run.rate_fit is None or fit_run.fitted is None:
            print("no rate terms fitted:", *fit_run.metrics["notes"], sep="\n  ")
            return 1
        check = analyse_bag(str(run / "check"), Options(calibration=fit_run.fitted))
        fit = fit_run.rate_fit
        if args.terms is not None or args.play != "auto":
            sig = fit_run.signals
            fit = fit_rate_calibration(
                record_from_segmentation(sig.t_s, sig.output_v, sig.force_n,
                                         fit_run.segmentation), "bench", terms=args.terms,
                play={"auto": None, "on": True, "off": False}[args.play], progress=fit_progress)
        return report(fit_run, fit, check, fit_s)


def fit_progress(fraction: float, what: str) -> None:
    """The fit's progress, a line per fit: it takes a minute or more."""
    print(f"fitting {100 * fraction:3.0f} %: {what}", flush=True)


def report(fit_run: Characterisation, fit: RateFit, check: Characterisation, fit_s: float
           ) -> int:
    assert check.static_reference is not None
    print(f"fit on {fit_run.recording.path} in {fit_s:.0f} s (incl. reading): "
          f"{fit.terms} term(s); leave-one-speed-out score (worst phase, 5 Hz) "
          + ", ".join(f"{n}: {c.score_n:.3f} N" for n, c in fit.counts.items()))
    truth = true_terms()
    print(f"{'term':>4} {'fitted g':>9} {'fitted tau [s]':>15} | {'true g':>7} "
          f"{'true tau [s]':>13}")
    for k in range(max(len(truth), fit.terms)):
        mine = (f"{fit.calibration.terms[k].g:>9.4f} {fit.calibration.terms[k].tau_s:>15.4g}"
                if k < fit.terms else f"{'-':>9} {'-':>15}")
        true = f"{truth[k][0]:>7.4f} {truth[k][1]:>13.4g}" if k < len(truth) else ""
        print(f"{k:>4} {mine} | {true}")
    print(f"instant gain 1 + sum g: fitted {fit.calibration.instant_gain:.4f}, true "
          f"{1 + sum(g for g, _ in truth):.4f}")
    play = fit.calibration.play
    other = ", ".join(f"{n}: {c.score_n:.3f} N" for n, c in fit.other_counts.items())
    if play is None:
        print(f"play: none (held out with play: {other or 'not tried'})")
    else:
        print(f"play: band {1e3 * play.band_v:.1f} mV on the output smoothed at "
              f"{play.smoothing_hz:g} Hz; held out without play: {other or 'not tried'}")
        at = np.array([0.1, 0.2, 0.3, 0.4])
        fitted = np.interp(at, fit.calibration.static.output_v, play.half_gap_n)
        truth = true_half_gap(at)
        print(f"{'output [V]':>10} {'fitted half-gap [N]':>20} {'true half-gap [N]':>18}")
        for k, out in enumerate(at.tolist()):
            true = f"{truth[1][k]:>18.3f}" if truth is not None else f"{'-':>18}"
            print(f"{out:>10.2f} {fitted[k]:>20.3f} {true}")
        if truth is not None:
            print(f"(true: output_play {1e3 * truth[0]:.3f} mm on the FEM curve)")
    for note in fit.notes:
        print("note:", note)
    sig = check.signals
    rec = record_from_segmentation(sig.t_s, sig.output_v, sig.force_n, check.segmentation)
    rows = phase_table(rec, check.static_reference, fit.calibration)
    print(f"held out: {check.recording.path} (static curve: its own "
          f"{check.metrics['reference_speed_mm_s']} mm/s ramps)")
    sample_ok, model_ok = print_table(rows, float(check.metrics["full_scale_n"]),
                                      exact_rows(check, rec))
    print(f"goal per-sample RMSE: {verdict(sample_ok)}; goal on the model error: "
          f"{verdict(model_ok)}")
    full_scale_n = float(check.metrics["full_scale_n"])
    goal = GOAL_TEXT
    figures = [Figure("fit (incl. reading)", fit_s, "s"), Figure("rate terms fitted", fit.terms)]
    for r in rows:
        row = f"{r.speed_mm_s:g} mm/s {r.phase}"
        figures += [Figure(f"{row}: static model error", r.static_model_rmse_n, "N"),
                    Figure(f"{row}: rate-aware model error", r.rate_model_rmse_n, "N", goal,
                           bool(r.meets_goal(full_scale_n, True)))]
    figures += [Figure("every row, per-sample RMSE", verdict(sample_ok), "", goal, sample_ok),
                Figure("every row, model error", verdict(model_ok), "", goal, model_ok)]
    series = {"speed_mm_s": [r.speed_mm_s for r in rows], "phase": [r.phase for r in rows],
              "static_model_rmse_n": [r.static_model_rmse_n for r in rows],
              "rate_model_rmse_n": [r.rate_model_rmse_n for r in rows],
              "full_scale_n": [full_scale_n] * len(rows)}
    write_results("rate_calibration", figures, series=series,
                  notes=f"Fitted on {fit_run.recording.path.name}, scored on "
                  f"{check.recording.path.name} against a static curve fitted on "
                  f"its own ramps; full scale {full_scale_n:.3f} N; {MODEL_ERROR_TEXT}.")
    return 0


if __name__ == "__main__":
    sys.exit(main())
