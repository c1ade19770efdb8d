"""The topics a bend recording holds, read into one time base: the driver's estimate's."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..bag_reader import TopicSpec, open_reader, read_recording
from ..errors import AnalysisError, SegmentError

ESTIMATE = "/driver/joint_states"
TRUTH = "/bend/joint_states"
TIP_TRUTH = "/bend/tip/wrench"
TIP_ESTIMATE = "/driver/wrench"
READING = "/driver/reading"


@dataclass(frozen=True)
class BendRecord:
    """On the estimate's stamps [s from the first]: true and estimated angle [rad], true
    and estimated tip force [N] (estimate NaN where the driver sent none), and how many
    modules the driver read."""

    t_s: np.ndarray
    truth_rad: np.ndarray
    estimate_rad: np.ndarray
    tip_force_n: np.ndarray
    tip_estimate_n: np.ndarray
    modules: int


def is_bend_recording(path: Path | str) -> bool:
    """Whether the bag holds a finger's joint angle (the driver's and the truth)."""
    try:
        reader = open_reader(Path(path))
    except AnalysisError:  # not readable here: the usual analysis says why
        return False
    try:
        return {ESTIMATE, TRUTH} <= set(reader.topics)
    finally:
        reader.close()


def read_bend(path: Path | str, progress=None, notify=None) -> BendRecord:  # noqa: ANN001
    specs = [
        TopicSpec("estimate", ESTIMATE, {"angle_rad": "position[0]"}, "(bend)", "JointState"),
        TopicSpec("truth", TRUTH, {"angle_rad": "position[0]"}, "(bend)", "JointState"),
        TopicSpec("tip", TIP_TRUTH, {"force_n": "wrench.force.z"}, "(bend)", "WrenchStamped"),
        TopicSpec("tip_estimate", TIP_ESTIMATE, {"force_n": "wrench.force.z"}, "(bend)",
                  "WrenchStamped", required=False),
        TopicSpec("reading", READING, {"output_v": "output"}, "(bend)", "TactileReading",
                  required=False, labels={"faces": "faces"}),
    ]
    rec = read_recording(path, specs, progress, notify)
    est, truth, tip = rec.series["estimate"], rec.series["truth"], rec.series["tip"]
    t0 = max(int(est.stamp_ns[0]), int(truth.stamp_ns[0]))
    t1 = min(int(est.stamp_ns[-1]), int(truth.stamp_ns[-1]))
    keep = (est.stamp_ns >= t0) & (est.stamp_ns <= t1)
    if keep.sum() < 10:
        raise SegmentError(f"the driver's angle ({ESTIMATE}) and the truth ({TRUTH}) do not "
                           "overlap in time; record both in one run (tactile-sensor bringup "
                           "bend --record).")
    stamps = est.stamp_ns[keep]
    t = (stamps - stamps[0]) * 1e-9

    def on_estimate(series, name: str) -> np.ndarray:  # noqa: ANN001
        x = (series.stamp_ns - stamps[0]) * 1e-9
        return np.interp(t, x, series.values[name], left=np.nan, right=np.nan)

    tip_est = np.full(t.size, np.nan)
    if "tip_estimate" in rec.series:
        s = rec.series["tip_estimate"]
        if s.stamp_ns.size:
            tip_est = on_estimate(s, "force_n")
    modules = 1
    if "reading" in rec.series:
        modules = max(1, len(rec.series["reading"].labels.get("faces", [])))
    return BendRecord(t, on_estimate(truth, "angle_rad"), est.values["angle_rad"][keep],
                      on_estimate(tip, "force_n"), tip_est, modules)
