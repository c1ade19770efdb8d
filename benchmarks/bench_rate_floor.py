"""The noise floor of the rate-aware calibration's goal: how often the exact model itself
meets it.

Usage (in the sourced workspace, ``DISTRO=jazzy . scripts/env.sh``):
    python benchmarks/bench_rate_floor.py [--seeds 64] [--fit 4] [--filter savgol]
        [--filter-params '{"window": 40}'] [--plot FILE]

Runs the ``rate_check`` protocol offline through the mock's own pieces
(``analysis/rate/floor.py``: the FEM skin, the physics' Prony terms and output play, the
ADC's 39 mV white noise, drift and 12-bit quantisation, the driver's filter and tare), once
per noise seed, and scores it as ``bench_rate_calibration.py`` scores a recording: model
error (low-passed at ``MODEL_CUTOFF_HZ``) per speed and phase, against a static curve fitted
on the run's own 3 mm/s ramps (each run aligned, segmented and baseline-corrected as the
analysis reads a bag); goal: rate-aware <= ``GOAL_RATIO`` x static and
<= ``GOAL_SHARE_FS`` of full scale.

- **exact**: the true skin inverted, the play's true state, the true Prony terms; its error
  is what the noise and the filter leave (every seed, fast).
- **exact, output only**: the same, with the play's state from the driver's direction
  tracker, as any estimator reading the output alone must (every seed).
- **fitted** (``--fit N``, the first N seeds, ~1 min each): the rate fit on a simulated
  ``speeds:cycles=1,hold=2`` run with its own noise, as ``make demo-rate`` fits.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import yaml

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tactile_sensor"))

from rate_goal import (
    GOAL_TEXT,
    MODEL_ERROR_TEXT,
    RATIO_TEXT,
    SHARE_TEXT,
    goal_line,
    limit_n,
    ratio_bound_n,
)
from results import Figure, write_results

from tactile_sensor.analysis.calibration_fit import Calibration, fit_calibration
from tactile_sensor.analysis.errors import RateFitError
from tactile_sensor.analysis.rate.evaluation import (
    PhaseError,
    phase_errors,
    phase_table,
)
from tactile_sensor.analysis.rate.fit import fit_rate_calibration
from tactile_sensor.analysis.rate.floor import OfflineRun, bench_world, simulate_run
from tactile_sensor.analysis.rate.history import static_force
from tactile_sensor.analysis.rate.record import LOADING, UNLOADING
from tactile_sensor.configurations import config_dir
from tactile_sensor.nodes.physics_parameters import physics_from_values
from tactile_sensor.physics.prediction import load_or_compute_curve
from tactile_sensor.sensing.errors import SensingError
from tactile_sensor.sensing.filters import DEFAULT_FILTER, FILTERS, make_filter
from tactile_sensor.sim.profiles import PROTOCOLS, LoadProfile
from tactile_sensor.sim.skin_response import TabulatedSkin

TRAIN_SEED_OFFSET = 10_000  # the fit's run draws other noise than the run it is scored on


def profile(name: str, **overrides: float) -> LoadProfile:
    return LoadProfile(**{**PROTOCOLS[name], **overrides})


def static_reference(run: OfflineRun) -> Calibration:
    """The static curve: fitted on the run's own reference-speed ramps (3 mm/s)."""
    rec = run.record
    keep = rec.mask([run.reference_mm_s]) & np.isin(rec.phase, (LOADING, UNLOADING))
    return fit_calibration(rec.output_v[keep], rec.force_n[keep], "bench_rate_floor")


def score(rows: list[PhaseError], full_scale_n: float) -> np.ndarray:
    """(rows, 3): model error of rate-aware and static [N], and whether the goal holds."""
    return np.array([(r.rate_model_rmse_n, r.static_model_rmse_n,
                      float(r.meets_goal(full_scale_n, True))) for r in rows])


def summary(label: str, names: list[str], runs: list[np.ndarray]) -> list[Figure]:
    if not runs:
        return []
    a = np.stack(runs)  # (runs, rows, 3)
    print(f"\n{label}: {len(runs)} run(s)")
    print(f"{'row':<19} {'rate-aware [N] median (5-95 %)':>31} {'static [N]':>11} "
          f"{'meets goal':>11}")
    for k, name in enumerate(names):
        lo, med, hi = np.percentile(a[:, k, 0], [5, 50, 95])
        print(f"{name:<19} {med:>13.3f} ({lo:.3f}-{hi:.3f}) {np.median(a[:, k, 1]):>11.3f} "
              f"{int(a[:, k, 2].sum()):>6}/{len(runs)}")
    every = int(np.all(a[:, :, 2] > 0, axis=1).sum())
    print(f"rows meeting the goal: {a[:, :, 2].sum():.0f} of {a[:, :, 2].size} "
          f"({100 * a[:, :, 2].mean():.1f} %); runs meeting it in every row: {every} of "
          f"{len(runs)}")
    return [Figure(f"{label}: rows meeting the goal", 100 * float(a[:, :, 2].mean()),
                   f"% of {a[:, :, 2].size}"),
            Figure(f"{label}: runs meeting it in every row", every, f"of {len(runs)}")]


def plot(path: Path, names: list[str], exact: list[np.ndarray],
         output_only: list[np.ndarray], fitted: list[np.ndarray], limit_n: float) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(10.5, 4.5))
    x = np.arange(len(names))
    for runs, dx, colour, label in ((exact, -0.2, "tab:blue", "exact model"),
                                    (output_only, 0.0, "tab:green", "exact, output only"),
                                    (fitted, 0.2, "tab:orange", "fitted model")):
        if not runs:
            continue
        a = np.stack(runs)
        for k in range(len(names)):
            ax.scatter(np.full(a.shape[0], x[k] + dx), a[:, k, 0], s=8, color=colour, alpha=0.5,
                       label=label if k == 0 else None)
    static = np.median(np.stack(exact)[:, :, 1], axis=0)
    ax.scatter(x, ratio_bound_n(static), marker="_", s=400, color="k",
               label=f"{RATIO_TEXT} (median)")
    ax.axhline(limit_n, color="tab:red", ls="--", label=SHARE_TEXT)
    ax.set_xticks(x, names, rotation=30, ha="right", rotation_mode="anchor")
    ax.set_ylabel(f"{MODEL_ERROR_TEXT} [N]")
    ax.set_title("Rate check on the mock's noise: exact and fitted models against the goal")
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))  # covers no row
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def arguments() -> argparse.Namespace:
    """The command line, checked (a filter's parameters the driver would refuse end here)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=64, help="noise seeds of the exact model")
    ap.add_argument("--fit", type=int, default=4,
                    help="also fit and score the rate model on the first N seeds (~1 min each)")
    ap.add_argument("--filter", default=DEFAULT_FILTER, choices=tuple(FILTERS),
                    help="the driver's filter_type")
    ap.add_argument("--filter-params", default="{}", type=json.loads,
                    help='the driver\'s filter.* parameters as JSON, e.g. \'{"window": 20}\'')
    ap.add_argument("--plot", type=Path, help="the figure's file (default: a temporary one)")
    args = ap.parse_args()
    if args.seeds < 1 or not 0 <= args.fit <= args.seeds:
        ap.error("--seeds must be >= 1 and --fit between 0 and --seeds.")
    try:
        make_filter(args.filter, 1000.0, args.filter_params)
    except SensingError as exc:
        ap.error(str(exc))
    return args


def main() -> int:
    args = arguments()
    values = yaml.safe_load((config_dir() / "physics.yaml").read_text())["/**"]["ros__parameters"]
    physics = physics_from_values(values)
    skin = TabulatedSkin.from_prediction_curve(load_or_compute_curve(physics))
    check, train = profile("rate_check"), profile("speeds", cycles=1, hold_s=2.0)
    print(f"filter {args.filter} {args.filter_params or '(defaults)'}; Prony "
          f"{list(physics.prony_g)} @ {list(physics.prony_tau)} s; output play "
          f"{1e3 * physics.output_play:.3f} mm", flush=True)

    worlds = {p: bench_world(p, skin, physics) for p in (check, train)}

    def run(p: LoadProfile, seed: int) -> OfflineRun:
        return simulate_run(worlds[p], skin, physics, seed, filter_name=args.filter,
                            filter_params=args.filter_params)

    exact: list[np.ndarray] = []
    output_only: list[np.ndarray] = []
    fitted: list[np.ndarray] = []
    fitted_seeds: list[int] = []
    names: list[str] = []
    full_scale: list[float] = []
    start = time.perf_counter()
    for seed in range(args.seeds):
        held = run(check, seed)
        curve = static_reference(held)
        static_f = static_force(np.asarray(curve.output_v), np.asarray(curve.force_n),
                                held.record.output_v)
        rows = phase_errors(held.record, static_f, held.exact_force_n)
        names = [f"{r.speed_mm_s:g} mm/s {r.phase}" for r in rows]
        exact.append(score(rows, held.full_scale_n))
        output_only.append(score(phase_errors(held.record, static_f, held.output_only_force_n),
                                 held.full_scale_n))
        full_scale.append(held.full_scale_n)
        if seed < args.fit:
            t0 = time.perf_counter()
            try:
                fit = fit_rate_calibration(run(train, TRAIN_SEED_OFFSET + seed).record,
                                           "bench_rate_floor")
            except RateFitError as exc:
                print(f"seed {seed}: no fit ({exc})", flush=True)
                continue
            rows_fit = phase_table(held.record, curve, fit.calibration)
            fitted.append(score(rows_fit, held.full_scale_n))
            fitted_seeds.append(seed)
            print(f"seed {seed}: fitted {fit.calibration.describe()} in "
                  f"{time.perf_counter() - t0:.0f} s; rows met {int(fitted[-1][:, 2].sum())}/9 "
                  f"(exact {int(exact[-1][:, 2].sum())}/9)", flush=True)
        elif (seed + 1) % 16 == 0:
            print(f"exact model: {seed + 1}/{args.seeds} runs "
                  f"({time.perf_counter() - start:.0f} s)", flush=True)
    limit = limit_n(float(np.median(full_scale)))
    print("\n" + goal_line(float(np.median(full_scale))))
    figures = summary("exact model (noise and filter only)", names, exact)
    figures += summary("exact model, play state from the output (the driver's tracker)", names,
                       output_only)
    figures += summary("fitted model", names, fitted)
    if fitted:
        same = np.stack([exact[k] for k in fitted_seeds])
        alone = np.stack([output_only[k] for k in fitted_seeds])
        print(f"on the same {len(fitted)} run(s), rows met: exact {same[:, :, 2].sum():.0f}, "
              f"exact from the output {alone[:, :, 2].sum():.0f}, fitted "
              f"{np.stack(fitted)[:, :, 2].sum():.0f} of {same[:, :, 2].size}")
    path = args.plot or Path(tempfile.mkdtemp(prefix="bench_rate_floor_")) / "floor.png"
    plot(path, names, exact, output_only, fitted, limit)
    print(f"figure: {path}")
    write_results("rate_floor", figures, notes=f"{args.seeds} noise seeds of rate_check "
                  f"offline, {len(fitted)} fitted; filter {args.filter}; goal per row: "
                  f"rate-aware model error {GOAL_TEXT} ({limit:.3f} N).")
    return 0


if __name__ == "__main__":
    sys.exit(main())
