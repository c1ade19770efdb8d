"""``tactile-sensor model sweep``: the FEM prediction of the module from the command line;
``tactile-sensor model array-calibration``: the grid of load paths that calibrates modules on
several faces for (Fx, Fy, Fz), its fit and the fit's error on held-out points;
``tactile-sensor model study`` (``studies/cli.py``) adds a design study to these commands.

Parameters come from the defaults, then ``--config`` (flat YAML or ROS ``ros__parameters``
form, e.g. ``config/physics.yaml``), then ``--set NAME=VALUE``, then ``--boundary`` and
``--steps``. The sweep is cached like the model node's (same digest, same cache folder), so
the CLI and the node share work.

Exit codes: 0 done, 1 the model failed (a PhysicsError, e.g. no convergence, or an output
file could not be written), 2 bad command line, parameter or config file.
"""

from __future__ import annotations

import argparse
import ctypes
import json
import sys
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NoReturn

import numpy as np

from .errors import PhysicsError
from .params import BOUNDARIES, PhysicsParams
from .prediction import PredictionCurve, compute_curve, load_or_compute_curve
from .yaml_file import read_yaml

PROG = "tactile-sensor model"


class UsageError(Exception):
    """A bad command line, parameter or config file (exit code 2)."""


class _Parser(argparse.ArgumentParser):
    """argparse that raises instead of exiting, so ``main`` owns every exit code."""

    def error(self, message: str) -> NoReturn:
        raise UsageError(f"{message}; see '{self.prog} --help'.")


@dataclass(frozen=True)
class Command:
    """A subcommand: its name, help line, description, options and what it runs (the exit
    code)."""

    name: str
    help: str
    description: str
    options: Callable[[argparse.ArgumentParser], None]
    run: Callable[[argparse.Namespace], int]


def parser(commands: Sequence[Command] | None = None) -> argparse.ArgumentParser:
    """The command line of ``commands`` (default every ``tactile-sensor model`` command)."""
    top = _Parser(prog=PROG, description="Finite-element prediction of the tactile-sensing "
                  "module (skin force, side bulge, photoreflector output).")
    sub = top.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True
    for command in MODEL_COMMANDS if commands is None else commands:
        command.options(sub.add_parser(command.name, help=command.help,
                                       description=command.description))
    return top


def _sweep_options(p: argparse.ArgumentParser) -> None:
    _model_options(p)
    p.add_argument("--boundary", choices=BOUNDARIES,
                   help="'bonded' (paper: base fixed, probe bonded, module present) or "
                        "'frictionless' (verification, no module)")
    p.add_argument("--steps", type=int, metavar="N", help="load steps (overrides 'steps')")
    p.add_argument("--json", type=Path, metavar="PATH",
                   help="write the curve (indentation_m, force_n, bulge_m, distance_m, "
                        "voltage_v, output_v, shear_x_m, shear_y_m, force_x_n, force_y_n "
                        "(the probe's force on the skin along +x, +y; force_n along -z), "
                        "module_bulges_m and module_outputs_v (face -> list), nodes, "
                        "seconds, params) as JSON")
    p.add_argument("--plot", type=Path, metavar="PATH",
                   help="write a PNG: force and output change against indentation")


def _array_calibration_options(a: argparse.ArgumentParser) -> None:
    _model_options(a)
    a.add_argument("--degree", type=int, default=3, metavar="N",
                   help="polynomial degree of the calibration (default 3)")
    a.add_argument("--workers", type=int, default=2, metavar="N",
                   help="load paths solved at once, one process each (default 2)")
    a.add_argument("--json", type=Path, metavar="PATH",
                   help="write the grid, the fit's held-out errors and the calibration")
    a.add_argument("--calibration", type=Path, metavar="PATH",
                   help="write the calibration file the driver loads "
                        "(format tactile_sensor/array_calibration)")
    a.add_argument("--wrench", action="store_true",
                   help="also solve the layout's wrench paths (press, shear, tilt about x "
                        "and y, twist about z; cached) and fit torque columns Tx, Ty, Tz "
                        "[N m]: a six-column calibration (version 2) whose 'observed' lists "
                        "the components the layout resolves at --torque-noise")
    a.add_argument("--torque-noise", type=float, default=None, metavar="V",
                   help="module output noise [V] at the driver's torque bandwidth at which "
                        "the observed components are decided (default the paper's 0.013 V, "
                        "with --wrench)")
    a.add_argument("--plot", type=Path, metavar="PATH",
                   help="write a PNG: calibrated vs FEM force per axis on held-out points, "
                        "module outputs against the shear direction")


def _model_options(p: argparse.ArgumentParser) -> None:
    """Parameter sources, cache and progress: the same for every model command."""
    p.add_argument("--config", type=Path, metavar="FILE",
                   help="YAML physics parameters: a flat NAME: VALUE mapping, or ROS params "
                        "form '<node or /**>: {ros__parameters: {...}}' (e.g. "
                        "config/physics.yaml; names that are not physics parameters are "
                        "ignored there)")
    p.add_argument("--set", dest="sets", action="extend", nargs="+", default=[],
                   metavar="NAME=VALUE",
                   help="override a physics parameter in SI units (m, Pa, ...), e.g. "
                        "--set height=0.025 c01=12180 gap=0.002; known names: "
                        + ", ".join(PhysicsParams.names()))
    p.add_argument("--cache-dir", type=Path, metavar="DIR",
                   help="cache folder (default $XDG_CACHE_HOME/tactile_sensor)")
    p.add_argument("--no-cache", action="store_true",
                   help="always run the FEM sweep and do not store the result")
    p.add_argument("--quiet", action="store_true", help="no progress on stderr")


# -- parameters ------------------------------------------------------------------------------


def _physics_names(section: Mapping[str, Any]) -> dict[str, Any]:
    names = set(PhysicsParams.names())
    return {str(k): v for k, v in section.items() if k in names}


def config_values(path: Path) -> dict[str, Any]:
    """Physics values from a YAML file in flat or ROS params form (not yet validated)."""
    data = read_yaml(path, "the config file", UsageError)
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise UsageError(f"the config file {path} must hold a mapping of physics parameters "
                         "or ROS params sections, not a {type(data).__name__}.")
    ros_sections = [v for v in data.values()
                    if isinstance(v, dict) and "ros__parameters" in v]
    if not ros_sections:
        return {str(k): v for k, v in data.items()}  # flat: unknown names are errors later
    if len(ros_sections) != len(data):
        raise UsageError(f"the config file {path} mixes ROS params sections with other "
                         "top-level keys; use one form.")
    values: dict[str, Any] = {}
    for section in ros_sections:
        params = section["ros__parameters"]
        if params is None:
            continue
        if not isinstance(params, dict):
            raise UsageError(f"a 'ros__parameters' entry in {path} is not a mapping; fix "
                             "the config file.")
        values.update(_physics_names(params))
    return values


def set_values(items: list[str]) -> dict[str, Any]:
    """``NAME=VALUE`` strings -> mapping (values stay strings; PhysicsParams coerces)."""
    names = set(PhysicsParams.names())
    values: dict[str, Any] = {}
    for item in items:
        name, sep, value = item.partition("=")
        name = name.strip()
        if not sep or not name or not value.strip():
            raise UsageError(f"--set expects NAME=VALUE, got {item!r}; e.g. --set "
                             "height=0.025.")
        if name not in names:
            raise UsageError(f"--set names an unknown physics parameter {name!r}; known "
                             f"ones are {', '.join(sorted(names))}.")
        values[name] = value.strip()
    return values


def build_params(args: argparse.Namespace, defaults: Mapping[str, Any] | None = None
                 ) -> PhysicsParams:
    values: dict[str, Any] = dict(defaults or {})
    if args.config is not None:
        values.update(config_values(args.config))
    values.update(set_values(args.sets))
    if getattr(args, "boundary", None) is not None:
        values["boundary"] = args.boundary
    if getattr(args, "steps", None) is not None:
        values["steps"] = args.steps
    try:
        return PhysicsParams.from_mapping(values)
    except PhysicsError as err:
        raise UsageError(str(err)) from None


def _check_output(path: Path | None, option: str) -> None:
    """Fail before a long sweep, not after it, when an output cannot be written there."""
    if path is None:
        return
    if path.is_dir():
        raise UsageError(f"{option} {path} is a directory; pass a file name.")
    if not path.parent.is_dir():
        raise UsageError(f"the folder of {option} {path} does not exist; create it first.")


# -- output ----------------------------------------------------------------------------------


class StderrProgress:
    """Percent and message of a cold sweep on stderr; also tells a cache miss from a hit."""

    def __init__(self, enabled: bool) -> None:
        self.enabled = enabled
        self.called = False

    def __call__(self, fraction: float, message: str) -> None:
        self.called = True
        if self.enabled:
            print(f"[{100 * fraction:5.1f}%] {message}", file=sys.stderr, flush=True)


def write_json(curve: PredictionCurve, params: PhysicsParams, path: Path) -> None:
    data = curve.to_dict()
    data["params"] = _plain(params)
    path.write_text(json.dumps(data, indent=1) + "\n", encoding="utf-8")


def write_plot(curve: PredictionCurve, params: PhysicsParams, path: Path) -> None:
    """Fig. 7(a)/(b) analogue: force and module output change against indentation."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    d_mm = curve.indentation_m * 1e3
    fig, (ax_f, ax_v) = plt.subplots(1, 2, figsize=(10, 4), constrained_layout=True)
    ax_f.plot(d_mm, curve.force_n, "o-", color="tab:red", ms=4)
    ax_f.set(xlabel="indentation [mm]", ylabel="contact force [N]",
             title="(a) force vs indentation")
    ax_v.plot(d_mm, curve.output_v, "o-", color="tab:blue", ms=4)
    ax_v.set(xlabel="indentation [mm]", ylabel="change in module output [V]",
             title="(b) predicted output vs indentation")
    for ax in (ax_f, ax_v):
        ax.grid(True, alpha=0.3)
        ax.set_xlim(left=0.0)
    fig.suptitle(f"FEM prediction ({params.boundary}, {curve.nodes} nodes, "
                 f"{params.pigment_white:g} % white, gap {params.gap * 1e3:g} mm)")
    try:
        fig.savefig(path, dpi=120, format="png")  # PNG whatever the file name says
    finally:
        plt.close(fig)


def summary(curve: PredictionCurve, cache: str) -> str:
    d = curve.max_indentation_m
    force = float(curve.force_n[-1])
    output = float(curve.output_v[-1])
    sensitivity = f"{output / force:.4f} V/N" if force > 0 else "n/a (no force)"
    extra = []
    if np.any(curve.shear_x_m) or np.any(curve.shear_y_m):
        extra.append(f"shear           ({curve.shear_x_m[-1] * 1e3:.3f}, "
                     f"{curve.shear_y_m[-1] * 1e3:.3f}) mm, lateral force "
                     f"({curve.force_x_n[-1]:.3f}, {curve.force_y_n[-1]:.3f}) N")
    if curve.rotates:
        extra.append(f"rotation        ({curve.tilt_x_rad[-1]:.4f}, {curve.tilt_y_rad[-1]:.4f}, "
                     f"{curve.twist_z_rad[-1]:.4f}) rad, torque "
                     f"({curve.torque_x_nm[-1] * 1e3:.3f}, {curve.torque_y_nm[-1] * 1e3:.3f}, "
                     f"{curve.torque_z_nm[-1] * 1e3:.3f}) mN m")
    if len(curve.module_outputs_v) > 1 or extra:
        extra.append("module outputs  " + ", ".join(
            f"{face} {values[-1]:.4f} V" for face, values in curve.module_outputs_v.items()))
    return "\n".join([*extra,
        f"indentation     {d * 1e3:.3f} mm",
        f"force           {force:.3f} N",
        f"bulge           {curve.bulge_m[-1] * 1e3:.4f} mm "
        f"(distance {curve.distance_m[0] * 1e3:.3f} -> {curve.distance_m[-1] * 1e3:.3f} mm)",
        f"output change   {output:.4f} V "
        f"(voltage {curve.voltage_v[0]:.4f} -> {curve.voltage_v[-1]:.4f} V)",
        f"sensitivity     {sensitivity} (output / force at max indentation)",
        f"nodes           {curve.nodes}",
        f"sweep seconds   {curve.seconds:.2f}",
        f"cache           {cache}",
    ])


def sweep(args: argparse.Namespace) -> int:
    params = build_params(args)
    _check_output(args.json, "--json")
    _check_output(args.plot, "--plot")
    progress = StderrProgress(not args.quiet)
    if params.max_indentation <= 0:
        raise UsageError("a sweep runs along the indentation, so it needs max_indentation "
                         "> 0; give one.")
    if args.no_cache:
        curve = compute_curve(params, progress)
        cache = "off (--no-cache)"
    else:
        curve = load_or_compute_curve(params, args.cache_dir, progress)
        cache = f"miss (computed, digest {params.digest()})" if progress.called else \
            f"hit (digest {params.digest()})"
    for path, write in ((args.json, write_json), (args.plot, write_plot)):
        if path is None:
            continue
        try:
            write(curve, params, path)
        except OSError as err:
            raise PhysicsError(f"cannot write {path} ({err.strerror or err}); pass a "
                               "writable path.") from None
    print(summary(curve, cache))
    return 0


def array_calibration(args: argparse.Namespace) -> int:
    from tactile_sensor.sensing.errors import CalibrationError

    from .array_grid import compute_grid, load_or_compute_grid
    from .array_report import OBSERVE_NOISE_V, fit_grid, fit_wrench, wrench_summary
    from .array_report import summary as array_summary
    from .array_report import write_plot as array_plot

    params = build_params(args, {"modules": "front,back,left,right"})
    for path, option in ((args.json, "--json"), (args.plot, "--plot"),
                         (args.calibration, "--calibration")):
        _check_output(path, option)
    if args.degree < 1 or args.workers < 1:
        raise UsageError("--degree and --workers must be at least 1.")
    if args.torque_noise is not None and not (args.wrench and 0 < args.torque_noise <= 1):
        raise UsageError("--torque-noise needs --wrench and a noise in (0, 1] V.")
    progress = StderrProgress(not args.quiet)
    if args.no_cache:
        grid = compute_grid(params, progress, args.workers)
        cache = "off (--no-cache)"
    else:
        grid = load_or_compute_grid(params, args.cache_dir, progress, args.workers)
        cache = (f"miss (computed, digest {params.grid_digest()})" if progress.called else
                 f"hit (digest {params.grid_digest()})")
    wrench_set = _wrench_set(params, args, progress) if args.wrench else None
    try:
        if wrench_set is None:
            calibration, report = fit_grid(grid, args.degree)
        else:
            calibration, report = fit_wrench(grid, wrench_set, args.degree,
                                             observe_noise_v=args.torque_noise
                                             if args.torque_noise is not None
                                             else OBSERVE_NOISE_V)
    except CalibrationError as err:
        raise UsageError(str(err)) from None
    report["source"] = calibration.source
    outputs = {
        args.json: lambda path: path.write_text(json.dumps(
            {"grid": grid.to_dict(), "fit": report, "calibration": calibration.to_dict(),
             "params": _plain(params)}, indent=1) + "\n", encoding="utf-8"),
        args.calibration: lambda path: calibration.to_file(path, fit={
            k: v for k, v in report.items() if k != "estimate_held_out"}),
        args.plot: lambda path: array_plot(grid, report, path),
    }
    for path, write in outputs.items():
        if path is None:
            continue
        try:
            write(path)
        except OSError as err:
            raise PhysicsError(f"cannot write {path} ({err.strerror or err}); pass a "
                               "writable path.") from None
    print(array_summary(report, params, cache))
    if wrench_set is not None:
        print(wrench_summary(report))
    return 0


def _wrench_set(params: Any, args: argparse.Namespace, progress: Any) -> Any:
    """The layout's wrench set: cached, or solved now (and cached) unless --no-cache."""
    from .wrench import compute_wrench_set, load_or_compute_wrench_set

    if args.no_cache:
        return compute_wrench_set(params, progress, args.workers)
    return load_or_compute_wrench_set(params, args.cache_dir, progress, args.workers)


def _plain(params: PhysicsParams) -> dict[str, Any]:
    return {k: list(v) if isinstance(v, tuple) else v for k, v in params.to_dict().items()}


#: The model's own commands; ``studies/cli.py`` adds the design study to them.
MODEL_COMMANDS = (
    Command("sweep",
            help="press the skin from 0 to max_indentation and predict force and output",
            description="Press the skin block from 0 to max_indentation (and, with "
                        "max_shear_x/y, move it sideways) with the FEM model, apply the "
                        "photoreflector optics and report force, bulge and module output (the "
                        "paper's Fig. 7(a)/(b)). Results are cached per parameter digest.",
            options=_sweep_options, run=sweep),
    Command("array-calibration",
            help="FEM grid of shear load paths and the modules' (Fx, Fy, Fz) calibration "
                 "fitted to it",
            description="Solve the array calibration grid (indentation x shear direction x "
                        "shear magnitude, parameters array_*), fit a polynomial from the "
                        "modules' outputs to (Fx, Fy, Fz), and report its error on grid "
                        "points held out of the fit. Four modules (front, back, left, right) "
                        "unless 'modules' is set. The grid is cached per parameter digest.",
            options=_array_calibration_options, run=array_calibration),
)

_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3    # glibc's mallopt parameters


def keep_freed_memory() -> bool:
    """Ask the C library to keep the memory numpy frees for reuse; False if it cannot.

    A sweep allocates and frees arrays of 0.1-14 MB hundreds of times. glibc hands the
    top of its heap back to the kernel once more than twice its (adaptive) mmap threshold
    lies free there, and the next arrays fault it back in page by page: ~55 000 page faults
    per default prediction, 0.3-0.7 s of CPU of a cold 'model sweep' measured side by side
    (4.19/4.24 against 4.91/4.50 s). A 1 GiB trim threshold and a fixed 32 MiB mmap
    threshold keep it. Best effort: another C library just does not get the hint.
    """
    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes = (ctypes.c_int, ctypes.c_int)
    return bool(mallopt(_M_TRIM_THRESHOLD, 1 << 30)) and \
        bool(mallopt(_M_MMAP_THRESHOLD, 32 << 20))


def main(argv: list[str] | None = None, commands: Sequence[Command] | None = None) -> int:
    """Run one of ``commands`` (default the model's own); the exit code of the docstring."""
    commands = MODEL_COMMANDS if commands is None else commands
    started = time.perf_counter()
    try:
        args = parser(commands).parse_args(sys.argv[1:] if argv is None else argv)
    except UsageError as err:
        print(f"{PROG}: {err}", file=sys.stderr)
        return 2
    except SystemExit as exc:  # --help
        return exc.code if isinstance(exc.code, int) else 0
    keep_freed_memory()
    try:
        code = {c.name: c.run for c in commands}[args.command](args)
    except UsageError as err:
        print(f"{PROG} {args.command}: {err}", file=sys.stderr)
        return 2
    except PhysicsError as err:
        print(f"{PROG} {args.command}: {err}", file=sys.stderr)
        return 1
    except KeyboardInterrupt as err:
        why = f"; {err}." if str(err) else "."
        print(f"{PROG} {args.command}: interrupted{why}", file=sys.stderr)
        return 130
    if not args.quiet:
        print(f"done in {time.perf_counter() - started:.1f} s", file=sys.stderr)
    return code


if __name__ == "__main__":
    sys.exit(main())
