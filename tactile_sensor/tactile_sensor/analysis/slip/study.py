"""One object through the study at one bandwidth: held at the grip the detector allows, its
load doubled, each signature set against the noise, the detector's delay and its false
alarms at rest.

The object is held at a fixed grip on the skins (normal force per finger, at the
indentation the FEM curve gives it): the least grip at which its weight rests outside the
detector's alarm (``held_grip_n``); then its load doubles (``signature.Scenario``). The
stuck twin runs the same load with a friction no load overcomes: what the shear would
have done without slip. False alarms at rest: ``REST_S`` of the weight held still at that
grip with the sensor's noise. The detector's friction is the kinetic one: what a hold
learns from the level at which the shear stopped growing at an earlier slip.

Signatures, each against its noise at the bandwidth B:
- the shear that stops growing: the slip run's Ft departs from the twin's (which would
  have kept following the load); ``plateau_ms`` is when that departure, low-passed at B,
  first exceeds k sigma_t. A detector would need the load's course to use it directly; it
  is the earliest any reading of the plateau can see it;
- the normal force's change: the largest |Fn| difference between the runs over the 50 ms
  after the onset, from the FEM's shear coupling, against sigma_n(B);
- vibration: Ft's content in each band of ``VIBRATION_BANDS_HZ`` over the 100 ms after the
  onset (noise-free, the twin's subtracted), against the white noise's content in the band.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from tactile_sensor.analysis.slip.detector import MarginDetector, detection_delay_s
from tactile_sensor.analysis.slip.resolution import Resolution, force_covariance, resolution
from tactile_sensor.analysis.slip.signature import (
    SAMPLE_RATE_HZ,
    Scenario,
    band_rms,
    least_grip_n,
    sense,
    simulate,
    white_band_rms,
)
from tactile_sensor.physics.output_noise import SAMPLE_NOISE_V
from tactile_sensor.sim.held_object import RateModel
from tactile_sensor.sim.skin_shear import TangentialStiffness

#: Bands [Hz] in which the slip's vibration is set against the noise: the object's own
#: ring (a few to tens of Hz), the reflex's band and the fast-adapting receptors' band up to
#: the 1 kHz stream's Nyquist frequency.
VIBRATION_BANDS_HZ = ((5.0, 50.0), (50.0, 200.0), (200.0, 490.0))
#: Window after the onset [s] over which the normal force's change is taken.
DIP_WINDOW_S = 0.05
#: Window after the onset [s] over which the vibration is measured.
VIBRATION_WINDOW_S = 0.1


@dataclass(frozen=True)
class BandwidthFigures:
    """One object held with the detector at one bandwidth: the grip the detector lets the
    hold keep, what it saw at rest and of the slip, and each signature against its noise."""

    resolution: Resolution
    grip_n: float
    indentation_m: float
    threshold_n: float
    least_margin_n: float
    #: Alarms over ``REST_S`` of the weight held at that grip (false alarms at rest).
    rest_alarms: int
    onset_s: float | None
    #: From the onset to the alarm [s], counted from the load's doubling on (None: never).
    delay_s: float | None
    plateau_s: float | None
    dip_n: float
    vibration_snr: tuple[float, ...]

    @property
    def dip_sigmas(self) -> float:
        return self.dip_n / self.resolution.sigma_n[2]


#: How long the weight is held at rest for the false-alarm count [s].
REST_S = 20.0
#: Friction that no load here overcomes: the stuck twin's, which keeps following the load.
STUCK_FRICTION = 1e3


def _lowpass(x: np.ndarray, bandwidth_hz: float) -> np.ndarray:
    from scipy.signal import butter, lfilter

    b, a = butter(2, bandwidth_hz / (SAMPLE_RATE_HZ / 2))
    return lfilter(b, a, x)


def _first_over(t: np.ndarray, x: np.ndarray, level: float, from_s: float) -> float | None:
    hits = np.flatnonzero((np.abs(x) > level) & (t >= from_s))
    return float(t[hits[0]]) if hits.size else None


def _window(t: np.ndarray, start_s: float, length_s: float) -> slice:
    i = int(np.searchsorted(t, start_s))
    return slice(i, i + round(length_s * SAMPLE_RATE_HZ))


@dataclass(frozen=True)
class Skin:
    """What the study needs of the skin: tangential stiffness, the normal curve (grip ->
    indentation), the layout's sensitivity and the shear coupling at an indentation."""

    stiffness: TangentialStiffness
    indentation_of: Callable[[float], float]
    sensitivity_at: Callable[[float], np.ndarray]
    coupling_at: Callable[[float], float] = lambda _d: 0.0
    rate: Callable[[], RateModel] | None = None
    sample_noise_v: float = SAMPLE_NOISE_V


def held_grip_n(scenario: Scenario, res: Resolution, learned: float = 1.0) -> float:
    """The least grip per finger [N] at which the weight rests outside the detector's alarm
    (its least margin) for a hold that believes the friction ``learned`` x the kinetic one
    (above the static least grip by construction: the margin is > 0)."""
    mu = learned * scenario.friction_kinetic
    detector = MarginDetector.for_resolution(mu, res)
    return (0.5 * scenario.weight_n + detector.least_margin_n()) / mu


@dataclass(frozen=True)
class HeldRun:
    """``scenario`` at the grip the detector at a bandwidth allows, with what that grip
    gives: its indentation, the resolution there, the detector and the per-sample (Ft, Fn)
    noise covariance [N^2]."""

    run: Scenario
    depth_m: float
    res: Resolution
    detector: MarginDetector
    cov: np.ndarray

    @classmethod
    def at(cls, scenario: Scenario, skin: Skin, bandwidth_hz: float,
           false_alarms_per_hour: float = 1.0, learned: float = 1.0) -> HeldRun:
        """The hold and its detector believe the friction ``learned`` x the kinetic one.
        The sensitivity is taken at the least grip's indentation to find the grip, then
        again at the grip's own."""
        first_d = skin.indentation_of(least_grip_n(scenario.weight_n,
                                                   scenario.friction_static))
        first = resolution(skin.sensitivity_at(first_d), bandwidth_hz, 1.0,
                           false_alarms_per_hour, skin.sample_noise_v)
        run = replace(scenario, grip_n=held_grip_n(scenario, first, learned))
        depth = skin.indentation_of(run.grip_n)
        sensitivity = skin.sensitivity_at(depth)
        res = resolution(sensitivity, bandwidth_hz, run.grip_n, false_alarms_per_hour,
                         skin.sample_noise_v)
        cov = force_covariance(sensitivity, skin.sample_noise_v)[np.ix_([0, 2], [0, 2])]
        detector = MarginDetector.for_resolution(learned * run.friction_kinetic, res)
        return cls(run, depth, res, detector, cov)


def evaluate(scenario: Scenario, skin: Skin, bandwidth_hz: float, rng: np.random.Generator,
             false_alarms_per_hour: float = 1.0, learned: float = 1.0) -> BandwidthFigures:
    """``scenario`` held at the grip the detector at ``bandwidth_hz`` allows (its own grip
    ignored), then its load doubled (module doc); ``learned``: the friction the hold and
    its detector believe, over the true kinetic one."""
    held = HeldRun.at(scenario, skin, bandwidth_hz, false_alarms_per_hour, learned)
    run, depth, res, detector, cov = held.run, held.depth_m, held.res, held.detector, held.cov
    coupling = skin.coupling_at(depth)
    slip = simulate(run, skin.stiffness, depth, coupling, skin.rate)
    stuck = simulate(replace(run, friction_static=STUCK_FRICTION,
                             friction_kinetic=STUCK_FRICTION), skin.stiffness, depth, coupling,
                     skin.rate)
    rest = _rest_alarms(detector, run, cov, rng)
    onset, t = slip.onset_s, slip.t_s
    delay = plateau = None
    dip, snr = 0.0, ()
    if onset is not None:
        sensed = sense(slip, cov, rng)
        delay = detection_delay_s(detector, t, *sensed, onset, run.double_at_s)
        seen = _first_over(t, _lowpass(stuck.ft_n - slip.ft_n, bandwidth_hz),
                           res.k * res.tangential_n, onset)
        plateau = None if seen is None else seen - onset
        dip = float(np.abs(slip.fn_n - stuck.fn_n)[_window(t, onset, DIP_WINDOW_S)].max())
        after = _window(t, onset, VIBRATION_WINDOW_S)
        sigma_t = math.sqrt(cov[0, 0])
        snr = tuple(band_rms(slip.ft_n - stuck.ft_n, band, after)
                    / white_band_rms(sigma_t, band) for band in VIBRATION_BANDS_HZ)
    return BandwidthFigures(res, run.grip_n, depth, detector.threshold_n,
                            detector.least_margin_n(), rest, onset, delay, plateau, dip, snr)


def _rest_alarms(detector: MarginDetector, run: Scenario, cov: np.ndarray,
                 rng: np.random.Generator) -> int:
    """Alarms over ``REST_S`` of the weight held still at the run's grip, with the noise."""
    n = int(REST_S * SAMPLE_RATE_HZ)
    noise = rng.multivariate_normal(np.zeros(2), cov, size=n)
    return detector.alarms(0.5 * run.weight_n + noise[:, 0], run.grip_n + noise[:, 1])


def ring_hz(skin: Skin, mass_kg: float, indentation_m: float) -> float:
    """The object's own frequency on the two stuck skins [Hz]."""
    return math.sqrt(2.0 * skin.stiffness(indentation_m) / mass_kg) / (2.0 * math.pi)


def as_row(scenario: Scenario, fig: BandwidthFigures) -> dict[str, Any]:
    """The figures of one object at one bandwidth as a flat row (tables and results)."""
    s = scenario
    row: dict[str, Any] = {
        "mass_kg": s.mass_kg, "friction_static": s.friction_static,
        "friction_kinetic": s.friction_kinetic, "double_s": s.double_s,
        "bandwidth_hz": fig.resolution.bandwidth_hz, "grip_n": fig.grip_n,
        "grip_over_least_doubled": fig.grip_n / least_grip_n(2 * s.weight_n,
                                                             s.friction_static),
        "indentation_mm": fig.indentation_m * 1e3,
        "sigma_ft_n": fig.resolution.tangential_n, "sigma_fn_n": fig.resolution.sigma_n[2],
        "threshold_n": fig.threshold_n, "least_margin_n": fig.least_margin_n,
        "rest_alarms": fig.rest_alarms,
        "onset_after_doubling_ms": None if fig.onset_s is None else
        (fig.onset_s - s.double_at_s) * 1e3,
        "delay_ms": None if fig.delay_s is None else fig.delay_s * 1e3,
        "plateau_ms": None if fig.plateau_s is None else fig.plateau_s * 1e3,
        "dip_mn": fig.dip_n * 1e3, "dip_sigmas": fig.dip_sigmas,
    }
    for band, value in zip(VIBRATION_BANDS_HZ, fig.vibration_snr, strict=False):
        row[f"vibration_snr_{band[0]:g}_{band[1]:g}hz"] = value
    return row


def example_trace(scenario: Scenario, skin: Skin, bandwidth_hz: float,
                  rng: np.random.Generator) -> dict[str, np.ndarray]:
    """One run for a figure, as columns of equal length: time from the load's doubling
    [s], finger A's true and sensed Ft [N], mu_k Fn [N], the detector's filtered margin and
    threshold [N], the slip [mm], the onset and first alarm times [s] (repeated)."""
    held = HeldRun.at(scenario, skin, bandwidth_hz)
    run, detector = held.run, held.detector
    trace = simulate(run, skin.stiffness, held.depth_m, skin.coupling_at(held.depth_m),
                     skin.rate)
    ft, fn = sense(trace, held.cov, rng)
    start = int(np.searchsorted(trace.t_s, run.double_at_s))
    alarm = detector.first_alarm(ft, fn, start)
    n = trace.t_s.size
    return {"t_s": trace.t_s - run.double_at_s, "ft_true_n": trace.ft_n, "ft_sensed_n": ft,
            "limit_n": run.friction_kinetic * trace.fn_n, "margin_n": detector.margin(ft, fn),
            "threshold_n": np.full(n, detector.threshold_n), "slip_mm": trace.slip_m * 1e3,
            "onset_s": np.full(n, np.nan if trace.onset_s is None else
                               trace.onset_s - run.double_at_s),
            "alarm_s": np.full(n, np.nan if alarm is None else
                               trace.t_s[alarm] - run.double_at_s)}
