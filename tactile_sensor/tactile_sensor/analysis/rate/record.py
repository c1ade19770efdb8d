"""A recording as the rate fit sees it: aligned arrays plus each sample's speed and phase.

Why per-sample labels rather than cycles: the rate terms run over the whole record (the
force at a sample depends on all before it), while the fit scores, and the evaluation
reports, samples by speed and phase (loading, hold, unloading).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import SegmentError
from ..segmentation import Segmentation

OUTSIDE, LOADING, HOLD, UNLOADING = 0, 1, 2, 3
PHASES = {LOADING: "loading", HOLD: "hold", UNLOADING: "unloading"}


@dataclass(frozen=True)
class RateRecord:
    """Equal-length arrays; ``speed_mm_s`` is NaN and ``phase`` OUTSIDE between presses."""

    t_s: np.ndarray
    output_v: np.ndarray
    force_n: np.ndarray
    speed_mm_s: np.ndarray
    phase: np.ndarray

    def __post_init__(self) -> None:
        sizes = {a.shape for a in (self.t_s, self.output_v, self.force_n, self.speed_mm_s,
                                   self.phase)}
        if len(sizes) != 1 or self.t_s.ndim != 1:
            raise SegmentError("time, output, force, speed and phase arrays differ in length; "
                               "build the record from one aligned recording.")
        if self.t_s.size < 3 or np.any(np.diff(self.t_s) <= 0):
            raise SegmentError("the record needs at least 3 samples at increasing times; "
                               "align the recording first.")

    def speeds(self) -> list[float]:
        """The distinct speed labels [mm/s], slowest first."""
        labels = self.speed_mm_s[np.isfinite(self.speed_mm_s)]
        return sorted({float(v) for v in labels.tolist()})

    def mask(self, speeds: list[float] | None = None, phase: int | None = None) -> np.ndarray:
        """Samples inside presses, of these speeds (all when None) and this phase."""
        keep = self.phase != OUTSIDE
        if speeds is not None:
            keep &= np.isin(self.speed_mm_s, speeds)
        if phase is not None:
            keep &= self.phase == phase
        return keep

    def longest_press_s(self) -> float:
        """Duration of the longest run of in-press samples (loading to end of unloading)."""
        inside = np.concatenate(([False], self.phase != OUTSIDE, [False]))
        edges = np.flatnonzero(np.diff(inside.astype(np.int8)))
        starts, stops = edges[::2], edges[1::2] - 1
        if starts.size == 0:
            return 0.0
        return float(np.max(self.t_s[stops] - self.t_s[starts]))


def labels_from_knots(t_s: np.ndarray, knots_t_s: np.ndarray, speeds_m_s: Sequence[float]
                      ) -> tuple[np.ndarray, np.ndarray]:
    """Speed [mm/s] and phase of each sample of a simulated one-press-per-speed run, from
    its profile's corner times (rest, then start, top, hold end, bottom per press): the
    labels a segmentation would give, without its detection error."""
    if knots_t_s.size < 1 + 4 * len(speeds_m_s):
        raise SegmentError(f"{knots_t_s.size} corner times cannot hold {len(speeds_m_s)} "
                           "press(es) of four corners each after a rest.")
    speed = np.full(t_s.shape, np.nan)
    phase = np.full(t_s.shape, OUTSIDE, dtype=np.int8)
    for i, s in enumerate(speeds_m_s):
        start, top, hold_end, bottom = knots_t_s[1 + 4 * i:5 + 4 * i]
        speed[(t_s >= start) & (t_s < bottom)] = s * 1e3
        phase[(t_s >= start) & (t_s < top)] = LOADING
        phase[(t_s >= top) & (t_s < hold_end)] = HOLD
        phase[(t_s >= hold_end) & (t_s < bottom)] = UNLOADING
    return speed, phase


def record_from_segmentation(t_s: np.ndarray, output_v: np.ndarray, force_n: np.ndarray,
                             seg: Segmentation) -> RateRecord:
    """Label each cycle's loading ramp, the hold between its ramps and its unloading ramp
    with the cycle's speed group (e.g. 0.1, 1.0, 10.0 mm/s)."""
    speed = np.full(t_s.shape, np.nan)
    phase = np.zeros(t_s.shape, dtype=np.int8)
    for key, members in seg.speed_groups.items():
        for i in members:
            c = seg.cycles[i]
            speed[c.load[0]:c.unload[1]] = float(key)
            phase[c.load[0]:c.load[1]] = LOADING
            phase[c.load[1]:c.unload[0]] = HOLD
            phase[c.unload[0]:c.unload[1]] = UNLOADING
    return RateRecord(t_s, output_v, force_n, speed, phase)
