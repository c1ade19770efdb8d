"""The stack benchmark's arithmetic (``benchmarks/bench_stack.py``), pure so it is tested
fast: CPU from /proc counters, the age of a stamped topic, the time the age takes to come
back under a bound after a load stops, samples missing against the ADC's rate, goals, and
the side-by-side table.

Why these definitions:

* CPU is user + system time over a window in cores (1.0 = one core busy), the measure the
  issue's figures use; a thread is labelled with its ``comm`` (Python 3.11 threads keep
  their process's name, so a running number tells same-named threads apart, and the main
  thread is the one whose id is the process's).
* Age = receipt time - header stamp. The recovery after a load is the end of the last
  0.25 s window whose p99 is at or over the bound (an empty window counts as over: no force
  arriving is not a recovered force), so a relapse after a good window still counts; a
  span whose last window is over has not recovered (None).
* The recording's missing samples count against the ADC's period, not the median step:
  a driver that publishes every fourth sample loses three of four to the recording.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

#: The issue's windows: the age's p99 over this long, after the load stops [s].
RECOVERY_WINDOW_S = 0.25
#: "Back under" means under this [s].
RECOVERY_BOUND_S = 0.010


@dataclass(frozen=True)
class Goal:
    """A bound a figure is judged against: ``value op bound``."""

    op: str  # "<=" or ">=" or "<"
    bound: float
    unit: str = ""

    def __post_init__(self) -> None:
        if self.op not in ("<=", ">=", "<"):
            raise ValueError(f"a goal compares with <=, >= or <, not {self.op!r}.")

    @property
    def text(self) -> str:
        return f"{self.op} {self.bound:g}{' ' + self.unit if self.unit else ''}"

    def met(self, value: float | None) -> bool | None:
        """Whether ``value`` meets the goal; None when nothing was measured."""
        if value is None or (isinstance(value, float) and math.isnan(value)):
            return None
        if self.op == "<=":
            return value <= self.bound
        if self.op == "<":
            return value < self.bound
        return value >= self.bound


@dataclass(frozen=True)
class AgeSummary:
    """p50, p99 and max of a topic's age [ms] over ``count`` messages (NaN without any)."""

    p50_ms: float
    p99_ms: float
    max_ms: float
    count: int


def age_summary(ages_s: Sequence[float] | np.ndarray) -> AgeSummary:
    ages = np.asarray(ages_s, dtype=float) * 1e3
    if ages.size == 0:
        return AgeSummary(math.nan, math.nan, math.nan, 0)
    return AgeSummary(float(np.percentile(ages, 50)), float(np.percentile(ages, 99)),
                      float(ages.max()), int(ages.size))


def window_p99(times_s: Sequence[float] | np.ndarray, ages_s: Sequence[float] | np.ndarray,
               start_s: float, span_s: float, width_s: float = RECOVERY_WINDOW_S
               ) -> list[float]:
    """p99 of the ages [s] received in each window [start + k w, start + (k+1) w) of the
    span (NaN for a window that received none); ``times_s``: receipt times [s]."""
    if width_s <= 0 or not math.isfinite(width_s):
        raise ValueError(f"the window must be a positive time, got {width_s!r} s.")
    times, ages = np.asarray(times_s, dtype=float), np.asarray(ages_s, dtype=float)
    if times.shape != ages.shape:
        raise ValueError(f"{times.size} receipt times for {ages.size} ages.")
    count = max(0, math.floor(span_s / width_s + 1e-9))
    out: list[float] = []
    for k in range(count):
        lo = start_s + k * width_s
        inside = ages[(times >= lo) & (times < lo + width_s)]
        out.append(float(np.percentile(inside, 99)) if inside.size else math.nan)
    return out


def recovery_s(times_s: Sequence[float] | np.ndarray, ages_s: Sequence[float] | np.ndarray,
               stop_s: float, span_s: float, width_s: float = RECOVERY_WINDOW_S,
               bound_s: float = RECOVERY_BOUND_S) -> float | None:
    """Seconds after ``stop_s`` (the load stopped) until every later window's p99 is under
    ``bound_s``: the end of the last window at or over it (or empty), 0 when none is.
    None when the span's last window is still over: not recovered within ``span_s``."""
    p99 = window_p99(times_s, ages_s, stop_s, span_s, width_s)
    if not p99:
        return None
    bad = [k for k, p in enumerate(p99) if not p < bound_s]  # NaN (empty) is bad
    if not bad:
        return 0.0
    if bad[-1] == len(p99) - 1:
        return None
    return (bad[-1] + 1) * width_s


@dataclass(frozen=True)
class Loss:
    """A stream's samples inside its recorded window against the device's period."""

    recorded: int
    expected: int

    @property
    def missing(self) -> int:
        return self.expected - self.recorded


def missing_samples(stamps_ns: Sequence[int] | np.ndarray, period_ns: float) -> Loss:
    """Samples missing between the first and the last recorded stamp, each step counted in
    device periods, rounded: exact while a stamp jitters by less than a quarter period (the
    driver stamps device time), and free of the drift a count from the first stamp would
    gather between the device's clock and the nominal rate."""
    if not period_ns > 0:
        raise ValueError(f"the device period must be > 0 ns, got {period_ns!r}.")
    stamps = np.unique(np.asarray(stamps_ns, dtype=np.int64))
    if stamps.size < 2:
        return Loss(int(stamps.size), int(stamps.size))
    periods = np.rint(np.diff(stamps) / period_ns).astype(np.int64)
    return Loss(int(stamps.size), int(1 + np.maximum(periods, 1).sum()))


def task_ticks(stat: str) -> int:
    """utime + stime [clock ticks] of one /proc/<pid>[/task/<tid>]/stat line (the name in
    parentheses may itself hold spaces and parentheses)."""
    fields = stat.rsplit(")", 1)[-1].split()
    if len(fields) < 13:
        raise ValueError(f"not a /proc stat line: {stat[:60]!r}")
    return int(fields[11]) + int(fields[12])


def thread_labels(pid: int, comms: Mapping[int, str]) -> dict[int, str]:
    """A label per thread id: ``main`` for the process's own, else its name, numbered
    (``python3#2``) where several threads share one."""
    counts: dict[str, int] = {}
    for tid in sorted(comms):
        if tid != pid:
            counts[comms[tid]] = counts.get(comms[tid], 0) + 1
    seen: dict[str, int] = {}
    labels: dict[int, str] = {}
    for tid in sorted(comms):
        name = comms[tid]
        if tid == pid:
            labels[tid] = f"main ({name})"
            continue
        seen[name] = seen.get(name, 0) + 1
        labels[tid] = f"{name}#{seen[name]}" if counts[name] > 1 else name
    return labels


def cores(before: Mapping[object, float], after: Mapping[object, float],
          span_s: float) -> dict[object, float]:
    """CPU [cores] of each key over ``span_s`` from two snapshots of CPU seconds; a key
    born inside the window counts from zero, one gone by its end is left out."""
    if not span_s > 0:
        raise ValueError(f"the window must be > 0 s, got {span_s!r}.")
    return {key: max(0.0, (t1 - before.get(key, 0.0)) / span_s)
            for key, t1 in after.items()}


def hold_goal(grasps: int) -> int:
    """Grasps that must hold within 5 %: 18 of 20, the same share of fewer."""
    return math.ceil(0.9 * grasps)


@dataclass(frozen=True)
class Row:
    """One line of the side-by-side table: a figure for each variant, judged where it has
    a goal."""

    name: str
    unit: str
    values: tuple[float | int | str | None, ...]
    goal: Goal | None = None
    digits: int = 3

    def text(self, value: float | int | str | None) -> str:
        if value is None or (isinstance(value, float) and math.isnan(value)):
            return "n/a"
        if isinstance(value, str):
            return value
        if isinstance(value, int) and not isinstance(value, bool):
            body = str(value)
        else:
            body = f"{value:.{self.digits}f}"
        if self.goal is None:
            return body
        return f"{body} {'met' if self.goal.met(float(value)) else 'NOT met'}"


def render_table(columns: Sequence[str], sections: Sequence[tuple[str, Sequence[Row]]]
                 ) -> str:
    """Figures as rows, variants as columns, the goal beside each; a section per way the
    stack ran."""
    for _, rows in sections:
        for row in rows:
            if len(row.values) != len(columns):
                raise ValueError(f"row {row.name!r} has {len(row.values)} values for "
                                 f"{len(columns)} columns.")
    names = [f"{r.name} [{r.unit}]" if r.unit else r.name
             for _, rows in sections for r in rows]
    width = max([len("figure"), *(len(n) + 2 for n in names)])
    goals = [r.goal.text if r.goal else "" for _, rows in sections for r in rows]
    goal_w = max([len("goal"), *map(len, goals)])
    cells = [[r.text(v) for v in r.values] for _, rows in sections for r in rows]
    col_w = [max([len(c), *(len(row[i]) for row in cells)]) for i, c in enumerate(columns)]
    lines = ["  ".join([f"{'figure':{width}s}", f"{'goal':{goal_w}s}",
                        *(f"{c:{w}s}" for c, w in zip(columns, col_w, strict=True))]).rstrip()]
    k = 0
    for title, rows in sections:
        lines.append(title)
        for _ in rows:
            lines.append("  ".join([f"  {names[k]:{width - 2}s}", f"{goals[k]:{goal_w}s}",
                                    *(f"{c:{w}s}" for c, w in zip(cells[k], col_w,
                                                                   strict=True))]).rstrip())
            k += 1
    return "\n".join(lines)
