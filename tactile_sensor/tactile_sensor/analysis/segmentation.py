"""Split a recording into press cycles (a loading ramp and an unloading ramp) and speeds.

Why the stage position: it is the commanded motion, free of the sensor's own lag and
noise. A Schmitt trigger at 25 %/75 % of the indentation span finds each press; the
ramps are then trimmed to the part between 1 % and 99 % of that press's travel, so
rests and holds belong to no ramp. Cycles are grouped by loading speed (within 25 %).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .alignment import Aligned
from .errors import SegmentError

MIN_SPAN_M = 1e-5  # presses shallower than 10 µm are not presses
MIN_RAMP_SAMPLES = 5
SPEED_GROUP_RATIO = 1.25
TRAVEL_TRIM = 0.01
GAP_SHARE = 0.05  # a press is left out when its output or force lost more than this share


@dataclass(frozen=True)
class Cycle:
    """One press: sample ranges of its ramps (half-open) and its loading speed."""

    index: int
    load: tuple[int, int]
    unload: tuple[int, int]
    speed_mm_s: float
    unload_speed_mm_s: float
    peak_indentation_m: float

    @property
    def window(self) -> tuple[int, int]:
        return self.load[0], self.unload[1]


@dataclass(frozen=True)
class Segmentation:
    """Cycles, the samples at rest between them, and the cycles grouped by speed."""

    cycles: list[Cycle]
    rest: np.ndarray  # bool per sample: unloaded and outside every cycle
    speed_groups: dict[str, list[int]]  # "1.0" -> indices into cycles, ordered by speed
    reference_key: str
    skipped: int  # presses cut off by the start/end of the recording or too short
    in_position_gaps: int = 0  # presses left out because messages are missing in them


def speed_key(speed_mm_s: float) -> str:
    """'0.1', '1.0', '10.0': two significant figures, as a float string."""
    return str(float(f"{speed_mm_s:.2g}"))


def _schmitt(x: np.ndarray, low: float, high: float) -> np.ndarray:
    """True from each rise above `high` until the next fall below `low` (starts False)."""
    event = np.where(x > high, 1, np.where(x < low, 0, -1))
    idx = np.where(event >= 0, np.arange(x.size), 0)
    np.maximum.accumulate(idx, out=idx)
    state = event[idx]
    state[(idx == 0) & (event[0] < 0)] = 0
    return state == 1


def _speed_mm_s(t_s: np.ndarray, d_m: np.ndarray, lo: int, hi: int) -> float:
    n = hi - lo
    a, b = lo + n // 10, hi - n // 10
    if b - a < 2:
        a, b = lo, hi
    slope = np.polyfit(t_s[a:b], d_m[a:b], 1)[0]
    return abs(float(slope)) * 1e3


def segment(aligned: Aligned, reference_speed_mm_s: float = 1.0,
            position_topic: str = "the position topic") -> Segmentation:
    """Cycles from the indentation signal; SegmentError when there is no usable press."""
    d, t = aligned.indentation_m, aligned.t_s
    lo_d, hi_d = np.percentile(d, [0.5, 99.5])
    span = float(hi_d - lo_d)
    if span < MIN_SPAN_M:
        raise SegmentError(f"the indentation on {position_topic} never changes by more than "
                           f"{MIN_SPAN_M * 1e6:.0f} µm while all topics overlap, so there is "
                           "no press to analyse; record a press or pass the right "
                           "--position-topic.")
    high = _schmitt(d, lo_d + 0.25 * span, lo_d + 0.75 * span)
    edges = np.flatnonzero(np.diff(high.astype(np.int8)))
    ups = [int(i) + 1 for i in edges if not high[i]]
    downs = [int(i) + 1 for i in edges if high[i]]
    cycles: list[Cycle] = []
    skipped = 0
    prev_end = 0
    cut_level = lo_d + 0.1 * span
    head_counted = tail_counted = False
    for k, up in enumerate(ups):
        later = [w for w in downs if w > up]
        if not later:
            skipped += 1
            tail_counted = True
            break
        down = later[0]
        next_up = ups[k + 1] if k + 1 < len(ups) else d.size
        before = d[prev_end:up]
        after = d[down:next_up]
        if before.size == 0 or after.size == 0:
            skipped += 1
            continue
        base_before, base_after = float(before.min()), float(after.min())
        if max(base_before, base_after) > cut_level:
            skipped += 1  # cut off by the recording's start or end
            head_counted |= base_before > cut_level and k == 0
            tail_counted |= base_after > cut_level and k == len(ups) - 1
            prev_end = down
            continue
        (load_start, load_stop), (unload_start, unload_stop), peak = _press_ramps(
            d, prev_end, up, down, next_up)
        if (load_stop - load_start < MIN_RAMP_SAMPLES
                or unload_stop - unload_start < MIN_RAMP_SAMPLES):
            skipped += 1
            prev_end = unload_stop
            continue
        cycles.append(Cycle(
            index=len(cycles), load=(load_start, load_stop), unload=(unload_start, unload_stop),
            speed_mm_s=_speed_mm_s(t, d, load_start, load_stop),
            unload_speed_mm_s=_speed_mm_s(t, d, unload_start, unload_stop),
            peak_indentation_m=peak))
        prev_end = unload_stop
    # a press under way when the recording starts or ends, too short to cross the trigger
    skipped += int(d[0] > cut_level and not head_counted)
    skipped += int(d[-1] > cut_level and not tail_counted)
    kept = [c for c in cycles if not _lost_in_gaps(aligned, t[c.window[0]], t[c.window[1] - 1])]
    in_gaps = len(cycles) - len(kept)
    if in_gaps:
        cycles = [Cycle(i, c.load, c.unload, c.speed_mm_s, c.unload_speed_mm_s,
                        c.peak_indentation_m) for i, c in enumerate(kept)]
    if not cycles:
        raise SegmentError(f"no complete loading and unloading cycle on {position_topic} "
                           "lies inside the span where all topics were recorded (an empty "
                           "segment); record whole presses with all three topics running.")
    rest = _rest_samples(d, cycles, lo_d + 0.02 * span)
    groups = _group_by_speed(cycles)
    ref = min(groups, key=lambda k: abs(np.log10(float(k) / reference_speed_mm_s)))
    return Segmentation(cycles=cycles, rest=rest, speed_groups=groups, reference_key=ref,
                        skipped=skipped, in_position_gaps=in_gaps)


def _press_ramps(d: np.ndarray, prev_end: int, up: int, down: int, next_up: int
                 ) -> tuple[tuple[int, int], tuple[int, int], float]:
    """One press's loading and unloading ramps (half-open) and its peak, trimmed to the
    travel between TRAVEL_TRIM and 1 - TRAVEL_TRIM so that rests and holds belong to
    neither."""
    before, after = d[prev_end:up], d[down:next_up]
    base_before, base_after = float(before.min()), float(after.min())
    peak_i = up + int(np.argmax(d[up:down]))
    peak = float(d[peak_i])
    travel, back = peak - base_before, peak - base_after
    # loading: last sample at base before `up` .. first sample near the peak
    at_base = np.flatnonzero(before <= base_before + TRAVEL_TRIM * travel)
    load_start = prev_end + int(at_base[-1])
    near_peak = np.flatnonzero(d[load_start:peak_i + 1] >= peak - TRAVEL_TRIM * travel)
    load_stop = load_start + int(near_peak[0]) + 1
    # unloading: last sample near the peak .. first sample back at base
    still_high = np.flatnonzero(d[peak_i:down] >= peak - TRAVEL_TRIM * back)
    unload_start = peak_i + int(still_high[-1])
    at_base_after = np.flatnonzero(after <= base_after + TRAVEL_TRIM * back)
    unload_stop = down + int(at_base_after[0]) + 1
    return (load_start, load_stop), (unload_start, unload_stop), peak


def _rest_samples(d: np.ndarray, cycles: list[Cycle], rest_level: float) -> np.ndarray:
    """Samples outside every cycle with the skin unloaded: where baselines and noise are
    read."""
    rest = np.zeros(d.size, dtype=bool)
    edges = [0] + [x for c in cycles for x in c.window] + [d.size]
    for a, b in zip(edges[::2], edges[1::2], strict=True):
        rest[a:b] = True
    return rest & (d <= rest_level)


def _lost_in_gaps(aligned: Aligned, t0: float, t1: float) -> bool:
    """Whether lost messages make a press unusable: any gap in the stage topic (its motion
    there is invented by interpolation), or gaps in the output or force topics covering
    more than GAP_SHARE of it (their values there are straight lines, not measurements)."""
    for role, gaps in aligned.gaps_s.items():
        covered = sum(max(0.0, min(b, t1) - max(a, t0)) for a, b in gaps)
        if covered > (0.0 if role == "position" else GAP_SHARE * (t1 - t0)):
            return True
    return False


def _group_by_speed(cycles: list[Cycle]) -> dict[str, list[int]]:
    order = sorted(range(len(cycles)), key=lambda i: cycles[i].speed_mm_s)
    clusters: list[list[int]] = []
    for i in order:
        if clusters and cycles[i].speed_mm_s <= (
                cycles[clusters[-1][0]].speed_mm_s * SPEED_GROUP_RATIO):
            clusters[-1].append(i)
        else:
            clusters.append([i])
    groups: dict[str, list[int]] = {}
    for members in clusters:
        key = speed_key(float(np.median([cycles[i].speed_mm_s for i in members])))
        groups.setdefault(key, []).extend(sorted(members))
    return groups
