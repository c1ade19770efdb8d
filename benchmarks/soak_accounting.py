"""The soak benchmark's bookkeeping (``benchmarks/soak.py``), pure so it is tested fast.

Three questions a long run under faults must answer without trusting rates or an idle
machine: when each fault happens (:func:`fault_schedule`), which lost ADC frames the
unplugged windows explain (:func:`account_losses`, from counters the device and the driver
keep by sequence number), and whether a process leaks (:func:`growth_per_hour`, a robust
slope after the warm-up, so start-up allocation is not mistaken for a leak).
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass

#: The faults, in the order the schedule cycles through them.
FAULT_KINDS = ("adc_unplug", "servo_overload", "cpu_burner", "model_restart")
#: Not scheduled: the recorder splits the bag every ``max_bag_duration`` by itself.
SPLIT_KIND = "recording_split"


@dataclass(frozen=True)
class ScheduledFault:
    kind: str
    at_s: float  # since the run's start (after bring-up)
    duration_s: float  # how long the fault is held (unplug, burner); 0 = an event


def fault_schedule(run_s: float, *, warmup_s: float = 10.0, unplug_s: float = 2.0,
                   burner_s: float = 10.0, spacing_s: float = 15.0,
                   settle_s: float = 10.0) -> list[ScheduledFault]:
    """Faults spread evenly over ``run_s`` after ``warmup_s``, cycling :data:`FAULT_KINDS`,
    at least ``spacing_s`` apart, the last one ending ``settle_s`` before the end (so its
    recovery is seen). Raises ``ValueError`` when the run cannot hold one of each kind."""
    for name, value in (("run_s", run_s), ("warmup_s", warmup_s), ("unplug_s", unplug_s),
                        ("burner_s", burner_s), ("spacing_s", spacing_s),
                        ("settle_s", settle_s)):
        if not math.isfinite(value) or value < 0:
            raise ValueError(f"{name} must be a finite time >= 0 s, got {value!r}.")
    held = {"adc_unplug": unplug_s, "cpu_burner": burner_s}
    longest = max(spacing_s, unplug_s, burner_s)
    room = run_s - warmup_s - settle_s - longest
    count = int(room // spacing_s) + 1 if room >= 0 else 0
    if count < len(FAULT_KINDS):
        need = warmup_s + settle_s + longest + (len(FAULT_KINDS) - 1) * spacing_s
        raise ValueError(f"a {run_s:g} s run holds {count} fault(s); one of each of the "
                         f"{len(FAULT_KINDS)} kinds needs at least {need:g} s.")
    step = room / (count - 1)
    kinds = [FAULT_KINDS[i % len(FAULT_KINDS)] for i in range(count)]
    return [ScheduledFault(kind, warmup_s + i * step, held.get(kind, 0.0))
            for i, kind in enumerate(kinds)]


@dataclass(frozen=True)
class LossSnapshot:
    """The driver's cumulative loss counters at ``t_s`` (one /diagnostics message)."""

    t_s: float
    lost: int  # frames missing in the sequence + dropped with a full backlog


@dataclass(frozen=True)
class LossAccount:
    sent: int  # frames the device sent while plugged in
    published: int  # readings the driver published
    lost_total: int  # sent - published
    lost_in_windows: int  # explained by the unplugged windows
    lost_outside: int  # everything else (the goal: 0)


def in_any_window(start_s: float, end_s: float,
                  windows: Sequence[tuple[float, float]]) -> bool:
    """Whether the interval (start_s, end_s] overlaps one of the closed ``windows``."""
    return any(start_s < w_end and end_s >= w_start for w_start, w_end in windows)


def account_losses(sent: int, received: int, published: int,
                   snapshots: Sequence[LossSnapshot],
                   windows: Sequence[tuple[float, float]],
                   link_capacity_frames: int) -> LossAccount:
    """Which of the ``sent - published`` lost frames the unplugged ``windows`` explain.

    ``sent``: frames the device generated while plugged in (its own counter, by sequence);
    ``received``: frames the driver's reader parsed; ``published``: readings the driver
    published. Three places lose frames:

    * the cable pull itself: frames in the device's and the pseudo-terminal's buffers go
      with the cable and the reader never sees their gap (it restarts its sequence on the
      new connection). That is ``sent - received - sequence losses``, explained by the
      windows up to ``link_capacity_frames`` per unplug; beyond that it counts outside;
    * the reader: sequence gaps and a full backlog, cumulative in each snapshot; an increase
      counts in a window when the interval since the previous snapshot overlaps it;
    * between reader and topic (received but not published): always outside.
    """
    if min(sent, received, published, link_capacity_frames) < 0:
        raise ValueError("frame counts must be >= 0.")
    ordered = sorted(snapshots, key=lambda s: s.t_s)
    in_windows = outside = 0
    previous_t, previous_lost = -math.inf, 0
    for snap in ordered:
        increase = snap.lost - previous_lost
        if increase < 0:
            raise ValueError(f"loss counters went backwards at {snap.t_s:g} s "
                             "(a restarted driver?); they must be cumulative.")
        if in_any_window(previous_t, snap.t_s, windows):
            in_windows += increase
        else:
            outside += increase
        previous_t, previous_lost = snap.t_s, snap.lost
    on_link = sent - received - previous_lost
    explained = min(max(on_link, 0), link_capacity_frames * len(windows))
    in_windows += explained
    outside += on_link - explained + (received - published)
    return LossAccount(sent, published, sent - published, in_windows, outside)


def growth_per_hour(samples: Sequence[tuple[float, float]], warmup_s: float) -> float:
    """Growth of a quantity per hour: the Theil-Sen slope (median of pairwise slopes) of the
    samples taken at ``t >= warmup_s``, which one outlier (a GC, a burst) cannot swing.
    NaN with fewer than two samples after the warm-up (too short to say)."""
    kept = sorted((t, v) for t, v in samples if t >= warmup_s)
    slopes = sorted((v2 - v1) / (t2 - t1) for i, (t1, v1) in enumerate(kept)
                    for t2, v2 in kept[i + 1:] if t2 > t1)
    if not slopes:
        return math.nan
    mid = len(slopes) // 2
    median = slopes[mid] if len(slopes) % 2 else 0.5 * (slopes[mid - 1] + slopes[mid])
    return median * 3600.0


@dataclass(frozen=True)
class Goal:
    name: str
    passed: bool
    detail: str


def evaluate_goals(loss: LossAccount, recorded: int, published_during_recording: int,
                   faults_unrecovered: list[str], rss_growth_mb_per_h: dict[str, float],
                   rss_limit_mb_per_h: float = 5.0) -> list[Goal]:
    """PASS/FAIL of each of the soak's goals (NaN growth: too short to judge, counts as a pass
    with that said)."""
    growing = {name: g for name, g in rss_growth_mb_per_h.items() if g >= rss_limit_mb_per_h}
    unknown = sorted(name for name, g in rss_growth_mb_per_h.items() if math.isnan(g))
    worst = max((g for g in rss_growth_mb_per_h.values() if not math.isnan(g)),
                default=math.nan)
    rss_detail = (f"worst {worst:+.2f} MB/h (limit {rss_limit_mb_per_h:g})"
                  + (f"; too few samples after warm-up: {', '.join(unknown)}" if unknown else "")
                  + (f"; over: {', '.join(sorted(growing))}" if growing else ""))
    return [
        Goal("readings lost outside unplugged windows = 0", loss.lost_outside == 0,
             f"{loss.lost_outside} lost outside, {loss.lost_in_windows} in the windows"),
        Goal("messages lost by the recorder = 0", recorded >= published_during_recording,
             f"{recorded} recorded of {published_during_recording} published"),
        Goal("every fault recovered without a restart", not faults_unrecovered,
             "all recovered" if not faults_unrecovered else
             "not recovered: " + ", ".join(faults_unrecovered)),
        Goal(f"RSS growth < {rss_limit_mb_per_h:g} MB/h", not growing, rss_detail),
    ]


def parse_device_stats(log: str) -> dict[str, int]:
    """The counters of the mock ADC's last ``DeviceStats(...)`` line (it prints one when it
    stops, and for each ``stats`` control command); ``ValueError`` when there is none."""
    found = re.findall(r"DeviceStats\(([^)]*)\)", log)
    if not found:
        raise ValueError("the mock ADC printed no DeviceStats line (did it stop cleanly?).")
    pairs = (item.partition("=") for item in found[-1].split(", "))
    return {key: int(value) for key, _, value in pairs if value.isdigit()}
