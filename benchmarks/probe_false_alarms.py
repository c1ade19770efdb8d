"""The adaptive hold's probe on a still object: how often does its fall test alarm on the
fingertip's Gaussian noise alone, per probe and per hour of probing, at each threshold?

Why: the probe's threshold (``SlipHoldConfig.probe_sigmas``) is derived from the
detector's false-alarm rate by Rice's formula at the ticks' bandwidth; this checks that
derivation against the test as the probe runs it: every tick, each run of its latest 1 to
``PROBE_TICKS`` tick means against the level (a mean over ``steady_s``, whose own error
every test shares). Noise in units of one tick's sigma; no slip, no load change.

    python benchmarks/probe_false_alarms.py [--probes N] [--ticks T] [--sigmas K ...]
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tactile_sensor"))

from tactile_sensor.control.slip_hold import PROBE_TICKS, SHEAR_FINGERTIP_NOISE, SlipHoldConfig

#: Probes drawn at a time (memory: chunk x ticks doubles).
CHUNK = 20000


def alarm_fraction(sigmas: list[float], probes: int, ticks: int, level_ticks: int,
                   seed: int = 1) -> list[float]:
    """The fraction of still probes of ``ticks`` ticks whose test alarmed, per threshold."""
    rng = np.random.default_rng(seed)
    hits = np.zeros(len(sigmas))
    level_var = 1.0 / level_ticks
    done = 0
    while done < probes:
        n_probes = min(CHUNK, probes - done)
        x = rng.standard_normal((n_probes, ticks))
        level = rng.standard_normal(n_probes) * math.sqrt(level_var)
        worst = np.full(n_probes, -np.inf)
        for t in range(1, ticks + 1):
            latest = x[:, max(0, t - PROBE_TICKS):t][:, ::-1]
            n = np.arange(1, latest.shape[1] + 1)
            fall = level[:, None] - np.cumsum(latest, axis=1) / n
            worst = np.maximum(worst, (fall / np.sqrt(1.0 / n + level_var)).max(axis=1))
        hits += (worst[:, None] > np.asarray(sigmas)[None, :]).sum(axis=0)
        done += n_probes
    return list(hits / probes)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--probes", type=int, default=4_000_000, help="still probes drawn")
    parser.add_argument("--ticks", type=int, default=30, help="ticks a probe runs (0.3 s)")
    parser.add_argument("--sigmas", type=float, nargs="*", default=None,
                        help="thresholds to test (default: the hold's own and 4.5 4.0 3.5 3.0)")
    args = parser.parse_args()
    if args.probes < 1 or args.ticks < 1:
        parser.error("--probes and --ticks must be 1 or more, e.g. --probes 400000 --ticks 30")
    cfg = SlipHoldConfig(SHEAR_FINGERTIP_NOISE, ceiling_n=10.0, newton_per_rad=1.0,
                         closed_position_rad=1.0)
    sigmas = args.sigmas or [cfg.probe_sigmas, 4.5, 4.0, 3.5, 3.0]
    level_ticks = round(cfg.steady_s * cfg.control_rate_hz)
    fractions = alarm_fraction(sigmas, args.probes, args.ticks, level_ticks)
    seconds = args.ticks / cfg.control_rate_hz
    print(f"{args.probes} still probes of {args.ticks} ticks; the hold's threshold "
          f"{cfg.probe_sigmas:.3f} sigma (one false alarm an hour at "
          f"{cfg.control_rate_hz / 2:g} Hz)")
    for k, p in zip(sigmas, fractions, strict=True):
        per_probe = f"1 in {1 / p:,.0f}" if p > 0 else "none"
        print(f"  {k:5.2f} sigma: {per_probe} probes, {p / seconds * 3600:8.2f} an hour of "
              "probing")


if __name__ == "__main__":
    main()
