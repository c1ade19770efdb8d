"""Where benchmarks keep what they measure: one JSON file per benchmark, written to
``build/benchmarks/results/`` (ignored by git, so a run never changes the checkout it
measures). ``make bench-publish`` copies the results of a clean commit into the committed
``benchmarks/results/``, so that the next change compares with this one and
``make bench-report`` renders every figure with the command, commit, machine and date.

A figure is a name, a value, its unit and, where one exists, the goal it is judged
against. A benchmark that runs a workflow also keeps the series the workflow's own plot is
drawn from (``series``: columns of equal length, decimated to at most ``SERIES_POINTS``
rows), so the docs draw that plot from the committed result (``benchmarks/docs_figures.py``).
Absolute times carry from one machine to another poorly, so each file names the machine
(cores, CPU model) it was measured on.
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import json
import math
import os
import platform
import shlex
import subprocess
import sys
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: Where a run writes: outside the tracked tree.
RESULTS = ROOT / "build" / "benchmarks" / "results"
#: The committed figures the page shows; only ``make bench-publish`` writes here.
PUBLISHED = ROOT / "benchmarks" / "results"
DIRTY = "-dirty"
#: The most rows a kept series has: enough for a page's figure, small enough for git.
SERIES_POINTS = 1_000
#: Significant digits a kept series value has: finer than any figure draws.
SERIES_DIGITS = 5


@dataclass(frozen=True)
class Figure:
    """One measured number: ``value`` in ``unit``, with the goal it answers, if any, and
    whether this run met it (``None``: no goal, or not judged)."""

    name: str
    value: float | int | str | None
    unit: str = ""
    goal: str = ""
    met: bool | None = None


class ResultsError(ValueError):
    """A results file that is not what ``write_results`` writes."""


FIELDS = {"benchmark": str, "command": str, "commit": str, "date": str, "machine": dict,
          "figures": list}


#: A benchmark's exit status when this installation cannot run it (automake's "skipped"):
#: ``make bench`` goes on with the others and says which it skipped.
CANNOT_RUN_HERE = 77


def without_ros2(benchmark: str, instead: str = "") -> int | None:
    """``CANNOT_RUN_HERE``, after one sentence saying why, where ``ros2`` is not on PATH
    (the PyPI-wheels setup has no ``ros2 launch``); None where it is."""
    import shutil

    if shutil.which("ros2") is not None:
        return None
    print(f"{benchmark} needs `ros2 launch`, which the PyPI-wheels setup lacks; run it where a "
          f"ROS 2 installation is sourced{instead}.", file=sys.stderr)
    return CANNOT_RUN_HERE


def read_results(path: Path) -> dict[str, object]:
    """One results file, checked: a hand-edited or truncated file names itself and the fix
    instead of failing somewhere in the page it would feed."""
    fix = f"rerun the benchmark that writes it or delete {path}"
    try:
        record = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError) as exc:
        raise ResultsError(f"{path} cannot be read ({exc.__class__.__name__}); {fix}.") from None
    except json.JSONDecodeError as exc:
        raise ResultsError(f"{path} is not valid JSON (line {exc.lineno}: {exc.msg}); "
                           f"{fix}.") from None
    if not isinstance(record, dict):
        raise ResultsError(f"{path} holds a JSON {type(record).__name__}, not a benchmark "
                           f"result; {fix}.")
    for key, kind in FIELDS.items():
        if not isinstance(record.get(key), kind):
            raise ResultsError(f"{path} lacks the {kind.__name__} field '{key}' of a benchmark "
                               f"result; {fix}.")
    for k, figure in enumerate(record["figures"]):  # type: ignore[arg-type]
        if not (isinstance(figure, dict) and isinstance(figure.get("name"), str)
                and "value" in figure):
            raise ResultsError(f"{path}: figure {k + 1} has no 'name' and 'value'; {fix}.")
    return record


def machine() -> dict[str, object]:
    """Cores and CPU model: absolute figures only compare on the same kind of machine."""
    model = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return {"cores": os.cpu_count(), "cpu_model": model, "python": platform.python_version(),
            "ros_distro": os.environ.get("DISTRO") or os.environ.get("ROS_DISTRO", "")}


def commit() -> str:
    """The checked-out commit, marked ``-dirty`` when the tree has uncommitted changes."""
    def git(*args: str) -> str:
        return subprocess.run(["git", "-C", str(ROOT), *args], capture_output=True,
                              text=True, check=False).stdout.strip()
    rev = git("rev-parse", "--short", "HEAD") or "unknown"
    return f"{rev}{DIRTY}" if git("status", "--porcelain", "--untracked-files=no") else rev


def measured_clean(record: dict[str, object]) -> bool:
    """Whether a result was measured at a commit (not at uncommitted changes that nobody
    can check out again)."""
    return not str(record["commit"]).endswith(DIRTY)


#: The commit a benchmark started on (this module is imported as it starts): a run of
#: minutes may end after HEAD moved on.
STARTED_ON = commit()


def write_results(name: str, figures: list[Figure], *, notes: str = "",
                  argv: list[str] | None = None, directory: Path | None = None,
                  series: dict[str, Sequence[object]] | None = None) -> Path:
    """Write ``<name>.json`` to ``directory`` (default ``build/benchmarks/results/``,
    replacing the last run's), say where, and return it. ``series`` (columns of equal
    length, numpy arrays or lists) is kept decimated."""
    argv = sys.argv if argv is None else argv
    script = Path(argv[0])
    with contextlib.suppress(ValueError):
        script = script.resolve().relative_to(ROOT)
    record = {
        "benchmark": name,
        "command": shlex.join(["python", str(script), *argv[1:]]),
        "commit": STARTED_ON,
        "date": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        "machine": machine(),
        "notes": notes,
        "figures": [{**asdict(f), "value": _finite(f.value)} for f in figures],
    }
    if series:
        record["series"] = decimated(series)
    out = (directory or RESULTS) / f"{name}.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(record_text(record))
    print(f"figures: {out}", flush=True)
    return out


def _finite(value: object) -> object:
    """A NaN or infinite figure (nothing measured) as ``null``: JSON has no NaN."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def _plain(value: object) -> object:
    """numpy scalars as Python numbers (their ``item()``), anything else as text."""
    item = getattr(value, "item", None)
    return item() if callable(item) else str(value)


def decimated(series: dict[str, Sequence[object]], points: int = SERIES_POINTS
              ) -> dict[str, object]:
    """Every column thinned by one stride to at most ``points`` rows (rows stay aligned),
    as plain lists with NaN as ``null``."""
    rows = max((len(column) for column in series.values()), default=0)
    stride = max(1, -(-rows // points))
    return {name: _finite_rows(column[::stride]) for name, column in series.items()}


def _finite_rows(column: object) -> object:
    """A column (or a row of one) as lists of numbers, a non-finite number as ``null``."""
    tolist = getattr(column, "tolist", None)
    values = tolist() if callable(tolist) else column
    if isinstance(values, (list, tuple)):
        return [_finite_rows(v) for v in values]
    value = _finite(values)
    return float(f"{value:.{SERIES_DIGITS}g}") if isinstance(value, float) else value


def record_text(record: dict[str, object]) -> str:
    """The record as indented JSON, each series column on one line: a figure per line
    diffs well, a thousand rows per column would not."""
    series = record.get("series")
    head = {key: value for key, value in record.items() if key != "series"}
    text = json.dumps(head, indent=2, allow_nan=False, default=_plain)
    if not isinstance(series, dict):
        return text + "\n"
    columns = ",\n".join(f"    {json.dumps(name)}: "
                         f"{json.dumps(values, allow_nan=False, separators=(',', ':'))}"
                         for name, values in series.items())
    return text[:-2] + ',\n  "series": {\n' + columns + "\n  }\n}\n"
