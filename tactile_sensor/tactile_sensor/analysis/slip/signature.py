"""The signature slip leaves on a held object: the gripper world's object model at a fixed
grip, read through the skin's response and the sensor's noise.

``simulate`` runs ``sim.held_object.HeldObject`` (two skins' tangential springs k(d) from
the FEM, Coulomb friction with a stick state, the silicone's rate effect) at a constant
normal force on each finger and records finger A's tangential force Ft at 1 kHz, the
object's slip and the onset (the first step in which a contact slides). The normal force
the skin carries at a fixed indentation falls as the skin is sheared: the FEM array grid
gives Fz(d, s) = Fz(d, 0) - c(d) s^2 (``shear_coupling``), which is the model's only route
to a normal-force dip. ``sense`` adds the modules' noise through the layout (per-sample
force covariance) and ``band_rms`` measures a signal's content in a frequency band, so
each signature can be set against the noise in the band where it lives.

The scenario of the gripper's slip goal: the object is lifted gently (its weight eased onto
the skins over ``lift_s``, so the lift itself does not ring the stuck skins into slip) and,
``hold_s`` later, its load doubles over ``double_s``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from tactile_sensor.analysis.errors import AnalysisError
from tactile_sensor.sim.held_object import (
    STANDARD_GRAVITY_M_S2,
    HeldObject,
    LoadScript,
    ObjectSpec,
    RateModel,
)
from tactile_sensor.sim.skin_shear import TangentialStiffness

#: The stream's sample rate [Hz] (the firmware's ADC).
SAMPLE_RATE_HZ = 1000.0


@dataclass(frozen=True)
class Scenario:
    """An object held at a fixed normal force ``grip_n`` per finger [N], lifted over
    ``lift_s`` and its load doubled over ``double_s`` from ``hold_s`` after the lift
    (``double``: False holds the weight only)."""

    mass_kg: float
    friction_static: float
    friction_kinetic: float
    grip_n: float
    lift_s: float = 0.3
    hold_s: float = 0.5
    double_s: float = 0.1
    after_s: float = 0.4
    double: bool = True

    @property
    def weight_n(self) -> float:
        return self.mass_kg * STANDARD_GRAVITY_M_S2

    @property
    def double_at_s(self) -> float:
        """When the load starts doubling, from the lift [s]."""
        return self.lift_s + self.hold_s

    @property
    def duration_s(self) -> float:
        return self.double_at_s + self.double_s + self.after_s

    def load(self) -> LoadScript:
        """The pull along the fingers: -weight at the lift (the support's share) eased to 0,
        then +weight over ``double_s``."""
        w = self.weight_n
        times = [0.0, self.lift_s, self.double_at_s, self.double_at_s + self.double_s]
        forces = [-w, 0.0, 0.0, w if self.double else 0.0]
        return LoadScript(tuple(times), tuple(forces))


def least_grip_n(load_n: float, friction_static: float) -> float:
    """The least normal force per finger [N] two skins need to hold ``load_n`` statically."""
    return load_n / (2.0 * friction_static)


@dataclass(frozen=True)
class SlipTrace:
    """One run at 1 kHz: finger A's tangential force [N] (the skin's, + toward the tips),
    its normal force [N] with the shear's coupling, the object's slip [m]; ``onset_s``:
    the first sample in which a contact slides (None: it stuck throughout)."""

    t_s: np.ndarray
    ft_n: np.ndarray
    fn_n: np.ndarray
    slip_m: np.ndarray
    onset_s: float | None
    dropped: bool


def simulate(scenario: Scenario, stiffness: TangentialStiffness, indentation_m: float,
             coupling_n_per_m2: float = 0.0,
             rate: Callable[[], RateModel] | None = None) -> SlipTrace:
    """Run ``scenario`` on skins of ``stiffness`` pressed ``indentation_m`` deep."""
    if not (math.isfinite(scenario.grip_n) and scenario.grip_n > 0):
        raise AnalysisError(f"The grip ({scenario.grip_n!r} N) must be a finite force > 0.")
    spec = ObjectSpec(scenario.mass_kg, scenario.friction_static, scenario.friction_kinetic,
                      scenario.load())
    held = HeldObject(spec, stiffness, rate)
    k = stiffness(indentation_m)
    n = round(scenario.duration_s * SAMPLE_RATE_HZ) + 1
    t = np.arange(n) / SAMPLE_RATE_HZ
    ft, slip = np.zeros(n), np.zeros(n)
    normal = (scenario.grip_n, scenario.grip_n)
    depth = (indentation_m, indentation_m)
    onset: float | None = None
    held.step(0.0, normal, depth)
    held.lift()
    for i, ti in enumerate(t.tolist()):
        state = held.step(ti, normal, depth)
        ft[i], slip[i] = state.force_a_n, state.slip_m
        if onset is None and not all(c.stuck for c in held.contacts):
            onset = ti
        if onset is None and i and slip[i] != slip[i - 1]:
            onset = ti  # slid and stuck again within one sample
    fn = scenario.grip_n - coupling_n_per_m2 * (ft / k) ** 2
    return SlipTrace(t, ft, fn, slip, onset, held.dropped)


def shear_coupling(grid: Any, indentation_m: float) -> float:
    """c(d) [N/m^2] of Fz(d, s) = Fz(d, 0) - c s^2 on the grid's +x path at the indentation
    level nearest ``indentation_m`` (least squares over its shear levels)."""
    d = np.asarray(grid.indentation_m, float)
    step = np.asarray(grid.step, int)
    pressed = step > 0
    if not pressed.any():
        raise AnalysisError("The array grid holds no pressed point; recompute it.")
    near = step[pressed][np.argmin(np.abs(d[pressed] - indentation_m))]
    direction = np.asarray(grid.direction, int)
    rows = (step == near) & ((direction == 0) | (np.asarray(grid.level, int) == 0))
    s2 = np.asarray(grid.shear_x_m, float)[rows] ** 2
    fz = np.asarray(grid.force_n, float)[rows]
    design = np.column_stack([np.ones(s2.size), s2])
    (_, slope), *_ = np.linalg.lstsq(design, fz, rcond=None)
    return float(-slope)


def sense(trace: SlipTrace, covariance_n2: np.ndarray, rng: np.random.Generator
          ) -> tuple[np.ndarray, np.ndarray]:
    """(Ft, Fn) as the layout reads them at 1 kHz: the trace plus Gaussian noise of the
    per-sample covariance ``covariance_n2`` ((Ft, Fn) 2 x 2 [N^2])."""
    cov = np.asarray(covariance_n2, float)
    noise = rng.multivariate_normal(np.zeros(2), cov, size=trace.t_s.size)
    return trace.ft_n + noise[:, 0], trace.fn_n + noise[:, 1]


def band_rms(signal: np.ndarray, band_hz: tuple[float, float],
             window: slice | None = None) -> float:
    """RMS [signal units] of ``signal`` (1 kHz) band-passed to ``band_hz`` (4th-order
    Butterworth, forward and backward: no delay) over ``window`` of its samples."""
    from scipy.signal import butter, sosfiltfilt

    low, high = band_hz
    nyquist = SAMPLE_RATE_HZ / 2.0
    if not 0.0 < low < high < nyquist:
        raise AnalysisError(f"A band ({low:g}, {high:g}) Hz must lie inside (0, {nyquist:g}) "
                            "Hz with its low edge first.")
    sos = butter(4, [low / nyquist, high / nyquist], btype="bandpass", output="sos")
    part = sosfiltfilt(sos, np.asarray(signal, float))
    part = part[window] if window is not None else part
    return float(np.sqrt(np.mean(part**2)))


def white_band_rms(sigma: float, band_hz: tuple[float, float]) -> float:
    """RMS of white noise of per-sample ``sigma`` in ``band_hz`` (its share 2 df / fs)."""
    return sigma * math.sqrt(2.0 * (band_hz[1] - band_hz[0]) / SAMPLE_RATE_HZ)
