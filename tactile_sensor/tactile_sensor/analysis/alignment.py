"""Put module output, reference force and stage position on one uniform time grid.

Why uniform: moving averages (noise, smoothing) assume a fixed sample interval. The grid
uses the module's median sample interval, starts on a module sample, and covers the span
all three topics cover; each topic is linearly interpolated by its header stamps.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .bag_reader import Recording, Series
from .errors import SegmentError, TopicError


@dataclass(frozen=True)
class Aligned:
    """Three signals on one grid; t_s counts from start_ns."""

    t_s: np.ndarray
    output_v: np.ndarray
    force_n: np.ndarray
    indentation_m: np.ndarray
    rate_hz: float
    start_ns: int
    force_flipped: bool
    # role ('reading', 'reference', 'position') -> [(start, stop) [s]] where that topic
    # has no message for longer than GAP_FACTOR of its usual interval (interpolated there)
    gaps_s: dict[str, list[tuple[float, float]]] = field(default_factory=dict)


GAP_FACTOR = 20.0  # a stamp step this many times the topic's median step is a gap
MIN_GAP_S = 0.02  # ... and at least this long


def stream_gaps(stamps_ns: np.ndarray, origin_ns: int) -> list[tuple[float, float]]:
    """Intervals [s from origin_ns] in which a topic has no message although it usually
    has many: the recorder or the publisher lost messages there (a starved process)."""
    if stamps_ns.size < 3:
        return []
    steps = np.diff(stamps_ns)
    limit = max(GAP_FACTOR * float(np.median(steps)), MIN_GAP_S * 1e9)
    where = np.flatnonzero(steps > limit)
    return [(float(stamps_ns[i] - origin_ns) * 1e-9, float(stamps_ns[i + 1] - origin_ns) * 1e-9)
            for i in where.tolist()]


def _finite(series: Series, name: str) -> tuple[np.ndarray, np.ndarray]:
    values = series.values[name]
    keep = np.isfinite(values)
    if not np.any(keep):
        raise TopicError(f"topic {series.topic} holds no finite {name} values (an empty "
                         "array or NaN in every message); record a topic that fills it.")
    stamps = series.stamp_ns[keep]
    values = values[keep]
    if stamps.size > 1:  # drop repeated stamps so interpolation sees a function
        unique = np.concatenate(([True], np.diff(stamps) > 0))
        stamps, values = stamps[unique], values[unique]
    return stamps, values


def align(recording: Recording) -> Aligned:
    """Resample reading, reference and position onto the reading's rate where all overlap."""
    reading, reference, position = (recording.series[r]
                                    for r in ("reading", "reference", "position"))
    streams = [_finite(reading, "output_v"), _finite(reference, "force_n"),
               _finite(position, "indentation_m")]
    start = max(int(s[0][0]) for s in streams)
    stop = min(int(s[0][-1]) for s in streams)
    if stop <= start:
        raise SegmentError("the reading, reference and position topics do not overlap in "
                           "time (by header stamps); record them together or check that "
                           "their clocks agree.")
    steps = np.diff(streams[0][0])
    steps = steps[steps > 0]
    if steps.size == 0:
        raise SegmentError(f"topic {reading.topic} has a single time stamp, so no sample "
                           "rate; record more than one reading.")
    dt_ns = float(np.median(steps))
    # start the grid on a module sample, so a uniformly sampled output is not interpolated
    # (interpolating between samples would average its noise away)
    start = int(streams[0][0][np.searchsorted(streams[0][0], start)])
    if stop <= start:
        raise SegmentError("the reading, reference and position topics do not overlap in "
                           "time (by header stamps); record them together or check that "
                           "their clocks agree.")
    n = int((stop - start) // dt_ns) + 1
    if n < 3:
        raise SegmentError("the topics overlap for less than three module samples; "
                           "record the press with all three topics running.")
    t_s = np.arange(n) * (dt_ns * 1e-9)
    resampled = [np.interp(t_s, (stamps - start) * 1e-9, values)
                 for stamps, values in streams]
    output_v, force_n, indentation_m = resampled
    flipped = bool(-np.min(force_n) > np.max(force_n))
    if flipped:
        force_n = -force_n
    span = t_s[-1]
    gaps = {}
    for role, (stamps, _) in zip(("reading", "reference", "position"), streams, strict=True):
        inside = [(max(a, 0.0), min(b, span)) for a, b in stream_gaps(stamps, start)
                  if b > 0.0 and a < span]
        if inside:
            gaps[role] = inside
    return Aligned(t_s=t_s, output_v=output_v, force_n=force_n, indentation_m=indentation_m,
                   rate_hz=1e9 / dt_ns, start_ns=start, force_flipped=flipped, gaps_s=gaps)
