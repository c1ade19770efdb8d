"""The rate check's noise floor: the offline bench run and the exact model on it.

The exact model is only a floor if it is exact: without noise its error must vanish in
every row, and it must need the play's true state (the output alone cannot show it).
"""

from __future__ import annotations

import numpy as np
import pytest

from tactile_sensor.analysis.errors import SegmentError
from tactile_sensor.analysis.rate.evaluation import phase_errors
from tactile_sensor.analysis.rate.floor import (
    bench_world,
    exact_force,
    simulate_run,
    stage_play_lag,
    tracker_play_lag,
)
from tactile_sensor.analysis.rate.record import HOLD, LOADING, OUTSIDE, UNLOADING, labels_from_knots
from tactile_sensor.physics.params import PhysicsParams
from tactile_sensor.sim.adc_device import AdcNoise
from tactile_sensor.sim.profiles import LoadProfile
from tactile_sensor.sim.skin_response import TabulatedSkin

QUIET = AdcNoise(white_v=0.0, drift_v=0.0)
PHYSICS = PhysicsParams()  # Prony 0.05 @ 0.1 s + 0.04 @ 1.5 s, output play 0.065 mm
CHECK = LoadProfile(depth_m=3e-3, speeds_m_s=(0.3e-3, 3e-3, 20e-3), cycles=1, hold_s=2.0,
                    rest_s=1.0)


def skin() -> TabulatedSkin:
    """A smooth skin like the FEM's: 7 N and 0.5 V of output at 3 mm (no FEM sweep)."""
    d = np.linspace(0.0, 3e-3, 31)
    return TabulatedSkin(d, 7.0 * (d / 3e-3) ** 1.3, 2.5 - 0.5 * (d / 3e-3) ** 0.9)


def run(seed: int, noise: AdcNoise | None = None, **kwargs):
    return simulate_run(bench_world(CHECK, skin(), PHYSICS), skin(), PHYSICS, seed, noise,
                        **kwargs)


@pytest.fixture(scope="module")
def quiet_run():
    """No noise and no filter: only the 12-bit quantisation (1.2 mV steps) is left."""
    return run(0, QUIET, filter_name="none")


def test_without_noise_the_exact_model_has_no_error_in_any_row(quiet_run):
    rows = phase_errors(quiet_run.record, quiet_run.exact_force_n, quiet_run.exact_force_n)
    assert len(rows) == 9
    assert max(r.rate_model_rmse_n for r in rows) < 0.02
    assert 7.0 < quiet_run.full_scale_n < 7.3  # 7 N relaxed at 3 mm, plus the rate force


def test_the_default_filters_corners_cost_at_20_mm_s_only():
    """The causal linear Savitzky-Golay overshoots where the slope jumps (~slope x window
    / 8): a few mV at 20 mm/s, part of that speed's floor; nothing at 0.3 mm/s."""
    quiet = run(0, QUIET)
    rows = {(r.speed_mm_s, r.phase): r.rate_model_rmse_n
            for r in phase_errors(quiet.record, quiet.exact_force_n, quiet.exact_force_n)}
    assert rows[(20.0, "unloading")] > 0.03
    assert rows[(0.3, "loading")] < 0.02 and rows[(0.3, "unloading")] < 0.02


def test_the_exact_model_needs_the_plays_true_state(quiet_run):
    """Without the play's lag, the estimate misses the force the output cannot see on
    loading: slope x play = ~2.7 N/mm x 0.065 mm near full depth."""
    rec = quiet_run.record
    blind = exact_force(skin(), PHYSICS, rec.t_s, rec.output_v, np.zeros(rec.t_s.size))
    rows = {(r.speed_mm_s, r.phase): r for r in phase_errors(rec, blind, blind)}
    assert rows[(3.0, "loading")].rate_model_rmse_n > 0.1


def test_the_output_alone_shows_the_play_late_after_each_reversal(quiet_run):
    """The driver's tracker switches branch once the output has fallen by its band, not
    when the probe turned: unloading errs more than with the play's true state, more so
    at 0.3 mm/s (the band takes longer to cross), and loading errs as little."""
    rec = quiet_run.record
    exact = {(r.speed_mm_s, r.phase): r.rate_model_rmse_n
             for r in phase_errors(rec, quiet_run.exact_force_n, quiet_run.exact_force_n)}
    tracked = {(r.speed_mm_s, r.phase): r.rate_model_rmse_n
               for r in phase_errors(rec, quiet_run.output_only_force_n,
                                     quiet_run.output_only_force_n)}
    assert tracked[(0.3, "unloading")] > exact[(0.3, "unloading")] + 0.01
    assert tracked[(0.3, "loading")] == pytest.approx(exact[(0.3, "loading")], abs=0.005)


def test_the_play_lag_from_the_stage_is_the_play_while_loading_and_none_after_reversal():
    d = np.concatenate((np.linspace(0.0, 1e-3, 101), np.linspace(1e-3, 0.0, 101)[1:]))
    lag = stage_play_lag(PHYSICS, d)
    assert lag[100] == pytest.approx(PHYSICS.output_play)  # top of the ramp
    assert lag[-1] == pytest.approx(0.0)
    assert np.all((lag >= -1e-15) & (lag <= PHYSICS.output_play + 1e-15))


def test_the_tracker_lag_is_the_whole_play_while_loading():
    t = np.arange(0.0, 2.0, 1e-3)
    out = np.where(t < 1.0, 0.5 * t, 0.5 * (2.0 - t))  # up to 0.5 V and down again
    lag = tracker_play_lag(PHYSICS, t, out, band_v=0.02)
    assert lag[500] == PHYSICS.output_play
    assert lag[-1] == 0.0


def test_the_noise_sets_a_floor_near_the_goal():
    """With the mock's noise (39 mV white) the exact model errs by ~0.05 N (1.5 % of full
    scale is ~0.10 N): what a fit's table must be read against."""
    noisy = run(3)
    rows = phase_errors(noisy.record, noisy.exact_force_n, noisy.exact_force_n)
    errors = np.array([r.rate_model_rmse_n for r in rows])
    assert 0.02 < np.median(errors) < 0.1


def test_labels_follow_the_profiles_corners():
    t = np.arange(0.0, CHECK.duration_s, 1e-3)
    speed, phase = labels_from_knots(t, CHECK.knots()[0], CHECK.speeds_m_s)
    loading_3 = np.count_nonzero((speed == 3.0) & (phase == LOADING))
    assert loading_3 == pytest.approx(1000, abs=2)  # 3 mm at 3 mm/s
    assert np.count_nonzero((speed == 20.0) & (phase == HOLD)) == pytest.approx(2000, abs=2)
    assert np.count_nonzero((speed == 0.3) & (phase == UNLOADING)) == pytest.approx(10000, abs=2)
    assert np.all(np.isnan(speed[phase == OUTSIDE]))
    assert phase[0] == OUTSIDE


def test_labels_refuse_too_few_corners():
    with pytest.raises(SegmentError, match="cannot hold 3 press"):
        labels_from_knots(np.arange(10.0), np.arange(5.0), (1e-3, 2e-3, 3e-3))


@pytest.mark.parametrize("cycles, rest_s", [(2, 1.0), (1, 0.5)])
def test_an_offline_run_needs_one_cycle_per_speed_and_a_rest_for_the_tare(cycles, rest_s):
    profile = LoadProfile(depth_m=3e-3, speeds_m_s=(1e-3,), cycles=cycles, hold_s=0.0,
                          rest_s=rest_s)
    with pytest.raises(SegmentError, match="one cycle per speed and a rest"):
        bench_world(profile, skin(), PHYSICS)


def test_the_exact_model_refuses_a_skin_whose_output_does_not_grow():
    d = np.linspace(0.0, 3e-3, 4)
    flat = TabulatedSkin(d, 7.0 * d / 3e-3, np.array([2.5, 2.4, 2.4, 2.3]))
    with pytest.raises(SegmentError, match="does not grow with indentation"):
        exact_force(flat, PHYSICS, np.arange(3.0), np.zeros(3), np.zeros(3))
