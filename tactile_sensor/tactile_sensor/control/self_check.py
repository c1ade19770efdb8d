"""The self-check: an optical gain and a skin stiffness from one slow close on a rigid object.

The gripper closes slowly on whatever rigid object stands between the fingers and records,
per servo sample, its position, velocity and Present Current, and the module's output.
No force reference is needed: the FEM prediction of the skin (the model node's
``~/predict``) says what the module outputs and what the skin pushes back at each
indentation, and the fit finds the two factors that make the record agree with it:

- the module's output is ``output_0 + gain * output_fem(d_a)``. The emitter and detector
  scale the skin's photocurrent (physics/detector.py), so an emitter at 0.8 gives 0.8 of
  the FEM's output at every indentation. A stiffer or softer skin (every Mooney-Rivlin
  modulus scaled by one factor) deforms the same under the same indentation, so its output
  against indentation is the FEM's and only its force scales;
- the rack force, read from the servo's current, is
  ``stiffness * (force_fem(d_a) + force_fem(d_b))``: the pinion drives both racks, and
  finger B (a skin without a module) touches the object at its own position.

The indentation comes from the servo's position after contact (finger A's contact from the
output trace). The position-to-indentation map is the drive train's (``DriveTrain``): the
pinion's pitch radius, the play between pinion and racks (backlash: the racks follow the
pinion only once the play is taken up) and the gear train's compliance (the racks lag the
pinion by the rack force times the compliance). What is left of the free-closing current
before contact (friction) is measured, not assumed, and taken off.

Pure: numbers in, numbers out (the node fetches the prediction and the samples).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from tactile_sensor.control.errors import ControlError
from tactile_sensor.control.geometry import GripperGeometry
from tactile_sensor.control.grasp import XM430_LOAD_FRICTION_RATIO
from tactile_sensor.hardware.xm430_table import A_PER_CURRENT_UNIT

#: XM430-W210 at 12 V: stall torque 3.0 N m at 2.3 A (ROBOTIS e-Manual), at the output.
XM430_TORQUE_CONSTANT_NM_PER_A = 3.0 / 2.3
#: Why a self-check ends without a fit, as the action's ``outcome``.
CLOSED_LIMIT_WITHOUT_CONTACT = "closed_limit_without_contact"
TOO_UNCERTAIN = "too_uncertain"
TOO_FEW_SAMPLES = "too_few_samples"
#: Samples before contact that set the output's and the current's free levels.
MIN_FREE_SAMPLES = 10
#: Samples the contact test averages.
SMOOTH = 5
#: Samples in contact a fit needs at least.
MIN_CONTACT_SAMPLES = 12
FloatArray = npt.NDArray[np.float64]


class SelfCheckError(ControlError):
    """A self-check that cannot give factors; ``outcome`` names why, the text says the fix."""

    def __init__(self, outcome: str, message: str) -> None:
        super().__init__(message)
        self.outcome = outcome


@dataclass(frozen=True)
class SkinPrediction:
    """The FEM prediction for the skin: indentation [m], force [N], module output [V]."""

    indentation_m: tuple[float, ...]
    force_n: tuple[float, ...]
    output_v: tuple[float, ...]

    def __post_init__(self) -> None:
        d = np.asarray(self.indentation_m, dtype=float)
        if not (len(d) == len(self.force_n) == len(self.output_v) and len(d) >= 3):
            raise ValueError("a skin prediction needs >= 3 (indentation, force, output) "
                             "points that pair up")
        if not (np.all(np.isfinite(d)) and np.all(np.diff(d) > 0) and d[0] == 0.0):
            raise ValueError("a skin prediction's indentations must start at 0 and increase")

    @property
    def max_indentation_m(self) -> float:
        return self.indentation_m[-1]

    def force(self, d: FloatArray) -> FloatArray:
        return np.interp(d, self.indentation_m, self.force_n)

    def output(self, d: FloatArray) -> FloatArray:
        return np.interp(d, self.indentation_m, self.output_v)

    def output_slope(self, d: FloatArray) -> FloatArray:
        return _slope(d, self.indentation_m, self.output_v)

    def force_slope(self, d: FloatArray) -> FloatArray:
        return _slope(d, self.indentation_m, self.force_n)


def _slope(d: FloatArray, xs: Sequence[float], ys: Sequence[float]) -> FloatArray:
    x, y = np.asarray(xs, dtype=float), np.asarray(ys, dtype=float)
    segment = np.clip(np.searchsorted(x, d, side="right") - 1, 0, len(x) - 2)
    return (y[segment + 1] - y[segment]) / (x[segment + 1] - x[segment])


@dataclass(frozen=True)
class DriveTrain:
    """The servo-to-finger map: geometry, torque constant, play and compliance."""

    geometry: GripperGeometry = field(default_factory=GripperGeometry)
    torque_constant_nm_per_a: float = XM430_TORQUE_CONSTANT_NM_PER_A
    #: Play between pinion and racks [rad of the pinion].
    backlash_rad: float = 0.0
    #: How far each rack lags the pinion per newton of rack force [m/N].
    compliance_m_per_n: float = 0.0
    #: One unit of Present Current [A].
    current_resolution_a: float = A_PER_CURRENT_UNIT
    #: Friction at rest per N m the gears transmit [1] (``XM430_LOAD_FRICTION_RATIO``).
    #: A close cannot measure it: the motor's torque u meets ``u (1 - ratio) = skin +
    #: friction`` however the current goes (opening, the motor pulls against friction the
    #: skin's force cannot overcome, and the same relation holds), so a higher ratio reads
    #: exactly as a stiffer skin. It is the servo's constant, as the torque constant is.
    load_friction_ratio: float = XM430_LOAD_FRICTION_RATIO

    def __post_init__(self) -> None:
        if not (self.torque_constant_nm_per_a > 0 and self.backlash_rad >= 0
                and self.compliance_m_per_n >= 0 and 0 <= self.load_friction_ratio < 1):
            raise ValueError("need a positive torque constant, a non-negative backlash "
                             "and compliance and a load friction ratio in [0, 1)")

    def rack_force_n(self, current_a: FloatArray, free_current_a: float) -> FloatArray:
        """The force both racks push with [N] (the sum of the two fingers' skin forces):
        the torque over the free close's, less the friction that torque brings."""
        return (self.torque_constant_nm_per_a * (1.0 - self.load_friction_ratio)
                * (current_a - free_current_a) / self.geometry.pitch_radius_m)

    def rack_positions_rad(self, positions_rad: FloatArray) -> FloatArray:
        """Where the racks are, in pinion angle: the play operator on the servo's positions,
        starting with the play taken up on the opening side (the fingers last opened)."""
        width = self.backlash_rad
        out = np.empty_like(positions_rad)
        rack = positions_rad[0] - width
        for i, p in enumerate(positions_rad.tolist()):
            rack = min(max(rack, p - width), p)
            out[i] = rack
        return out

    def travel_m(self, rack_rad: FloatArray, contact_rad: float,
                 rack_force_n: FloatArray) -> FloatArray:
        """A finger's travel past its contact [m], less the train's compliance."""
        travel = self.geometry.pitch_radius_m * (rack_rad - contact_rad)
        return travel - self.compliance_m_per_n * np.maximum(rack_force_n, 0.0)


@dataclass(frozen=True)
class ClosingRecord:
    """One slow close, one entry per servo sample (arrays of equal length)."""

    position_rad: FloatArray
    velocity_rad_s: FloatArray
    current_a: FloatArray
    output_v: FloatArray

    @classmethod
    def of(cls, position_rad: Sequence[float], velocity_rad_s: Sequence[float],
           current_a: Sequence[float], output_v: Sequence[float]) -> ClosingRecord:
        arrays = [np.asarray(a, dtype=float) for a in
                  (position_rad, velocity_rad_s, current_a, output_v)]
        if len({a.shape for a in arrays}) != 1 or arrays[0].ndim != 1:
            raise ValueError("a closing record's columns must be 1-D and of equal length")
        keep = np.all(np.isfinite(np.vstack(arrays)), axis=0)
        return cls(*(a[keep] for a in arrays))


@dataclass(frozen=True)
class SelfCheckLimits:
    """When the self-check calls contact and when a fit is too uncertain to apply."""

    #: Output rise over the free level that is contact: this many noise sigmas ...
    contact_sigmas: float = 6.0
    #: ... and at least this [V].
    contact_floor_v: float = 0.005
    #: The largest standard uncertainty of either factor a correction may carry [1].
    max_sigma: float = 0.015
    #: How far one finger may touch before the other [m]: twice how far off the centre
    #: the object may stand. The force alone cannot tell finger B touching with finger A
    #: on a skin k from finger B not touching at all on a skin 2 k; the object's place can.
    max_lead_m: float = 0.0015


@dataclass(frozen=True)
class SelfCheckFit:
    """Both factors with their standard uncertainty, and where finger A touched."""

    optical_gain: float
    optical_gain_sigma: float
    stiffness: float
    stiffness_sigma: float
    contact_position_rad: float
    max_indentation_m: float
    samples: int

    def corrected_curve(self, prediction: SkinPrediction) -> tuple[FloatArray, FloatArray]:
        """The output -> force curve of this skin and module: (output [V], force [N]),
        output strictly increasing (repeated outputs dropped)."""
        out = self.optical_gain * np.asarray(prediction.output_v, dtype=float)
        force = self.stiffness * np.asarray(prediction.force_n, dtype=float)
        keep = np.concatenate([[True], np.diff(out) > 0])
        return out[keep], force[keep]


def fit_self_check(record: ClosingRecord, prediction: SkinPrediction,
                   train: DriveTrain = DriveTrain(),
                   limits: SelfCheckLimits = SelfCheckLimits()) -> SelfCheckFit:
    """The two factors from one close; ``SelfCheckError`` (one sentence) when it has none."""
    closing = record.velocity_rad_s > 0.0
    out, cur = record.output_v[closing], record.current_a[closing]
    _contact_index(out, limits)  # refuses a close that never touched
    rack = train.rack_positions_rad(record.position_rad[closing])
    # the free level from the first samples, before either finger touches: the
    # compliance's deflection needs the force from the start
    free = float(np.median(cur[:MIN_FREE_SAMPLES]))
    force = train.rack_force_n(cur, free)
    # finger A's contact anywhere in the close: where the output first crosses its
    # threshold is no bound, a noise excursion of the free output can cross it early
    gain, gain_sigma, contact = _fit_optical(rack, out, force, (rack[0], rack[-1]),
                                             prediction, train)
    travel = train.travel_m(rack, contact, force)
    usable = travel <= prediction.max_indentation_m
    pressed = int(np.count_nonzero(travel[usable] > 0))
    if pressed < MIN_CONTACT_SAMPLES:
        raise SelfCheckError(TOO_FEW_SAMPLES, (
            f"The self-check pressed only {pressed} samples into the skin (a fit needs "
            f"{MIN_CONTACT_SAMPLES}); close more slowly or further."))

    def stiffness_at(free_a: float) -> tuple[float, float]:
        pushed = train.rack_force_n(cur, free_a)
        moved = train.travel_m(rack, contact, pushed)
        keep = moved <= prediction.max_indentation_m
        return _fit_stiffness(moved[keep], pushed[keep], prediction, limits.max_lead_m)

    stiffness, statistical = stiffness_at(free)
    # a steady free current reads the same code every sample: it is known only to within
    # one current unit, uniformly, whatever the number of samples (a systematic term)
    half = 0.5 * train.current_resolution_a
    spread = abs(stiffness_at(free + half)[0] - stiffness_at(free - half)[0]) / 2.0
    stiffness_sigma = math.hypot(statistical, spread / math.sqrt(3.0))
    fit = SelfCheckFit(gain, gain_sigma, stiffness, stiffness_sigma, contact,
                       float(np.max(travel[usable])), pressed)
    _check_certain(fit, limits)
    return fit


def _contact_index(out: FloatArray, limits: SelfCheckLimits) -> int:
    """The first sample the output has risen over its free level for good (a running mean
    of ``SMOOTH`` samples over the threshold)."""
    if out.size < MIN_FREE_SAMPLES + MIN_CONTACT_SAMPLES:
        raise SelfCheckError(TOO_FEW_SAMPLES, (
            f"The self-check recorded {out.size} closing samples (it needs "
            f"{MIN_FREE_SAMPLES + MIN_CONTACT_SAMPLES}); start it with the fingers open."))
    free = out[:MIN_FREE_SAMPLES]
    sigma = float(np.std(free, ddof=1)) / math.sqrt(SMOOTH)
    threshold = float(np.median(free)) + max(limits.contact_sigmas * sigma,
                                             limits.contact_floor_v)
    smooth = np.convolve(out, np.full(SMOOTH, 1.0 / SMOOTH), mode="valid")
    over = np.flatnonzero(smooth[MIN_FREE_SAMPLES:] > threshold)
    if over.size == 0:
        raise SelfCheckError(CLOSED_LIMIT_WITHOUT_CONTACT, (
            "The fingers reached their closed limit without touching anything; put a rigid "
            "object between the fingers and run the self-check again."))
    return int(over[0]) + MIN_FREE_SAMPLES + SMOOTH - 1


def _linear_fit(columns: FloatArray, data: FloatArray) -> tuple[FloatArray, float]:
    """Least-squares coefficients of ``columns`` (n x p) for ``data``, and the residual
    sum of squares."""
    coef, *_ = np.linalg.lstsq(columns, data, rcond=None)
    residual = data - columns @ coef
    return coef, float(residual @ residual)


def _scan(objective: Callable[[float], float], low: float, high: float, points: int = 81,
          rounds: int = 3) -> float:
    """The argument minimising ``objective`` over [low, high]: a grid refined around its
    best point (the residual is not smooth in a contact position: a table is linear in
    pieces)."""
    best = 0.5 * (low + high)
    for _ in range(rounds):
        grid = np.linspace(low, high, points)
        best = float(grid[int(np.argmin([objective(float(x)) for x in grid]))])
        width = (high - low) / (points - 1)
        low, high = best - width, best + width
    return best


def _fit_optical(rack: FloatArray, out: FloatArray, force: FloatArray,
                 bracket: tuple[float, float], prediction: SkinPrediction,
                 train: DriveTrain) -> tuple[float, float, float]:
    """(gain, its sigma, finger A's contact position [rad]): the output is a free level
    plus the gain times the FEM's output at finger A's indentation. Every candidate contact
    is judged on the same samples, those within the prediction's range at the latest one
    (``bracket[1]``); an earlier contact that would press one of them past the range is no
    candidate. (Judged on the samples each keeps, a contact early enough to leave out every
    pressed sample fitted the flat free output best: a gain of 0.47 for 1.0.)"""
    keep = train.travel_m(rack, bracket[1], force) <= prediction.max_indentation_m

    def columns(contact: float) -> FloatArray | None:
        d = train.travel_m(rack[keep], contact, force[keep])
        if np.any(d > prediction.max_indentation_m):
            return None
        d = np.maximum(d, 0.0)
        return np.column_stack([prediction.output(d), np.ones_like(d)])

    def residual(contact: float) -> float:
        cols = columns(contact)
        return math.inf if cols is None else _linear_fit(cols, out[keep])[1]

    contact = _scan(residual, *bracket)
    cols = columns(contact)
    assert cols is not None  # the latest contact, bracket[1], always is a candidate
    (gain, _level), ssr = _linear_fit(cols, out[keep])
    d = np.maximum(train.travel_m(rack[keep], contact, force[keep]), 0.0)
    slope = -gain * prediction.output_slope(d) * (d > 0) * train.geometry.pitch_radius_m
    return float(gain), _sigma_first(np.column_stack([cols, slope]), ssr), contact


def _fit_stiffness(travel_a: FloatArray, force: FloatArray, prediction: SkinPrediction,
                   max_lead_m: float) -> tuple[float, float]:
    """(stiffness, its sigma) from the rack force (the free closing's friction taken off):
    the stiffness times both skins' FEM force; finger B's lead over finger A (its
    indentation at finger A's contact, [m], negative: it touches later) is fitted beside
    it, from the force before finger A touches as much as after. Samples where either
    skin is past the prediction's range are left out."""
    d_a = np.maximum(travel_a, 0.0)

    def columns(lead_m: float) -> tuple[FloatArray, npt.NDArray[np.bool_]]:
        d_b = np.maximum(travel_a + lead_m, 0.0)
        keep = d_b <= prediction.max_indentation_m
        both = prediction.force(d_a[keep]) + prediction.force(d_b[keep])
        return both[:, None], keep

    def residual(lead_m: float) -> float:
        cols, keep = columns(lead_m)
        if np.count_nonzero(keep) < MIN_CONTACT_SAMPLES:
            return math.inf
        return _linear_fit(cols, force[keep])[1] / np.count_nonzero(keep)

    lead = _scan(residual, -max_lead_m, max_lead_m)
    cols, keep = columns(lead)
    (stiffness,), ssr = _linear_fit(cols, force[keep])
    d_b = np.maximum(travel_a[keep] + lead, 0.0)
    slope = stiffness * prediction.force_slope(d_b) * (d_b > 0)
    return float(stiffness), _sigma_first(np.column_stack([cols, slope]), ssr)


def _sigma_first(jac: FloatArray, ssr: float) -> float:
    """The standard uncertainty of the first parameter of a least-squares fit."""
    dof = jac.shape[0] - jac.shape[1]
    if dof <= 0:
        return math.inf
    try:
        cov = np.linalg.inv(jac.T @ jac) * (ssr / dof)
    except np.linalg.LinAlgError:
        return math.inf
    return float(math.sqrt(max(cov[0, 0], 0.0)))


def _check_certain(fit: SelfCheckFit, limits: SelfCheckLimits) -> None:
    worst = max(fit.optical_gain_sigma, fit.stiffness_sigma)
    if not (math.isfinite(worst) and worst <= limits.max_sigma):
        raise SelfCheckError(TOO_UNCERTAIN, (
            f"The self-check's fit is too uncertain to apply (optical gain "
            f"{fit.optical_gain:.3f} +- {fit.optical_gain_sigma:.3f}, stiffness "
            f"{fit.stiffness:.3f} +- {fit.stiffness_sigma:.3f}, limit +- {limits.max_sigma}); "
            "hold the object still and run it again, closing more slowly."))
