"""The phase lag measures lateness, not the shape of the output: on the mock bench's own
physics (FEM skin, Prony force, output play) the analysis must give

- no lag when the output is a static function of the indentation (play 0), although
  the FEM output and force curves have different shapes (a mid-level crossing read
  that shape difference as a lag of ~0.05 mm / speed);
- a lag of play / speed with a play, falling ten-fold per ten-fold speed, as the paper's;
- low hysteresis with the default play (the paper: "nearly identical for loading and
  unloading").

Noise-free signals straight from ``BenchWorld``, so every tolerance is about the method.
"""

from __future__ import annotations

import numpy as np
import pytest

from tactile_sensor.analysis import metrics as m
from tactile_sensor.analysis.alignment import Aligned
from tactile_sensor.analysis.segmentation import segment
from tactile_sensor.physics.params import PhysicsParams
from tactile_sensor.physics.viscoelastic import RateDependentForce
from tactile_sensor.sim.bench_world import BenchWorld
from tactile_sensor.sim.profiles import LoadProfile
from tactile_sensor.sim.skin_response import default_skin

SPEEDS_MM_S = (0.1, 1.0, 10.0)
RATE_HZ = 1000.0


@pytest.fixture(scope="module")
def skin():
    return default_skin()


def measure(skin, play_m: float) -> tuple[dict[str, float], dict[str, float]]:
    """(lag [s], hysteresis [% FS]) per speed key for one cycle at each paper speed."""
    profile = LoadProfile(depth_m=0.003, speeds_m_s=tuple(v * 1e-3 for v in SPEEDS_MM_S),
                          cycles=1, hold_s=0.0, rest_s=1.0)
    world = BenchWorld(profile, skin, RateDependentForce.from_params(PhysicsParams()),
                       output_play_m=play_m)
    t = np.arange(0.0, world.duration_s, 1.0 / RATE_HZ)
    volts = world.photoreflector_voltage(t)
    aligned = Aligned(t_s=t, output_v=volts[0] - volts, force_n=world.force_n(t),
                      indentation_m=world.indentation_m(t), rate_hz=RATE_HZ, start_ns=0,
                      force_flipped=False)
    seg = segment(aligned)
    sig = m.baseline(aligned, seg)
    lags, hyst = {}, {}
    for key, members in seg.speed_groups.items():
        group = [seg.cycles[i] for i in members]
        peaks = np.array([m.peak_values(sig, c) for c in group])
        lags[key] = m.phase_lag(sig, group, RATE_HZ)
        h = m.hysteresis(sig, group, float(peaks[0, 1]), float(peaks[0, 0]))
        hyst[key] = h.pct_fs if h else float("nan")
    assert sorted(lags, key=float) == ["0.1", "1.0", "10.0"]
    return lags, hyst


@pytest.fixture(scope="module")
def static(skin):
    return measure(skin, 0.0)


def test_static_output_has_no_lag_at_any_speed(static):
    lags, hyst = static
    # as indentation: < 10 µm (the paper's lags are 50-70 µm). At 10 mm/s the ramp
    # (0.3 s) is as short as the fast Prony time (0.1 s), which reshapes the force's own
    # foot by ~30 µm: a true effect of the force, allowed there.
    for key, bound_m in (("0.1", 1e-5), ("1.0", 1e-5), ("10.0", 4e-5)):
        assert abs(lags[key] * float(key) * 1e-3) < bound_m, (key, lags[key])
    assert hyst["1.0"] < 3.0  # only the viscoelastic force loop remains


def test_play_gives_a_lag_of_play_over_speed(skin, static):
    play_m = 1e-4
    lags, _ = measure(skin, play_m)
    for key, lag in lags.items():
        expected = play_m / (float(key) * 1e-3)
        assert lag - static[0][key] == pytest.approx(expected, rel=0.2), (key, lag)


def test_default_play_meets_the_papers_lags_with_low_hysteresis(skin):
    lags, hyst = measure(skin, PhysicsParams().output_play)
    paper = {"0.1": 0.706, "1.0": 0.062, "10.0": 0.005}
    assert lags["0.1"] > lags["1.0"] > lags["10.0"] > 0
    for key, lag in lags.items():
        assert lag == pytest.approx(paper[key], rel=0.3), (key, lag)
    assert max(hyst.values()) < 6.0  # % of full-scale output


def test_an_output_that_falls_during_the_press_has_no_lag_instead_of_an_error(skin):
    """A module that reads the press inverted (an array's far face draws in) never rises
    above its rest level: no onset, so no lag, and the force's cycles still segment."""
    profile = LoadProfile(depth_m=0.003, speeds_m_s=(0.001,), cycles=2, hold_s=0.0,
                          rest_s=1.0)
    world = BenchWorld(profile, skin, RateDependentForce.from_params(PhysicsParams()))
    t = np.arange(0.0, world.duration_s, 1.0 / RATE_HZ)
    volts = world.photoreflector_voltage(t)
    aligned = Aligned(t_s=t, output_v=volts - volts[0], force_n=world.force_n(t),
                      indentation_m=world.indentation_m(t), rate_hz=RATE_HZ, start_ns=0,
                      force_flipped=False)
    seg = segment(aligned)
    sig = m.baseline(aligned, seg)
    assert len(seg.cycles) == 2 and np.max(sig.output_v) <= 1e-9
    assert m.phase_lags(sig, seg.cycles, RATE_HZ) == []
    assert m.phase_lag(sig, seg.cycles, RATE_HZ) is None
