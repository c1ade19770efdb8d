"""Each servo sample's module output, paired by time stamps once the close is over.

The driver stamps each reading with the host time its ADC sample was taken
(sensing/device_clock.py) and the servo link notes the host time of each servo sample (the
middle of its read; control/servo_link.py). Readings reach the gripper some time after
that, later on a busy machine: a servo sample paired with the outputs *received* since the
one before sees the output of an earlier finger position, so the output seems to rise
after the fingers touched, and the self-check's fit reads a late contact (a stiffer skin
and a brighter emitter than there are). Paired by their stamps, the delivery delay drops
out.

Pure: numbers in, numbers out.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.intp]


def outputs_at(sample_times_s: Sequence[float], stamps_s: Sequence[float],
               outputs_v: Sequence[float]) -> tuple[IntArray, FloatArray]:
    """For each servo sample, the mean of the outputs stamped inside its window: centred on
    the sample, as wide as the nearer of half way to the sample before and half way to the
    sample after (the end windows as wide as their neighbours'). Returns the indices of the
    samples whose window holds a reading, and those means; samples with none (readings lost
    or not yet come) are left out.

    Centred, because the fingers move while the window lasts: a sample the control loop took
    just before a gap (a starved machine once left 0.12-0.38 s between samples) would
    otherwise average the outputs of the next tenths of a second with its own position, and
    the close's output curve would stretch toward the closed fingers."""
    t = np.asarray(sample_times_s, dtype=float)
    stamps = np.asarray(stamps_s, dtype=float)
    outputs = np.asarray(outputs_v, dtype=float)
    if stamps.shape != outputs.shape:
        raise ValueError(f"{stamps.size} stamps for {outputs.size} outputs; they must pair up")
    if t.size == 0 or stamps.size == 0:
        return np.zeros(0, dtype=np.intp), np.zeros(0)
    if np.any(np.diff(t) < 0.0):
        raise ValueError("servo sample times must not decrease")
    middles = 0.5 * (t[1:] + t[:-1])
    first = t[0] - (middles[0] - t[0]) if t.size > 1 else t[0]
    last = t[-1] + (t[-1] - middles[-1]) if t.size > 1 else t[-1]
    half = np.minimum(t - np.concatenate(([first], middles)),
                      np.concatenate((middles, [last])) - t)
    low, high = t - half, t + half
    order = np.argsort(stamps, kind="stable")
    stamps, outputs = stamps[order], outputs[order]
    sums = np.concatenate(([0.0], np.cumsum(outputs)))
    start = np.searchsorted(stamps, low, side="right")
    end = np.searchsorted(stamps, high, side="right")
    if t.size == 1:  # one sample: the readings stamped at its time
        start = np.searchsorted(stamps, low, side="left")
    count = end - start
    kept = np.flatnonzero(count > 0)
    means = (sums[end[kept]] - sums[start[kept]]) / count[kept]
    return kept.astype(np.intp), means
