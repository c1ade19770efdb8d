"""The QTR-1A photoreflector: output voltage against photoreflector-skin distance.

The sensor's phototransistor pulls the output down from the supply as reflected light
grows, so the voltage rises with distance and saturates at both rails (paper Sec. II-B,
Fig. 3(b)). We model the reflected-light term as ``rho(pigment) * D(x)``:

    V(x) = smooth_clamp(Vcc - rho(w) / rho(75 %) * D(x),  0,  Vcc)

``D`` (the light term of the 75 % white skin, in volts) is a monotone PCHIP through anchor
points chosen so that over 1-2 mm the 75 % curve follows the paper's fit
V = 1.9374 x[mm] - 1.8875 (eq. 1), falls past the lower rail at contact, and approaches the
supply beyond ~6 mm where little light returns. ``rho`` (diffuse reflectance at 940 nm) is
an assumption interpolated between black and white silicone; a whiter skin reflects more
and so swings further over 0-10 mm (the 100 % and 75 % mixes both reach the lower rail at
contact, so their swings are equal there; darker mixes never reach it). The anchors are a
stated assumption shaped like Fig. 3(b): the paper publishes only the 75 % fit.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from .errors import PhysicsError

PIGMENTS = (100.0, 75.0, 50.0, 25.0, 0.0)  # white share [%] of the paper's five samples
FIT_SLOPE_V_PER_M = 1.9374e3  # paper eq. (1): 1.9374 V/mm
FIT_OFFSET_V = -1.8875
FIT_WINDOW_M = (1.0e-3, 2.0e-3)

# Distance [mm] -> light term D [V] of the 75 % skin at a 5 V supply (assumption, see above).
# The 0.5-2 mm anchors lie on eq. (1) so the PCHIP slope at 1 mm is the fit's; an anchor off
# the line there made the curve sag ~50 mV (2.7 % of the window's span) below eq. (1) at 1.15 mm.
_ANCHOR_X_MM = np.array([0.0, 0.5, 1.0, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0, 6.5, 8.0, 10.0, 20.0])
_ANCHOR_V = np.array([-1.0, -0.9188, 0.0499, 1.0186, 1.9873, 2.90, 3.60, 4.40, 4.75, 4.93,
                      4.99, 5.0, 5.0])


class _Pchip:
    """Monotone piecewise-cubic Hermite interpolation (Fritsch-Carlson slopes, as MATLAB's
    and SciPy's ``pchip``) through a few anchors, in numpy alone.

    Why not ``scipy.interpolate.PchipInterpolator``: importing scipy.interpolate pulls in
    scipy.special, scipy.optimize and scipy.linalg, 0.15 s of CPU and 700 modules that every
    cold ``tactile-sensor model sweep`` paid for thirteen anchor points. The values agree
    with SciPy's to rounding (tested). Inside [x[0], x[-1]] only: the caller clamps.
    """

    def __init__(self, x: np.ndarray, y: np.ndarray) -> None:
        h = np.diff(x)
        m = np.diff(y) / h                                   # secant slopes
        d = np.zeros_like(y)
        # interior: weighted harmonic mean of the secants, 0 at a local extremum
        w1, w2 = 2.0 * h[1:] + h[:-1], h[1:] + 2.0 * h[:-1]
        same = (np.sign(m[:-1]) * np.sign(m[1:])) > 0
        # a secant near zero makes its term overflow to inf and the mean 0, SciPy's limit
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            harmonic = (w1 + w2) / (w1 / m[:-1] + w2 / m[1:])
        d[1:-1] = np.where(same, harmonic, 0.0)
        d[0] = self._end_slope(h[0], h[1], m[0], m[1])
        d[-1] = self._end_slope(h[-1], h[-2], m[-1], m[-2])
        self._x, self._y, self._d = x, y, d
        self._c2 = (3.0 * m - 2.0 * d[:-1] - d[1:]) / h      # t^2 coefficient per interval
        self._c3 = (d[:-1] + d[1:] - 2.0 * m) / (h * h)      # t^3 coefficient

    @staticmethod
    def _end_slope(h0: float, h1: float, m0: float, m1: float) -> float:
        """One-sided three-point slope at an end, kept shape-preserving."""
        d = ((2.0 * h0 + h1) * m0 - h0 * m1) / (h0 + h1)
        if np.sign(d) != np.sign(m0):
            return 0.0
        if np.sign(m0) != np.sign(m1) and abs(d) > abs(3.0 * m0):
            return 3.0 * m0
        return float(d)

    def __call__(self, x: npt.ArrayLike) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        k = np.clip(np.searchsorted(self._x, x, side="right") - 1, 0, self._x.size - 2)
        t = x - self._x[k]
        return self._y[k] + t * (self._d[k] + t * (self._c2[k] + t * self._c3[k]))


_LIGHT = _Pchip(_ANCHOR_X_MM * 1e-3, 5.0 - _ANCHOR_V)


def reflectance(pigment_white: npt.ArrayLike) -> np.ndarray:
    """Diffuse reflectance at 940 nm of silicone with this white share [%] (assumption:
    linear mix between 0.08 for all-black and 0.80 for all-white pigment); element-wise, so
    a graded skin can give each sample the share under the window."""
    w = np.asarray(pigment_white, dtype=float)
    if not np.all((w >= 0.0) & (w <= 100.0)):
        bad = w[~((w >= 0.0) & (w <= 100.0))].ravel()[0]
        raise PhysicsError(f"Pigment white share {float(bad)!r} % must be in 0..100.")
    return 0.08 + (0.80 - 0.08) * w / 100.0


def _smooth_clamp(v: np.ndarray, low: float, high: float, sharpness: float = 40.0
                  ) -> np.ndarray:
    """A clamp with rounded corners (~1/sharpness V wide), like a transistor saturating."""
    s = sharpness
    return low + (np.logaddexp(0.0, s * (v - low)) - np.logaddexp(0.0, s * (v - high))) / s


@dataclass(frozen=True)
class Photoreflector:
    """Voltage [V] against photoreflector-skin distance [m] for one pigment mix."""

    pigment_white: float = 75.0
    supply_voltage: float = 5.0

    def __post_init__(self) -> None:
        reflectance(self.pigment_white)
        if not 0.0 < self.supply_voltage <= 24.0:
            raise PhysicsError(f"Supply voltage {self.supply_voltage!r} V must be in (0, 24].")

    def voltage(self, distance_m: npt.ArrayLike, white_share: npt.ArrayLike | None = None
                ) -> np.ndarray:
        """V at each distance; ``white_share`` [%] (broadcast against the distances) is the
        pigment the window sees where it differs from ``pigment_white`` (a graded skin that
        slid along the face)."""
        x = np.asarray(distance_m, dtype=float)
        if np.any(x < 0) or np.any(~np.isfinite(x)):
            raise PhysicsError("Photoreflector distances must be finite and >= 0 m (the skin "
                               "cannot pass through the module).")
        light = np.where(x >= 20e-3, 0.0, _LIGHT(np.minimum(x, 20e-3)))
        white = self.pigment_white if white_share is None else white_share
        gain = reflectance(white) / reflectance(75.0)
        scale = self.supply_voltage / 5.0
        return _smooth_clamp(self.supply_voltage - scale * gain * light, 0.0,
                             self.supply_voltage)

    def slope(self, distance_m: npt.ArrayLike, step_m: float = 1e-6) -> np.ndarray:
        """dV/dx [V/m] by central difference."""
        x = np.asarray(distance_m, dtype=float)
        return (self.voltage(x + step_m) - self.voltage(np.maximum(x - step_m, 0.0))) / (
            x + step_m - np.maximum(x - step_m, 0.0))


def _isotonic(y: np.ndarray) -> np.ndarray:
    """Least-squares non-decreasing fit (pool adjacent violators): the photoreflector's
    curve is monotone, measurement noise is not."""
    blocks: list[list[float]] = []  # [mean, weight]
    for value in y.tolist():
        blocks.append([value, 1.0])
        while len(blocks) > 1 and blocks[-2][0] > blocks[-1][0]:
            m2, w2 = blocks.pop()
            m1, w1 = blocks.pop()
            blocks.append([(m1 * w1 + m2 * w2) / (w1 + w2), w1 + w2])
    return np.concatenate([np.full(int(w), m) for m, w in blocks])


@dataclass(frozen=True)
class OpticsFit:
    """A fitted curve from measured pairs and its most linear window."""

    distance_m: np.ndarray  # sorted measurement distances
    voltage_v: np.ndarray  # smoothed, monotone voltages at them
    window_m: tuple[float, float]  # the most linear window
    slope_v_per_m: float  # straight-line fit over the window
    offset_v: float
    max_deviation_v: float  # largest deviation from that line inside the window

    def voltage(self, distance_m: npt.ArrayLike) -> np.ndarray:
        return np.interp(distance_m, self.distance_m, self.voltage_v)


def fit_optics(distance_m: npt.ArrayLike, voltage_v: npt.ArrayLike,
               window_length_m: float = 1e-3) -> OpticsFit:
    """Fit measured (distance, voltage) pairs (the paper's linear-stage experiment) with a
    monotone curve, and find the window of ``window_length_m`` where it is most linear
    (smallest worst deviation from a least-squares line relative to the window's rise, the
    usual non-linearity figure; an absolute deviation would favour flat stretches, where the
    monotone smoothing hides the noise, over the steep useful one)."""
    x = np.asarray(distance_m, dtype=float)
    v = np.asarray(voltage_v, dtype=float)
    if x.ndim != 1 or x.shape != v.shape or x.size < 4:
        raise PhysicsError("fit_optics needs two equal-length 1-D arrays of at least 4 "
                           "(distance, voltage) pairs.")
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(v))):
        raise PhysicsError("fit_optics got NaN or infinite values; drop those samples.")
    order = np.argsort(x)
    x, v = x[order], v[order]
    v_mono = _isotonic(v)
    span = float(v_mono[-1] - v_mono[0])
    if span <= 0:
        raise PhysicsError("The measured voltage does not rise with distance; check the "
                           "wiring or the distance axis.")
    best: tuple[float, int, int] | None = None
    for i in range(x.size):
        j = int(np.searchsorted(x, x[i] + window_length_m, side="right"))
        if j - i < 3 or x[j - 1] - x[i] < 0.9 * window_length_m:
            continue
        a, b = np.polyfit(x[i:j], v_mono[i:j], 1)
        if a * window_length_m < 0.1 * span:  # a flat rail is "linear" but useless
            continue
        dev = float(np.max(np.abs(v_mono[i:j] - (a * x[i:j] + b))))
        nonlinearity = dev / (a * window_length_m)
        if best is None or nonlinearity < best[0]:
            best = (nonlinearity, i, j)
    if best is None:
        raise PhysicsError(f"No window of {window_length_m * 1e3:g} mm with a usable slope "
                           "in the measurements; measure a wider distance range.")
    _, i, j = best
    a, b = np.polyfit(x[i:j], v_mono[i:j], 1)
    dev = float(np.max(np.abs(v_mono[i:j] - (a * x[i:j] + b))))
    return OpticsFit(x, v_mono, (float(x[i]), float(x[j - 1])), float(a), float(b), dev)
