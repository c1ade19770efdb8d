"""Module arrays: the driver's force vector against the gauge's (and its torque where both
carry one), and what each module reads per newton along each axis.

Why over the whole recording rather than per press: the shear protocol is a single press
held while the probe sweeps sideways, so there are no repeated ramps to segment; every
aligned sample is a comparison of the estimate with the reference. Forces follow the
project's convention (docs/array.md): +z compression, +x toward the right face, +y toward
the front face, the probe's force on the skin; torques the probe's torque on the skin
(right hand about +x, +y, +z) [N m].
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..bag_reader import Recording, Series
from ..errors import SegmentError, TopicError
from .excursions import excursion_metrics

AXES = ("x", "y", "z")
# an axis is excited (its column of the sensitivity matrix and of the cross-talk can be
# fitted) when the reference force's range along it is at least this share of the largest
AXIS_MIN_FRACTION = 0.02
# the shear direction is compared where the lateral reference force is at least this share
# of its largest magnitude in the recording, and at least SHEAR_MIN_N: below that a
# direction is mostly noise (at zero lateral force it is undefined)
SHEAR_FRACTION = 0.2
SHEAR_MIN_N = 0.05
# our names of a WrenchStamped's torque, read where the type has them (every WrenchStamped)
TORQUE_FIELDS = {f"torque_{a}_nm": f"wrench.torque.{a}" for a in AXES}


@dataclass(frozen=True)
class ArraySignals:
    """The array's signals on one uniform time grid (t_s from start_ns)."""

    t_s: np.ndarray
    estimate_n: np.ndarray  # (n, 3) the driver's wrench force x, y, z [N]
    reference_n: np.ndarray  # (n, 3) the gauge's force x, y, z [N]
    outputs_v: np.ndarray  # (n, k) every module's output [V]; k = 0 if the reading has none
    faces: tuple[str, ...]  # k names
    rate_hz: float
    start_ns: int
    reference_flipped: bool
    # (n, 3) torque x, y, z [N m] when both the driver and the gauge carry torque, else
    # None; a column the driver publishes only as NaN stays NaN
    estimate_torque_nm: np.ndarray | None = None
    reference_torque_nm: np.ndarray | None = None


@dataclass(frozen=True)
class Sensitivity:
    """Least squares outputs = S F + c over the recording (S: faces x axes, V/N)."""

    faces: tuple[str, ...]
    matrix_v_per_n: np.ndarray  # (k, 3); NaN in the columns of axes not excited
    offset_v: np.ndarray  # (k,)
    r2: np.ndarray  # (k,) per face
    excited: np.ndarray  # (3,) bool


@dataclass(frozen=True)
class ShearDirections:
    """Applied (gauge) and estimated (driver) lateral force directions where the applied
    lateral force reaches threshold_n."""

    threshold_n: float
    applied_rad: np.ndarray
    estimated_rad: np.ndarray
    applied_n: np.ndarray  # lateral magnitude, reference
    estimated_n: np.ndarray  # lateral magnitude, estimate
    error_rad: np.ndarray  # estimated - applied, wrapped to (-pi, pi]


@dataclass(frozen=True)
class ArrayAnalysis:
    """Metrics (JSON-ready, merged into metrics.json) and what the plots draw."""

    metrics: dict[str, Any]
    notes: list[str]
    signals: ArraySignals
    rmse_n: np.ndarray  # (3,)
    range_n: np.ndarray  # (3,)
    sensitivity: Sensitivity | None
    cross_talk: np.ndarray  # (3 estimated, 3 reference) N/N; NaN columns where not excited
    shear: ShearDirections | None
    detected_by: str
    torque_rmse_nm: np.ndarray | None = None  # (3,) NaN along unobserved axes
    torque_range_nm: np.ndarray | None = None  # (3,)
    torque_unobserved: tuple[str, ...] = ()  # axes the driver publishes only as NaN


def _lateral(series: Series) -> bool:
    """Whether any message has a finite, non-zero lateral force."""
    return any(np.any(np.isfinite(v) & (v != 0.0))
               for v in (series.values.get("force_x_n"), series.values.get("force_y_n"))
               if v is not None)


def module_count(recording: Recording) -> int:
    """Modules the reading carries per message (0: the single-module message)."""
    outputs = recording.series["reading"].arrays.get("outputs_v")
    return 0 if outputs is None else int(outputs.shape[1])


def detect(recording: Recording) -> str | None:
    """Why this is an array recording, or None for a single module.

    The reading's per-module outputs (filled only with several modules) or lateral force in
    the driver's wrench. Lateral force in the gauge alone is not enough: a three-axis gauge
    on a single module reads lateral noise.
    """
    k = module_count(recording)
    if k >= 2:
        return f"the reading carries {k} modules' outputs"
    estimate = recording.series.get("estimate")
    if estimate is not None and _lateral(estimate):
        return f"the driver's wrench on {estimate.topic} has lateral force"
    return None


def _finite_rows(stamps: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    keep = np.all(np.isfinite(values), axis=1)
    stamps, values = stamps[keep], values[keep]
    if stamps.size > 1:
        unique = np.concatenate(([True], np.diff(stamps) > 0))
        stamps, values = stamps[unique], values[unique]
    return stamps, values


def _vector(series: Series) -> np.ndarray:
    v = series.values
    return np.column_stack([v["force_x_n"], v["force_y_n"], v["force_n"]])


def _torque(series: Series) -> np.ndarray | None:
    """(n, 3) torque x, y, z, or None if the type has no torque fields."""
    if not all(name in series.values for name in TORQUE_FIELDS):
        return None
    return np.column_stack([series.values[name] for name in TORQUE_FIELDS])


def reference_has_torque(series: Series) -> bool:
    """A gauge measures torque when some message has a finite, non-zero one (a force-only
    gauge's WrenchStamped leaves it zero)."""
    torque = _torque(series)
    return torque is not None and bool(np.any(np.isfinite(torque) & (torque != 0.0)))


def estimate_has_torque(series: Series) -> bool:
    """The driver estimates torque when some message has a non-zero one, or a NaN one
    beside a finite force (a component its layout does not observe); a force-only driver
    leaves torque zero."""
    torque = _torque(series)
    if torque is None:
        return False
    forced = np.all(np.isfinite(_vector(series)), axis=1)
    return bool(np.any(np.isfinite(torque) & (torque != 0.0))
                or np.any(np.isnan(torque[forced])))


def _torque_note(recording: Recording) -> tuple[bool, str | None]:
    """Whether to compare torque, and why not when only one side carries it."""
    reference, estimate = recording.series["reference"], recording.series["estimate"]
    measured, estimated = reference_has_torque(reference), estimate_has_torque(estimate)
    if measured and not estimated:
        return False, (f"the gauge on {reference.topic} measures torque but the driver's "
                       f"wrench on {estimate.topic} carries none (zero in every message), so "
                       "no torque is compared.")
    if estimated and not measured:
        return False, (f"the driver's wrench on {estimate.topic} carries torque but the gauge "
                       f"on {reference.topic} measures none (zero or absent in every "
                       "message), so no torque is compared.")
    return measured and estimated, None


def _check_inputs(recording: Recording, reason: str) -> None:
    """The sentences for array recordings a user cannot analyse (exit 1)."""
    if "estimate" not in recording.series:
        problem = recording.absent.get("estimate", "the driver's wrench topic is missing.")
        raise TopicError(f"this is a module array's recording ({reason}), but {problem}")
    reference = recording.series["reference"]
    if "force_x_n" not in reference.values or "force_y_n" not in reference.values:
        raise TopicError(f"this is a module array's recording ({reason}), but the reference "
                         f"topic {reference.topic} ({reference.msgtype}) has no lateral force "
                         "fields wrench.force.x/y; pass --reference-topic naming the "
                         "three-axis gauge's WrenchStamped topic.")
    estimate = recording.series["estimate"]
    applied = float(np.nanmax(np.abs(np.concatenate(
        [reference.values["force_x_n"], reference.values["force_y_n"], [0.0]]))))
    if applied >= SHEAR_MIN_N and not _lateral(estimate):
        raise TopicError(f"the gauge on {reference.topic} measures up to {applied:.3g} N of "
                         f"lateral force, but the driver's wrench on {estimate.topic} has no "
                         "lateral force (force.x and force.y are zero or NaN in every "
                         "message); record the driver running its array calibration "
                         "(parameter modules) or pass --estimate-topic naming the array's "
                         "wrench.")


def _resample_columns(stamps: np.ndarray, values: np.ndarray, start: int, t_s: np.ndarray
                      ) -> np.ndarray:
    """Each column on the grid from its own finite samples; NaN where it has fewer than
    two (a torque component the driver never observes)."""
    out = np.full((t_s.size, values.shape[1]), np.nan)
    for j in range(values.shape[1]):
        x, v = _finite_rows(stamps, values[:, j:j + 1])
        if x.size > 1:
            out[:, j] = np.interp(t_s, (x - start) * 1e-9, v[:, 0])
    return out


def align_array(recording: Recording, torque: bool = False) -> ArraySignals:
    """Resample the modules' outputs, the driver's and the gauge's force vectors onto one
    uniform grid: the reading's median interval, starting on a reading sample, over the
    span all cover (the estimate's stamps when the reading carries no per-module outputs).
    Samples with a NaN (outputs and wrench before the driver's tare) are left out first.
    ``torque``: the driver's and the gauge's torque too, on the same grid, each component
    from its own finite samples."""
    reading = recording.series["reading"]
    estimate = recording.series["estimate"]
    reference = recording.series["reference"]
    outputs = reading.arrays.get("outputs_v", np.empty((reading.stamp_ns.size, 0)))
    faces = tuple(reading.labels.get("faces", []))
    if len(faces) != outputs.shape[1]:
        faces = tuple(f"module{i}" for i in range(outputs.shape[1]))
    streams = [_finite_rows(estimate.stamp_ns, _vector(estimate)),
               _finite_rows(reference.stamp_ns, _vector(reference))]
    if outputs.shape[1]:
        streams.append(_finite_rows(reading.stamp_ns, outputs))
    for (stamps, _), series in zip(streams, (estimate, reference, reading), strict=False):
        if stamps.size < 2:
            raise TopicError(f"topic {series.topic} holds fewer than two samples without NaN; "
                             "record the array after the driver's tare.")
    base = streams[2][0] if outputs.shape[1] else streams[0][0]
    start = max(int(s[0][0]) for s in streams)
    stop = min(int(s[0][-1]) for s in streams)
    steps = np.diff(base)
    dt_ns = float(np.median(steps[steps > 0])) if np.any(steps > 0) else 0.0
    if stop <= start or dt_ns <= 0:
        raise SegmentError(f"the topics {reading.topic}, {estimate.topic} and "
                           f"{reference.topic} do not overlap in time (by header stamps); "
                           "record them together or check that their clocks agree.")
    start = int(base[np.searchsorted(base, start)])
    n = int((stop - start) // dt_ns) + 1 if stop >= start else 0
    if n < 3:
        raise SegmentError("the array's topics overlap for less than three samples; record "
                           "the driver's wrench, the gauge and the reading together.")
    t_s = np.arange(n) * (dt_ns * 1e-9)

    def resample(stamps: np.ndarray, values: np.ndarray) -> np.ndarray:
        x = (stamps - start) * 1e-9
        return np.column_stack([np.interp(t_s, x, values[:, j])
                                for j in range(values.shape[1])]) if values.shape[1] \
            else np.empty((n, 0))

    est, ref = resample(*streams[0]), resample(*streams[1])
    outs = resample(*streams[2]) if outputs.shape[1] else np.empty((n, 0))
    est_t = ref_t = None
    est_raw, ref_raw = _torque(estimate), _torque(reference)
    if torque and est_raw is not None and ref_raw is not None:
        est_t = _resample_columns(estimate.stamp_ns, est_raw, start, t_s)
        ref_t = _resample_columns(reference.stamp_ns, ref_raw, start, t_s)
    flipped = bool(-np.min(ref[:, 2]) > np.max(ref[:, 2]))
    if flipped:  # the skin's wrench on the probe: the whole wrench is the negative
        ref = -ref
        ref_t = None if ref_t is None else -ref_t
    return ArraySignals(t_s=t_s, estimate_n=est, reference_n=ref, outputs_v=outs, faces=faces,
                        rate_hz=1e9 / dt_ns, start_ns=start, reference_flipped=flipped,
                        estimate_torque_nm=est_t, reference_torque_nm=ref_t)


def force_errors(estimate_n: np.ndarray, reference_n: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Per axis: RMSE of estimate - reference, and the reference's range (max - min); NaN
    for an axis whose values are NaN (also used for torque)."""
    rmse = np.sqrt(np.mean((estimate_n - reference_n) ** 2, axis=0))
    span = np.max(reference_n, axis=0) - np.min(reference_n, axis=0)
    return rmse, span


def _pct(rmse: np.ndarray, span: np.ndarray) -> np.ndarray:
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(span > 0, 100 * rmse / span, np.nan)


def excited_axes(reference_n: np.ndarray) -> np.ndarray:
    """Axes whose reference range is at least AXIS_MIN_FRACTION of the largest one."""
    span = np.max(reference_n, axis=0) - np.min(reference_n, axis=0)
    top = float(np.max(span))
    return (span >= AXIS_MIN_FRACTION * top) & (span > 0) if top > 0 else np.zeros(3, bool)


def _fit(design_force: np.ndarray, excited: np.ndarray, y: np.ndarray
         ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """y (n, m) = F[:, excited] B + c; B (3, m) with NaN rows where not excited."""
    a = np.column_stack([design_force[:, excited], np.ones(design_force.shape[0])])
    coef, *_ = np.linalg.lstsq(a, y, rcond=None)
    b = np.full((3, y.shape[1]), np.nan)
    b[excited] = coef[:-1]
    resid = y - a @ coef
    total = np.sum((y - y.mean(axis=0)) ** 2, axis=0)
    with np.errstate(divide="ignore", invalid="ignore"):
        r2 = np.where(total > 0, 1.0 - np.sum(resid ** 2, axis=0) / total, np.nan)
    return b, coef[-1], r2


def sensitivity_matrix(outputs_v: np.ndarray, reference_n: np.ndarray,
                       faces: tuple[str, ...]) -> Sensitivity | None:
    """Outputs per newton along each axis: least squares outputs = S F + c (S faces x axes)
    over the excited axes; None without per-module outputs or any excited axis."""
    excited = excited_axes(reference_n)
    if outputs_v.shape[1] == 0 or not np.any(excited):
        return None
    b, c, r2 = _fit(reference_n, excited, outputs_v)
    return Sensitivity(faces=faces, matrix_v_per_n=b.T, offset_v=c, r2=r2, excited=excited)


def cross_talk(estimate_n: np.ndarray, reference_n: np.ndarray) -> np.ndarray:
    """(estimated axis, reference axis) slopes of estimate = K F_ref + b [N/N]: identity
    for a perfect estimate, the off-diagonal terms are cross-talk."""
    excited = excited_axes(reference_n)
    if not np.any(excited):
        return np.full((3, 3), np.nan)
    b, _, _ = _fit(reference_n, excited, estimate_n)
    return b.T


def shear_directions(estimate_n: np.ndarray, reference_n: np.ndarray) -> ShearDirections | None:
    """Direction of the lateral force, applied vs estimated, where the applied lateral force
    is at least max(SHEAR_FRACTION x its largest magnitude, SHEAR_MIN_N)."""
    applied = np.hypot(reference_n[:, 0], reference_n[:, 1])
    top = float(np.max(applied)) if applied.size else 0.0
    threshold = max(SHEAR_FRACTION * top, SHEAR_MIN_N)
    keep = applied >= threshold
    if not np.any(keep):
        return None
    a = np.arctan2(reference_n[keep, 1], reference_n[keep, 0])
    e = np.arctan2(estimate_n[keep, 1], estimate_n[keep, 0])
    err = np.angle(np.exp(1j * (e - a)))
    return ShearDirections(threshold_n=threshold, applied_rad=a, estimated_rad=e,
                           applied_n=applied[keep],
                           estimated_n=np.hypot(estimate_n[keep, 0], estimate_n[keep, 1]),
                           error_rad=err)


def _num(x: float | None, digits: int = 6) -> float | None:
    if x is None or not np.isfinite(x):
        return None
    return float(f"{float(x):.{digits}g}")


def _per_axis(values: np.ndarray) -> dict[str, float | None]:
    return {a: _num(float(v)) for a, v in zip(AXES, values, strict=True)}


def analyse_array(recording: Recording, reason: str) -> ArrayAnalysis:
    """The array's metrics; TopicError/SegmentError (one sentence) for unusable inputs."""
    _check_inputs(recording, reason)
    compare_torque, torque_note = _torque_note(recording)
    sig = align_array(recording, torque=compare_torque)
    notes = [f"analysed as a module array: {reason}."]
    if torque_note:
        notes.append(torque_note)
    topics = {r: recording.series[r].topic for r in ("reading", "estimate", "reference")}
    return analyse_signals(sig, reason, topics, notes)


def analyse_signals(sig: ArraySignals, reason: str, topics: dict[str, str],
                    notes: list[str]) -> ArrayAnalysis:
    """The array's metrics from aligned signals: a recording's, or the decimated ones a
    benchmark keeps so the docs can draw the analysis's figures again."""
    if sig.reference_flipped:
        notes.append("the gauge's force.z was mostly negative (the skin's force on the probe); "
                     "its whole force vector was negated to the sensor's convention.")
    rmse, span = force_errors(sig.estimate_n, sig.reference_n)
    excited = excited_axes(sig.reference_n)
    if not np.all(excited):
        left = [a for a, e in zip(AXES, excited, strict=True) if not e]
        notes.append(f"the reference force hardly varies along {', '.join(left)} (range below "
                     f"{AXIS_MIN_FRACTION:.0%} of the largest axis'), so the sensitivity "
                     "matrix and the cross-talk leave those axes out (null).")
    sens = sensitivity_matrix(sig.outputs_v, sig.reference_n, sig.faces)
    if sig.outputs_v.shape[1] == 0:
        notes.append("the reading carries no per-module outputs, so there is no sensitivity "
                     "matrix.")
    talk = cross_talk(sig.estimate_n, sig.reference_n)
    shear = shear_directions(sig.estimate_n, sig.reference_n)
    if shear is None:
        notes.append(f"the lateral reference force never reaches {SHEAR_MIN_N} N, so no shear "
                     "direction is compared.")
    pct = _pct(rmse, span)
    metrics: dict[str, Any] = {
        "force_rmse_n": _per_axis(rmse),
        "force_range_n": _per_axis(span),
        "force_rmse_pct_range": _per_axis(pct),
        "array": {
            "detected_by": reason,
            "faces": list(sig.faces),
            "topics": topics,
            "samples": int(sig.t_s.size),
            "duration_s": _num(float(sig.t_s[-1])),
            "sample_rate_hz": _num(sig.rate_hz),
            "excited_axes": [a for a, e in zip(AXES, excited, strict=True) if e],
            "sensitivity_matrix": _sensitivity_dict(sens),
            "force_cross_talk": {"rows": "estimated axis", "columns": "reference axis",
                                 "axes": list(AXES),
                                 "values": [[_num(v) for v in row] for row in talk]},
            "shear_direction": _direction_dict(shear),
        },
    }
    torque_rmse, torque_span, unobserved = _torque_errors(sig, metrics, notes)
    metrics["wrench_excursions"] = excursion_metrics(*wrench_columns(sig), sig.t_s)
    return ArrayAnalysis(metrics=metrics, notes=notes, signals=sig, rmse_n=rmse, range_n=span,
                         sensitivity=sens, cross_talk=talk, shear=shear, detected_by=reason,
                         torque_rmse_nm=torque_rmse, torque_range_nm=torque_span,
                         torque_unobserved=unobserved)


def wrench_columns(sig: ArraySignals) -> tuple[tuple[str, ...], np.ndarray, np.ndarray]:
    """(component names, estimate, reference): the forces, and the torques where the
    recording compares them."""
    names = tuple(f"f{a}" for a in AXES)
    if sig.estimate_torque_nm is None or sig.reference_torque_nm is None:
        return names, sig.estimate_n, sig.reference_n
    return (names + tuple(f"t{a}" for a in AXES),
            np.column_stack([sig.estimate_n, sig.estimate_torque_nm]),
            np.column_stack([sig.reference_n, sig.reference_torque_nm]))


def _sensitivity_dict(sens: Sensitivity | None) -> dict[str, Any] | None:
    if sens is None:
        return None
    return {
        "faces": list(sens.faces), "axes": list(AXES),
        "values_v_per_n": [[_num(v) for v in row] for row in sens.matrix_v_per_n],
        "offset_v": [_num(v) for v in sens.offset_v],
        "r2": [_num(v) for v in sens.r2],
    }


def _direction_dict(shear: ShearDirections | None) -> dict[str, Any] | None:
    if shear is None:
        return None
    deg = np.degrees(shear.error_rad)
    return {"threshold_n": _num(shear.threshold_n), "samples": int(deg.size),
            "rmse_deg": _num(float(np.sqrt(np.mean(deg ** 2)))),
            "median_abs_deg": _num(float(np.median(np.abs(deg)))),
            "max_abs_deg": _num(float(np.max(np.abs(deg))))}


def _torque_errors(sig: ArraySignals, metrics: dict[str, Any], notes: list[str]
                   ) -> tuple[np.ndarray | None, np.ndarray | None, tuple[str, ...]]:
    """The torque's errors per axis where the recording has both torques (added to
    ``metrics``), and the axes the driver does not observe (a note)."""
    if sig.estimate_torque_nm is None or sig.reference_torque_nm is None:
        return None, None, ()
    torque_rmse, torque_span = force_errors(sig.estimate_torque_nm, sig.reference_torque_nm)
    unobserved = tuple(a for a, col in zip(AXES, sig.estimate_torque_nm.T, strict=True)
                       if np.all(np.isnan(col)))
    metrics["torque_rmse_nm"] = _per_axis(torque_rmse)
    metrics["torque_range_nm"] = _per_axis(torque_span)
    metrics["torque_rmse_pct_range"] = _per_axis(_pct(torque_rmse, torque_span))
    metrics["array"]["torque_unobserved_axes"] = list(unobserved)
    if unobserved:
        names = ", ".join(f"T{a}" for a in unobserved)
        them, their = ("them", "their") if len(unobserved) > 1 else ("it", "its")
        notes.append(f"the driver publishes {names} as NaN throughout (its module layout "
                     f"does not observe {them}), so {their} torque error is null.")
    return torque_rmse, torque_span, unobserved
