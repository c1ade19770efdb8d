"""Fit a module array's six-column calibration from a recording (``analyze --fit-calibration``).

The modules' outputs are fitted against the gauge's wrench with the driver's own model
(``sensing.array_calibration.ArrayCalibration.fit``: symmetry-adapted features, each
component on the monomials of its mirror parity), so the file loads with
``calibration_source: file``.

What is fitted is the quasi-static relation. The recorded outputs are the driver's, already
low-passed by its force filter and so a few milliseconds behind the gauge, and the gauge
also reads the silicone's viscoelastic rate force, which no static polynomial of the
outputs can give. Both sides are therefore low-passed alike (zero-phase Butterworth,
``QUASI_STATIC_HZ``): what is left is the slow, static part of the protocol, in which the
filter's lag is a small share of a period; both are then decimated to five times the cut-off, which
the low-pass makes lossless and which keeps the noise-augmented least squares small.

The calibration will meet the driver's force-filtered outputs with their noise, not the
low-passed ones, so the force fit adds noise as physics' FEM fit does (``FIT_NOISE_V``):
without it the fit may lean on terms that amplify a module's noise. The torques are fitted
as the FEM's are (``physics.array_report``): without noise, linear with gains that follow
the press. Noise in their fit is a ridge that shrinks them (regression dilution: 10 mV read
a twist at a fraction of its torque); the driver's torque low-pass narrows their noise
instead.

The force's slow part (what the FEM fit adds for tilt and twist, low-passed with the
torque) is not fitted: the recording's forces already include the tilt's and the twist's,
so the forces are fitted directly on every sample; the file has no ``force_slow_*``.

Held-out error: contiguous blocks of ``BLOCK_S`` seconds, every ``HOLD_EVERY``-th held out,
so that neighbouring (correlated) samples do not leak between fit and test; the file written
is then refitted on every sample.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.signal import butter, sosfiltfilt

from tactile_sensor.physics.array_report import (
    TORQUE_FIT_NOISE_V,
    WRENCH_TORQUE_DEGREE,
    WRENCH_TORQUE_PRESS_SCALED,
)
from tactile_sensor.sensing.array_calibration import COMPONENTS, ArrayCalibration
from tactile_sensor.sensing.errors import CalibrationError

from ..bag_reader import Recording
from ..errors import SegmentError
from .analysis import ArraySignals, align_array, reference_has_torque

#: Cut-off [Hz] of the zero-phase low-pass applied alike to outputs and gauge: well above
#: the protocol's motions (about 1 mm/s over millimetres) and well below the force filter's
#: and the rate force's fast parts.
QUASI_STATIC_HZ = 2.0
BLOCK_S = 2.0  # held-out block length [s]
HOLD_EVERY = 5  # every 5th block is held out
#: A component is fitted only if its range in the recording is at least this share of its
#: full scale: the largest range among the forces (N) or among the torques (N m).
EXCITED_FRACTION = 0.05
DEGREE = 3  # the force polynomial's degree, as the FEM calibration's
FIT_NOISE_V = 0.005  # physics.array_report.FIT_NOISE_V
UNITS = {"f": "N", "t": "N m"}


@dataclass(frozen=True)
class ArrayFit:
    """The calibration fitted on every sample, its held-out errors and what was left out."""

    calibration: ArrayCalibration
    metrics: dict[str, Any]
    lines: list[str]  # one per component, for the terminal and the report


def decimation(rate_hz: float, fit_rate_hz: float) -> int:
    """Every how many samples the low-passed signals are kept."""
    return max(1, round(rate_hz / fit_rate_hz))


def quasi_static(t_s: np.ndarray, values: np.ndarray, rate_hz: float,
                 cutoff_hz: float = QUASI_STATIC_HZ, fit_rate_hz: float = 5 * QUASI_STATIC_HZ
                 ) -> tuple[np.ndarray, np.ndarray]:
    """(times, values) low-passed with zero phase at ``cutoff_hz`` and decimated to about
    ``fit_rate_hz``; columns NaN anywhere stay NaN."""
    step = decimation(rate_hz, fit_rate_hz)
    out = np.array(values, dtype=float)
    if rate_hz > 2.5 * cutoff_hz and out.shape[0] > 30:
        sos = butter(2, cutoff_hz, fs=rate_hz, output="sos")
        finite = np.all(np.isfinite(out), axis=0)
        out[:, finite] = sosfiltfilt(sos, out[:, finite], axis=0)
    return t_s[::step], out[::step]


def held_out_blocks(t_s: np.ndarray, block_s: float = BLOCK_S, every: int = HOLD_EVERY
                    ) -> np.ndarray:
    """Boolean mask of the samples in every ``every``-th block of ``block_s`` seconds
    (starting with the third, so neither end of the recording is all held out)."""
    block = np.floor((t_s - t_s[0]) / block_s).astype(int)
    return block % every == every // 2


def excited_components(wrench: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(per column whether its range reaches EXCITED_FRACTION of its kind's full scale,
    the ranges)."""
    span = np.ptp(wrench, axis=0)
    excited = np.zeros(span.size, bool)
    for kind in (slice(0, 3), slice(3, span.size)):
        top = float(np.max(span[kind], initial=0.0))
        excited[kind] = (span[kind] >= EXCITED_FRACTION * top) & (span[kind] > 0)
    return excited, span


def _num(x: float) -> float | None:
    return float(f"{x:.6g}") if np.isfinite(x) else None


def fit_array_signals(sig: ArraySignals, with_torque: bool, source: str,
                      degree: int = DEGREE, torque_degree: int = WRENCH_TORQUE_DEGREE,
                      cutoff_hz: float = QUASI_STATIC_HZ, noise_v: float = FIT_NOISE_V,
                      torque_noise_v: float = TORQUE_FIT_NOISE_V) -> ArrayFit:
    """The fit on aligned signals (module docstring), both sides low-passed at
    ``cutoff_hz``; SegmentError (one sentence) when the recording cannot give one."""
    if sig.outputs_v.shape[1] < 2:
        raise SegmentError("the reading carries no per-module outputs, so no array calibration "
                           "can be fitted; record the driver's reading with its modules.")
    wrench = sig.reference_n
    if with_torque and sig.reference_torque_nm is not None:
        wrench = np.column_stack([wrench, sig.reference_torque_nm])
    t, data = quasi_static(sig.t_s, np.column_stack([sig.outputs_v, wrench]), sig.rate_hz,
                          cutoff_hz, 5 * cutoff_hz)
    m = sig.outputs_v.shape[1]
    outputs, wrench = data[:, :m], data[:, m:]
    keep = np.all(np.isfinite(data), axis=1)
    t, outputs, wrench = t[keep], outputs[keep], wrench[keep]
    if t.size < 2 or t[-1] - t[0] < HOLD_EVERY * BLOCK_S:
        raise SegmentError(f"the array recording spans {t[-1] - t[0] if t.size else 0:.3g} s, "
                           f"too short to hold out {BLOCK_S:g} s blocks for an honest error; "
                           f"record at least {HOLD_EVERY * BLOCK_S:g} s of the protocol.")
    excited, span = excited_components(wrench)
    names = COMPONENTS[:wrench.shape[1]]
    observed = [c for c, e in zip(names, excited, strict=True) if e]
    if not any(c.startswith("f") for c in observed):
        raise SegmentError("the gauge's force does not vary during the recording, so no "
                           "array calibration can be fitted; record the press protocol.")
    fitted = wrench.copy()
    fitted[:, ~excited] = np.nan  # a component not excited has no data to fit
    held = held_out_blocks(t)
    try:
        trial = ArrayCalibration.fit(sig.faces, outputs[~held], fitted[~held], degree, source,
                                     noise_v, torque_degree, observed, torque_noise_v,
                                     press_scaled=WRENCH_TORQUE_PRESS_SCALED)
        estimate = trial.wrenches(outputs[held])[:, :wrench.shape[1]]
        cal = ArrayCalibration.fit(sig.faces, outputs, fitted, degree, source, noise_v,
                                   torque_degree, observed, torque_noise_v,
                                   press_scaled=WRENCH_TORQUE_PRESS_SCALED)
    except CalibrationError as err:
        why = str(err).replace("add grid points", "record longer").replace(
            "add load paths", "record longer")
        raise SegmentError(f"the array calibration cannot be fitted from this recording: "
                           f"{why[0].lower()}{why[1:]}") from None
    rmse = np.sqrt(np.mean((estimate - wrench[held]) ** 2, axis=0))
    lines: list[str] = []
    per: dict[str, Any] = {}
    for k, name in enumerate(names):
        unit = UNITS[name[0]]
        if excited[k]:
            pct = 100 * rmse[k] / span[k]
            per[name] = {"rmse": _num(rmse[k]), "range": _num(span[k]),
                         "rmse_pct_range": _num(pct), "unit": unit}
            lines.append(f"{name}: held-out rmse {rmse[k]:.3g} {unit} ({pct:.2f} % of the "
                         f"{span[k]:.3g} {unit} range)")
        else:
            per[name] = {"rmse": None, "range": _num(span[k]), "rmse_pct_range": None,
                         "unit": unit}
            lines.append(f"{name}: not fitted, left out of observed: its range "
                         f"{span[k]:.3g} {unit} is below {EXCITED_FRACTION:.0%} of the "
                         f"largest {'force' if name[0] == 'f' else 'torque'}'s, so the "
                         "recording does not excite it")
    if wrench.shape[1] == 3:
        lines.append("tx, ty, tz: not fitted: the gauge measures no torque (force-only "
                     "calibration)")
    metrics = {
        "source": source, "faces": list(sig.faces), "degree": degree,
        "torque_degree": min(torque_degree, degree) if wrench.shape[1] == 6 else None,
        "observed": observed, "components": per,
        "quasi_static_hz": cutoff_hz, "fit_rate_hz": _num(sig.rate_hz / decimation(
            sig.rate_hz, 5 * cutoff_hz)),
        "block_s": BLOCK_S, "hold_every": HOLD_EVERY,
        "samples": int(t.size), "held_out_samples": int(held.sum()),
        "noise_v": noise_v, "torque_noise_v": torque_noise_v,
        "torque_press_scaled": WRENCH_TORQUE_PRESS_SCALED,
        "force_slow_part": False,
    }
    return ArrayFit(cal, metrics, lines)


def fit_array_recording(recording: Recording, source: str, degree: int = DEGREE,
                        torque_degree: int = WRENCH_TORQUE_DEGREE) -> ArrayFit:
    """Align the recording (with the gauge's torque where it measures one) and fit."""
    sig = align_array(recording, torque=True)
    torque = reference_has_torque(recording.series["reference"])
    return fit_array_signals(sig, torque, source, degree, torque_degree)
