"""`make demo`'s bench protocol gives Figs 7-9 something to show in a short demo: every
paper speed with at least two cycles (an interval, not one dot), several at the reference
speed (hysteresis and repeatability over cycles), all in about a minute of motion."""

from __future__ import annotations

from collections import Counter

from tactile_sensor.sim.profiles import PROTOCOLS, LoadProfile

PAPER_SPEEDS_M_S = {0.0001, 0.001, 0.01}  # Sec. III-D: 0.1, 1 and 10 mm/s
MOTION_BUDGET_S = 60.0  # of the demo's 90 s: the rest starts the nodes and analyses


def test_demo_runs_every_paper_speed_with_cycles_to_compare_within_a_minute():
    profile = LoadProfile(**PROTOCOLS["demo"])
    cycles = Counter(s for s in profile.speeds_m_s for _ in range(profile.cycles))
    assert set(cycles) == PAPER_SPEEDS_M_S
    assert min(cycles.values()) >= 2
    assert cycles[0.001] >= 5  # the reference speed: hysteresis, CV and drift
    assert profile.duration_s <= MOTION_BUDGET_S
