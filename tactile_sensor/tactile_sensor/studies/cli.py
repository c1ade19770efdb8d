"""``tactile-sensor model study``: a design study over a space of parameters, run on Dask.

The study command joins the model's own (``physics/cli.py``: sweep, array-calibration) under
one ``tactile-sensor model``, with the same parameter sources, cache and exit codes; it lives
here because the model must not depend on its studies.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from tactile_sensor.physics.batch import default_workers
from tactile_sensor.physics.cli import (
    MODEL_COMMANDS,
    Command,
    StderrProgress,
    UsageError,
)
from tactile_sensor.physics.cli import main as model_main
from tactile_sensor.physics.errors import PhysicsError


def _study_options(st: argparse.ArgumentParser) -> None:
    st.add_argument("spec", type=Path, metavar="SPEC", help="the study's YAML file")
    st.add_argument("--out", type=Path, required=True, metavar="DIR",
                    help="folder for the results (created if missing)")
    st.add_argument("--scheduler", metavar="ADDRESS",
                    help="address of a running Dask scheduler, e.g. tcp://10.0.0.5:8786 "
                         "(start one with 'dask scheduler' and 'dask worker'); default: a "
                         "local cluster of --workers processes")
    st.add_argument("--workers", type=int, metavar="N",
                    help="local worker processes, one design each at a time (default: the "
                         "cores, here " + str(default_workers()) + "); 1 solves in this process")
    st.add_argument("--cache-dir", type=Path, metavar="DIR",
                    help="cache folder (default $XDG_CACHE_HOME/tactile_sensor, shared with "
                         "'model sweep' and 'model array-calibration')")
    st.add_argument("--quiet", action="store_true", help="no progress on stderr")


def study(args: argparse.Namespace) -> int:
    from tactile_sensor.physics.yaml_file import read_yaml

    from .bend_placement import is_bend_spec
    from .report import fmt_metric, pareto_rows, write_results
    from .run import run_study
    from .spec import StudySpecError, load_spec

    try:
        if is_bend_spec(read_yaml(args.spec, "the study spec", StudySpecError, "")):
            return _bend_study(args)
        spec = load_spec(args.spec)
    except StudySpecError as err:
        raise UsageError(str(err)) from None
    if args.workers is not None and args.workers < 1:
        raise UsageError("--workers must be at least 1.")
    if args.scheduler is not None and args.workers is not None:
        raise UsageError("--workers sizes the local cluster and --scheduler names your own; "
                         "give one of them.")
    if args.out.exists() and not args.out.is_dir():
        raise UsageError(f"--out {args.out} is a file; pass a folder.")
    try:
        args.out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise UsageError(f"cannot create --out {args.out} ({err.strerror}); pass a writable "
                         "folder.") from None
    started = time.perf_counter()
    progress = StderrProgress(not args.quiet)
    try:
        rows = run_study(spec, scheduler=args.scheduler, workers=args.workers,
                         cache_dir=args.cache_dir, progress=progress)
    except KeyboardInterrupt:
        raise KeyboardInterrupt("the finished designs are cached; rerun the same command "
                                "to resume") from None
    seconds = time.perf_counter() - started
    try:
        paths = write_results(rows, spec, args.out, seconds)
    except OSError as err:
        raise PhysicsError(f"cannot write the results to {args.out} "
                           f"({err.strerror or err}); pass a writable folder.") from None
    solved = sum(r.ok for r in rows)
    lines = [f"study           {spec.name}",
             f"designs         {len(rows)} ({solved} solved, {len(rows) - solved} failed), "
             f"{seconds:.1f} s"]
    if rows[0].ok:
        lines.append("paper's design  " + ", ".join(
            f"{c} {fmt_metric(c, rows[0].metrics[c])}" for c in spec.objectives))
    front = pareto_rows(rows, spec)
    lines.append(f"pareto          {len(front)} designs: "
                 + ", ".join(r.design for r in front))
    lines += [f"{p.name:<15} {p}" for p in paths.values()]
    print("\n".join(lines))
    return 0


def _bend_study(args: argparse.Namespace) -> int:
    """A placement study of the bending finger's joint module (``kind: bend_placement``)."""
    from .bend_placement import load_bend_spec, run_bend_study, write_bend_results

    spec = load_bend_spec(args.spec)
    started = time.perf_counter()
    rows = run_bend_study(spec, scheduler=args.scheduler, workers=args.workers or 1,
                          cache_dir=args.cache_dir, progress=StderrProgress(not args.quiet))
    paths = write_bend_results(rows, spec, args.out)
    lines = [f"study           {spec.name}",
             f"designs         {len(rows)} ({sum(not r.error for r in rows)} solved), "
             f"{time.perf_counter() - started:.1f} s"]
    for r in rows:
        m = r.metrics
        lines.append(f"{r.module.label:<32} " + (r.error or (
            f"{m['sensitivity_v_per_rad']:.3f} V/rad, cond {m['jacobian_condition']:.1f}, "
            f"angle std {m['angle_sigma_deg']:.2f} deg, one module under contact "
            f"{m['one_module_contact_error_deg']:.0f} deg")))
    lines += [f"{p.name:<15} {p}" for p in paths.values()]
    print("\n".join(lines))
    return 0


#: Every ``tactile-sensor model`` command: the model's, then the design study.
COMMANDS = (*MODEL_COMMANDS, Command(
    "study", help="a design and placement study: the FEM over a design space, on Dask",
    description="Solve every design of SPEC (YAML: parameters to vary as lists or ranges "
                "{from, to, count}, a grid or a seeded Sobol/Halton sample, fixed parameters, "
                "metrics; see config/studies/) as Dask tasks, measure each (sensitivity "
                "[V/N], full-scale force [N], non-linearity [%% FS], dynamic range [dB]; with "
                "several modules the sensitivity matrix over Fx, Fy, Fz, its singular values, "
                "condition number and cross-talk) and write results.csv, summary.json (Pareto "
                "designs), pareto.png, metrics.png and report.md to --out. Each design is "
                "cached: a rerun or a widened study solves only new designs; Ctrl-C keeps the "
                "finished ones.",
    options=_study_options, run=study))


def main(argv: list[str] | None = None) -> int:
    """``tactile-sensor model``: every command, exit codes as ``physics/cli.py`` documents."""
    return model_main(argv, COMMANDS)


if __name__ == "__main__":
    sys.exit(main())
