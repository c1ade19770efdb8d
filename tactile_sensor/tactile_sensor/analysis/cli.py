"""``tactile-sensor analyze BAG --out DIR``: characterise a recording as the paper does.

Exit codes: 0 done, 1 an AnalysisError (one sentence on stderr), 2 bad command line.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from .calibration_fit import load_calibration, save_calibration
from .characterise import Options, Topics, analyse
from .errors import AnalysisError
from .prediction import Prediction, load_prediction_file, physics_prediction


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="tactile-sensor analyze",
        description="Characterise a rosbag2 recording (sqlite3 or MCAP) the way the paper "
                    "does: metrics.json, PNG figures and report.md/.html in --out.")
    p.add_argument("bag", help="rosbag2 directory, or its .db3/.mcap file")
    p.add_argument("--out", required=True, type=Path, help="output directory (created)")
    d = Topics()
    p.add_argument("--reading-topic", default=d.reading,
                   help=f"TactileReading topic, the module output (default {d.reading})")
    p.add_argument("--reference-topic", default=d.reference,
                   help=f"WrenchStamped topic, reference force.z [N] (default {d.reference})")
    p.add_argument("--position-topic", default=d.position,
                   help="JointState topic, indentation position[0] [m], positive into the "
                        f"sensor (default {d.position})")
    p.add_argument("--estimate-topic", default=d.estimate,
                   help="WrenchStamped topic, the driver's force estimate force.x/y/z [N]; "
                        f"read when present, needed for a module array (default {d.estimate})")
    p.add_argument("--reference-speed", type=float, default=1.0, metavar="MM_S",
                   help="speed group used for sensitivity, hysteresis, repeatability, "
                        "full scale and fitting (nearest one; default 1.0 mm/s)")
    p.add_argument("--noise-window", type=int, default=9, metavar="N",
                   help="moving-average length for the noise estimate (default 9, the "
                        "paper's 9-point mean; use 1 if the driver already filters)")
    p.add_argument("--fit-calibration", action="store_true",
                   help="fit output -> force and write OUT/calibration.json (on a module array: "
                        "the array calibration of forces and, where the gauge measures them, "
                        "torques, with held-out errors)")
    p.add_argument("--calibration", type=Path, metavar="FILE",
                   help="evaluate this calibration file (force error per speed)")
    p.add_argument("--prediction", default="auto", metavar="FILE|auto|none",
                   help="model output vs indentation: a 'model sweep --json' file, 'auto' "
                        "(physics layer, default parameters, cached) or 'none'")
    p.add_argument("--no-figures", action="store_true",
                   help="skip the PNG figures (metrics and report only; faster)")
    p.add_argument("--quiet", action="store_true", help="no progress on stderr")
    return p


class _Progress:
    """A percentage on one stderr line (a new line every 10 % if not a tty), for reading
    the bag and for fitting rate terms; ``line`` formats ``pct`` and ``detail``."""

    def __init__(self, enabled: bool, line: str) -> None:
        self.enabled = enabled
        self.line = line
        self.tty = sys.stderr.isatty()
        self.shown = -1

    def __call__(self, fraction: float, detail: str = "") -> None:
        if not self.enabled:
            return
        pct = int(100 * fraction)
        step = 1 if self.tty else 10
        if pct // step == self.shown // step and pct != 100:
            return
        if pct == self.shown:
            return
        self.shown = pct
        end = "" if self.tty and pct < 100 else "\n"
        prefix = "\r\033[K" if self.tty else ""
        print(prefix + self.line.format(pct=pct, detail=detail), end=end, file=sys.stderr,
              flush=True)


def _prediction(arg: str, verbose: bool) -> tuple[Prediction | None, str]:
    if arg == "none":
        return None, "not requested (--prediction none)"
    if arg == "auto":
        return physics_prediction(verbose)
    return load_prediction_file(arg), ""


def run(args: argparse.Namespace) -> int:
    verbose = not args.quiet
    from .bend.record import is_bend_recording

    if is_bend_recording(args.bag):  # a finger's joint angle (configuration 'bend')
        from .bend.report import run_bend

        return run_bend(args.bag, args.out, draw=not args.no_figures, verbose=verbose)
    started = time.perf_counter()
    calibration = load_calibration(args.calibration) if args.calibration else None
    prediction, note = _prediction(args.prediction, verbose)
    if args.noise_window < 1:
        raise AnalysisError("--noise-window must be at least 1 sample; pass e.g. 9.")
    try:
        args.out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise AnalysisError(f"cannot create the output directory {args.out} "
                            f"({err.strerror}); pass a writable --out.") from None
    options = Options(topics=Topics(args.reading_topic, args.reference_topic,
                                    args.position_topic, args.estimate_topic),
                      reference_speed_mm_s=args.reference_speed,
                      noise_window=args.noise_window, calibration=calibration,
                      fit_calibration=args.fit_calibration, prediction=prediction,
                      prediction_note=note,
                      fit_progress=_Progress(verbose, "fitting rate terms: {pct:3d}% ({detail})"))
    result = analyse(args.bag, options, _Progress(verbose, "reading bag: {pct:3d}% of messages"),
                     lambda line: print(f"tactile-sensor analyze: {line}", file=sys.stderr))
    from .report import write_report

    figures = {}
    if not args.no_figures:
        from .plots import all_figures, array_figures  # matplotlib only when drawing

        if result.single is not None:
            figures.update(all_figures(result.single, args.out))
        if result.array is not None:
            figures.update(array_figures(result.array, args.out))
    (args.out / "metrics.json").write_text(json.dumps(result.metrics, indent=2) + "\n",
                                           encoding="utf-8")
    if result.array_fit is not None:  # an array's calibration, not its first module's curve
        result.array_fit.calibration.to_file(args.out / "calibration.json",
                                             result.array_fit.metrics)
        if verbose:
            for line in result.array_fit.lines:
                print(f"tactile-sensor analyze: array calibration {line}", file=sys.stderr)
    elif result.fitted is not None:
        save_calibration(result.fitted, args.out / "calibration.json")
    md, _ = write_report(result, figures, args.out)
    if verbose:
        mt = result.metrics
        array = (f"; array force rmse {mt['force_rmse_n']} N over ranges "
                 f"{mt['force_range_n']} N" if result.array is not None else "")
        print(f"analysed {mt['cycles']} cycles in {time.perf_counter() - started:.1f} s: "
              f"sensitivity {mt['sensitivity_v_per_n']} V/N, dynamic range "
              f"{mt['dynamic_range_db']} dB{array}; report {md}", file=sys.stderr)
    return 0


def main(argv: list[str] | None = None) -> int:
    args = parser().parse_args(sys.argv[1:] if argv is None else argv)
    try:
        return run(args)
    except AnalysisError as err:
        print(f"tactile-sensor analyze: {err}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("tactile-sensor analyze: interrupted.", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
