"""Which wrench components a module layout resolves: the observability metric.

From the wrench paths of ``physics/wrench.py`` (press, shear, tilt about x and y, twist
about z): S6 (modules x Fx, Fy, Fz, Tx, Ty, Tz), the least-squares linear map from wrench to
outputs. S6 [V/N, V/(N m)] mixes units, so its singular values mean nothing until each
column is scaled by the load the paths reach (full scale): the scaled column is the output
pattern [V] a full-scale load of that component produces. Its singular values compare with
the module noise directly: a direction whose singular value is below ``OBSERVE_SNR`` x
noise_v is not resolved at full scale. A component is observed when, added to the components
already observed (order Fz, Fx, Fy, Tz, Tx, Ty: forces first), the scaled columns' smallest
singular value stays above that threshold; ``distinct`` is the part of a component's pattern
that no combination of the three forces explains (for a force, of the other two). Each
component's noise [% of its full scale] at the output bandwidths ``NOISE_BANDWIDTHS_HZ`` is
the least-squares estimate's: covariance sigma^2 (S^T S)^-1 of the scaled S6, with sigma the
module noise a 2nd-order low-pass leaves at that bandwidth (``physics/output_noise.py``);
infinite when S6 cannot separate the six at all.

It lives with the model, not with the design studies, because the model's own array
calibration (``physics/array_report.py``) decides with it which components a six-column
calibration publishes; the studies report the same figures per design.
"""

from __future__ import annotations

import math

import numpy as np

from .errors import PhysicsError
from .output_noise import SAMPLE_NOISE_V, SAMPLE_RATE_HZ, noise_at_bandwidth
from .wrench import WRENCH_AXES, WrenchSet

#: Greedy order in which components are admitted as observed: forces first.
OBSERVE_ORDER = ("fz", "fx", "fy", "tz", "tx", "ty")
#: A wrench direction is resolved when its full-scale output pattern exceeds this many times
#: the module noise (about 10 dB: three distinguishable levels across the full scale).
OBSERVE_SNR = 3.0
#: Output bandwidths [Hz] at which each wrench component's noise is reported.
NOISE_BANDWIDTHS_HZ = (1, 10, 100)


def wrench_matrix(data: WrenchSet) -> np.ndarray:
    """(modules, 6) least-squares S with outputs = S @ (Fx, Fy, Fz, Tx, Ty, Tz)."""
    solution, *_ = np.linalg.lstsq(data.wrench, data.output_matrix(), rcond=None)
    return solution.T


def full_scale(data: WrenchSet) -> np.ndarray:
    """The largest |component| the paths reach, per component (N, N m)."""
    return np.abs(data.wrench).max(axis=0)


def _smallest_singular(a: np.ndarray) -> float:
    values = np.linalg.svd(a, compute_uv=False)
    return float(values[-1]) if values.size == a.shape[1] else 0.0


def distinct_output(scaled: np.ndarray, k: int) -> float:
    """|part of column k| [V] that no combination of the force columns (other than k)
    explains."""
    others = [j for j in range(3) if j != k]
    basis = scaled[:, others]
    coef, *_ = np.linalg.lstsq(basis, scaled[:, k], rcond=None)
    return float(np.linalg.norm(scaled[:, k] - basis @ coef))


def component_noise(scaled: np.ndarray, noise_v: float) -> np.ndarray:
    """Each component's least-squares estimate noise in units of its full scale: the square
    roots of the diagonal of noise_v^2 (S^T S)^-1 (inf where S^T S is singular)."""
    gram = scaled.T @ scaled
    values = np.linalg.svd(scaled, compute_uv=False)
    if values.size < scaled.shape[1] or values[-1] <= 1e-9 * max(values[0], 1e-300):
        return np.full(scaled.shape[1], math.inf)
    return noise_v * np.sqrt(np.diag(np.linalg.inv(gram)))


def wrench_metrics(data: WrenchSet, noise_v: float, sample_noise_v: float = SAMPLE_NOISE_V,
                   sample_rate_hz: float = SAMPLE_RATE_HZ) -> dict[str, float]:
    """Singular values of the full-scale output patterns, their rank above the threshold,
    and per component its full scale, distinct output, whether it is observed at
    ``noise_v`` and its noise [% FS] at each of ``NOISE_BANDWIDTHS_HZ`` (from white samples
    of ``sample_noise_v`` at ``sample_rate_hz``)."""
    threshold = OBSERVE_SNR * noise_v
    scale = full_scale(data)
    if np.any(scale <= 0):
        raise PhysicsError("A wrench path produced no load along one component; check "
                           "wrench_twist, wrench_tilt and array_shear_ratio.")
    scaled = wrench_matrix(data) * scale[None, :]
    singular = np.zeros(len(WRENCH_AXES))
    values = np.linalg.svd(scaled, compute_uv=False)
    singular[:values.size] = values
    out: dict[str, float] = {f"wrench_singular_value_{k}_v": float(v)
                             for k, v in enumerate(singular, start=1)}
    out["wrench_rank"] = float(np.sum(singular > threshold))
    observed: list[int] = []
    for name in OBSERVE_ORDER:
        k = WRENCH_AXES.index(name)
        if _smallest_singular(scaled[:, [*observed, k]]) > threshold:
            observed.append(k)
    for k, name in enumerate(WRENCH_AXES):
        unit = "n" if name.startswith("f") else "nm"
        out[f"full_scale_{name}_{unit}"] = float(scale[k])
        out[f"distinct_{name}_v"] = distinct_output(scaled, k)
        out[f"observes_{name}"] = float(k in observed)
    out["observed_torques"] = float(sum(k in observed for k in (3, 4, 5)))
    out["output_noise_v"] = noise_v
    for hz in NOISE_BANDWIDTHS_HZ:
        sigma = noise_at_bandwidth(hz, sample_noise_v, sample_rate_hz)
        for name, value in zip(WRENCH_AXES, component_noise(scaled, sigma), strict=True):
            out[f"noise_{name}_pct_fs_{hz}hz"] = float(100.0 * value)
    return out
