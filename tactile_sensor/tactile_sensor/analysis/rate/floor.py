"""The rate check's noise floor: the mock bench run offline, and the exact model on it.

Why: the calibration's goal (rate-aware error at most half the static one and at most
1.5 % of full scale, in every speed and phase) is scored on recordings whose output carries the
paper's noise (31.5 dB: 39 mV white at the ADC). To tell a fit's error from the noise's,
this module runs the same pieces the mock hardware and the driver run (the FEM skin's
world, the Prony terms and output play of the physics parameters, the ADC's noise and
quantisation, the driver's filter and tare) without ROS, and scores the *exact* model
(the true skin inverted, the true Prony terms) on them, with the play's true state and
with the state the driver's tracker reads from the output. Its error is what the noise
and the filter leave an unbiased estimate when nothing is fitted (an estimator that
shrinks its slope where data is noisy can do better in places).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from tactile_sensor.physics.params import PhysicsParams
from tactile_sensor.physics.viscoelastic import RateDependentForce
from tactile_sensor.sensing.filters import DEFAULT_FILTER, make_filter
from tactile_sensor.sensing.rate_calibration import Play
from tactile_sensor.sim.adc_device import AdcNoise, AdcSampler
from tactile_sensor.sim.bench_world import BenchWorld, play
from tactile_sensor.sim.profiles import LoadProfile
from tactile_sensor.sim.skin_response import TabulatedSkin

from ..alignment import Aligned
from ..errors import SegmentError
from ..metrics import baseline, peak_values
from ..segmentation import segment
from .grid import TRACKER_SMOOTHING_HZ, tracker_band_v
from .history import loading_history
from .record import RateRecord, record_from_segmentation

TARE_WINDOW_S = (0.2, 0.9)  # inside the first rest, after the filter has filled


@dataclass(frozen=True)
class OfflineRun:
    """One simulated bench run: the record the analysis builds from a bag of it (aligned,
    segmented, baseline removed), and the forces the exact model estimates from the same
    output: knowing the play's state, and reading it from the output alone as the driver
    must."""

    record: RateRecord
    exact_force_n: np.ndarray  # with the play's true state (from the stage)
    output_only_force_n: np.ndarray  # with the play's state from the driver's tracker
    reference_mm_s: float  # the analysis' reference speed (nearest 1 mm/s)
    full_scale_n: float  # its presses' median peak force, as the analysis reads it


def bench_world(profile: LoadProfile, skin: TabulatedSkin, physics: PhysicsParams,
                rate_hz: float = 1000.0) -> BenchWorld:
    """The mock's world for ``profile``: built once, sampled by every seed's run."""
    if profile.cycles != 1 or profile.rest_s < TARE_WINDOW_S[1]:
        raise SegmentError(f"an offline run needs one cycle per speed and a rest of at least "
                           f"{TARE_WINDOW_S[1]} s for the tare; got {profile.cycles} cycle(s) "
                           f"and {profile.rest_s} s.")
    return BenchWorld(profile, skin, RateDependentForce.from_params(physics), grid_hz=rate_hz,
                      output_play_m=physics.output_play)


def simulate_run(world: BenchWorld, skin: TabulatedSkin, physics: PhysicsParams,
                 seed: int, noise: AdcNoise | None = None, adc_bits: int = 12,
                 vref_v: float = 5.0, rate_hz: float = 1000.0,
                 filter_name: str = DEFAULT_FILTER,
                 filter_params: Mapping[str, Any] | None = None) -> OfflineRun:
    """The run of ``world`` (from ``bench_world`` with the same skin and physics) as the
    driver outputs it and the analysis reads it, with the exact model's estimates."""
    t = np.arange(0.0, world.duration_s, 1.0 / rate_hz)
    counts = AdcSampler(rate_hz, noise, adc_bits, vref_v, rng=seed).counts(
        world.photoreflector_voltage(t))[:, 0]
    volts = counts * (vref_v / ((1 << adc_bits) - 1))
    filt = make_filter(filter_name, rate_hz, filter_params)
    filtered = np.array([filt.update(v) for v in volts.tolist()])
    tare = (t >= TARE_WINDOW_S[0]) & (t < TARE_WINDOW_S[1])
    aligned = Aligned(t_s=t, output_v=float(np.mean(filtered[tare])) - filtered,
                      force_n=np.asarray(world.force_n(t), dtype=float),
                      indentation_m=np.asarray(world.indentation_m(t), dtype=float),
                      rate_hz=rate_hz, start_ns=0, force_flipped=False)
    seg = segment(aligned)
    sig = baseline(aligned, seg)
    record = record_from_segmentation(sig.t_s, sig.output_v, sig.force_n, seg)
    exact = exact_force(skin, physics, t, sig.output_v,
                        stage_play_lag(physics, sig.indentation_m))
    tracked = exact_force(skin, physics, t, sig.output_v,
                          tracker_play_lag(physics, t, sig.output_v, tracker_band_v(record)))
    peaks = [peak_values(sig, seg.cycles[i]) for i in seg.speed_groups[seg.reference_key]]
    return OfflineRun(record, exact, tracked, float(seg.reference_key),
                      float(np.median([f for _, f in peaks])))


def exact_force(skin: TabulatedSkin, physics: PhysicsParams, t_s: np.ndarray,
                output_v: np.ndarray, play_lag_m: np.ndarray) -> np.ndarray:
    """The true skin's output inverted to the indentation the output shows, plus the
    play's lag [m] at each sample (``stage_play_lag`` or ``tracker_play_lag``), then the
    true elastic force and Prony terms."""
    table_d, table_f, table_v = skin.table()
    table_out = table_v[0] - table_v
    if np.any(np.diff(table_out) <= 0):
        raise SegmentError("the skin's output does not grow with indentation; the exact "
                           "model needs an invertible skin table.")
    seen = _linear_beyond_ends(output_v, table_out, table_d)
    elastic = _linear_beyond_ends(seen + play_lag_m, table_d, table_f)
    return RateDependentForce.from_params(physics).force_history(t_s, elastic)


def stage_play_lag(physics: PhysicsParams, indentation_m: np.ndarray) -> np.ndarray:
    """The play's true lag [m], from the stage's indentation: what the output cannot show
    (after a reversal it stays still until the probe has moved by the play)."""
    return indentation_m - play(indentation_m, physics.output_play)


def tracker_play_lag(physics: PhysicsParams, t_s: np.ndarray, output_v: np.ndarray,
                     band_v: float, smoothing_hz: float = TRACKER_SMOOTHING_HZ) -> np.ndarray:
    """The play's lag [m] as an estimator reading the output alone can know it: the whole
    play where the driver's direction tracker says loading, none where it says unloading."""
    loading = loading_history(Play((0.0,), band_v, smoothing_hz), t_s, output_v)
    return physics.output_play * loading.astype(float)


def _linear_beyond_ends(x: np.ndarray, xp: np.ndarray, fp: np.ndarray) -> np.ndarray:
    """``np.interp`` continued with the end segments' slopes. Noise carries the output past
    both ends of the table (at rest, and in a hold at full depth); clamping there would
    bias the exact model by ~0.4 sigma x slope, an error of the clamp, not of the noise."""
    y = np.interp(x, xp, fp)
    low, high = x < xp[0], x > xp[-1]
    y[low] = fp[0] + (x[low] - xp[0]) * (fp[1] - fp[0]) / (xp[1] - xp[0])
    y[high] = fp[-1] + (x[high] - xp[-1]) * (fp[-1] - fp[-2]) / (xp[-1] - xp[-2])
    return y
