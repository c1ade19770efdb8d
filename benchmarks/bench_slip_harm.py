"""Slip, do no harm: the adaptive hold against a fixed hold at the adaptive hold's own peak
grip, on household objects, offline.

What runs: ``bench_slip_hold``'s closed loop (the pure ``control.slip_hold.SlipHold`` at
the control tick on the gripper world, the held object and the motor model with the
default drivetrain or ``--drivetrain held-out``'s (``grasp_hold.DRIVETRAINS``), the
fingertip's noise and 5 ms of delay, no ROS), on the objects of
``sim.object_set.HOUSEHOLD_OBJECTS`` (YCB masses; silicone's friction on their surfaces).

Each object is gripped at ``START_OVER_LEAST`` times the least grip for its weight at its
kinetic friction (under the ceiling), lifted (its weight eased on over 0.3 s), held
``HOLD_S`` while the adaptive hold probes, then its load doubles over 100 ms (a pull, or
the object accelerated), and held ``AFTER_S`` more. The adaptive hold's peak grip is the
largest true grip over the whole run; a fixed hold is then run at that peak from the
start. Do no harm: every object the fixed hold at the peak keeps, the adaptive hold keeps.

That count cannot see an object the probe itself loses (the adaptive hold never above its
start grip, so the fixed hold runs at the start and loses it at the doubling too), nor a
probe that stopped with nothing slid (a false alarm: more grip): both are counted beside
it, the latter from the held object's true slip when the friction was learned.
``--probe-sigmas`` sets the probe's threshold in place of the hold's own (a sweep).

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_slip_harm.py [--design-only] [--seeds N]
        [--probe-sigmas K] [--drivetrain default|held-out]
"""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import dataclass, fields, replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tactile_sensor"))

from bench_slip_hold import CEILING_N, GRIPPED_S, TICK_S, WORLD_STEP_S, Loop
from grasp_hold import DRIVETRAINS
from results import Figure, write_results

from tactile_sensor.analysis.slip.signature import Scenario, least_grip_n
from tactile_sensor.control.slip_hold import HoldPhase, SlipHoldConfig
from tactile_sensor.sim.object_set import HOUSEHOLD_OBJECTS, HouseholdObject

#: The starting grip over the least grip for the weight at the kinetic friction [1].
START_OVER_LEAST = 1.5
#: Held after the lift before the doubling [s]; after the doubling starts [s].
HOLD_S = 3.0
AFTER_S = 1.5


#: The true slip under which a probe's stop saw nothing slide [mm].
STILL_MM = 1e-3


@dataclass(frozen=True)
class SweptThreshold(SlipHoldConfig):
    """The hold's configuration with the probe's threshold set (``--probe-sigmas``)."""

    sigmas: float = math.nan

    @property
    def probe_sigmas(self) -> float:
        return self.sigmas


@dataclass(frozen=True)
class Outcome:
    """One object under one hold: kept to the end, the peak true grip [N], its slip [mm];
    the adaptive hold's friction and its true slip when a probe's slip taught it [mm] (NaN:
    none learned; inf: the probe reached the largest friction and claimed no slip)."""

    kept: bool
    peak_n: float
    slip_mm: float
    friction: float | None = None
    probe_slip_mm: float = math.nan
    probed: bool = False

    def lost_in_probe(self, start_n: float) -> bool:
        """Probed and dropped with the grip never above its start: the probe let it go."""
        return self.probed and not self.kept and self.peak_n <= start_n * 1.01


def scenario(obj: HouseholdObject) -> Scenario:
    s = Scenario(obj.mass_kg, obj.friction_static, obj.friction_kinetic, 1.0,
                 hold_s=HOLD_S, after_s=AFTER_S)
    start = min(CEILING_N, START_OVER_LEAST * least_grip_n(s.weight_n, s.friction_kinetic))
    return replace(s, grip_n=start)


def run(s: Scenario, adaptive: bool, seed: int, probe_sigmas: float | None = None,
        drivetrain: str = "default") -> Outcome:
    """The world, the motor and the hold (adaptive) or the fingers where they closed."""
    loop = Loop(s, adaptive, seed, drivetrain=DRIVETRAINS[drivetrain])
    world = loop.world
    if loop.hold is not None and probe_sigmas is not None:
        cfg = loop.hold.config
        loop.hold.config = SweptThreshold(
            **{f.name: getattr(cfg, f.name) for f in fields(cfg)}, sigmas=probe_sigmas)
    # the true slip when the friction was learned, from where the probe started
    probe_slip_mm, probe_from_m, probed = math.nan, 0.0, False
    steps = round((GRIPPED_S + s.duration_s) / WORLD_STEP_S)
    per_tick = round(TICK_S / WORLD_STEP_S)
    read = 0
    for i in range(1, steps + 1):
        if i == round(GRIPPED_S / WORLD_STEP_S):
            world.lift()
        loop.step(i * WORLD_STEP_S)
        if i % per_tick == 0:
            hold = loop.hold
            was_probing = hold is not None and hold.phase is HoldPhase.PROBING
            read = loop.tick(i * WORLD_STEP_S, read)
            if hold is None or world.held is None or not math.isnan(probe_slip_mm):
                continue
            slip_m = world.held.state.slip_m
            if hold.phase is HoldPhase.PROBING and not was_probing:
                probe_from_m, probed = slip_m, True
            elif hold.friction is not None:
                # a probe whose grip reached |Ft| / Fn = max_friction took the ratio it saw
                # and claimed no slip (the hold's own stop rule, from its probe's start)
                level, start_n, start_s = hold._probe
                cfg = hold.config
                declared = (start_n - cfg.probe_rate_n_s * (i * WORLD_STEP_S - start_s)
                            > level / cfg.max_friction)
                probe_slip_mm = abs(slip_m - probe_from_m) * 1e3 if declared else math.inf
    held = world.held
    assert held is not None
    peak = float(np.max([sample[1] for sample in loop.samples]))
    return Outcome(not held.dropped, peak, abs(held.state.slip_m) * 1e3,
                   loop.hold.friction if loop.hold is not None else None, probe_slip_mm,
                   probed)


def compare(obj: HouseholdObject, seed: int, probe_sigmas: float | None = None,
            drivetrain: str = "default") -> tuple[Scenario, Outcome, Outcome]:
    s = scenario(obj)
    adaptive = run(s, True, seed, probe_sigmas, drivetrain)
    fixed = run(replace(s, grip_n=adaptive.peak_n), False, seed, drivetrain=drivetrain)
    return s, adaptive, fixed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--design-only", action="store_true",
                        help="leave out the held-out objects")
    parser.add_argument("--seeds", type=int, default=1,
                        help="noise seeds per object (default 1)")
    parser.add_argument("--probe-sigmas", type=float, default=None,
                        help="the probe's threshold [standard errors] in place of the "
                        "hold's own (one false alarm an hour)")
    parser.add_argument("--drivetrain", choices=tuple(k for k, v in DRIVETRAINS.items()
                                                      if v is not None), default="default",
                        help="the servo's drivetrain (grasp_hold.py; default: the mock's)")
    args = parser.parse_args()
    if args.seeds < 1:
        parser.error(f"--seeds {args.seeds} must be 1 or more")
    if args.probe_sigmas is not None and not args.probe_sigmas > 0:
        parser.error(f"--probe-sigmas {args.probe_sigmas} must be > 0, e.g. 4.0")
    objects = [o for o in HOUSEHOLD_OBJECTS if not (args.design_only and o.held_out)]
    print(f"drivetrain: {args.drivetrain}")
    print(f"{'object':<26} {'g':>5} {'mu_s':>4} {'mu_k':>4} {'start':>5} {'seed':>4} | "
          f"{'adaptive':>8} {'peak N':>6} {'slip':>6} {'mu':>5} | {'fixed@peak':>10} "
          f"{'slip':>6} | harm")
    harms = kept_fixed = kept_adaptive = runs = lost = still = 0
    for obj in objects:
        number = HOUSEHOLD_OBJECTS.index(obj)
        for seed in range(args.seeds):
            s, a, f = compare(obj, 1000 * number + seed, args.probe_sigmas, args.drivetrain)
            harm = f.kept and not a.kept
            runs += 1
            lost += a.lost_in_probe(s.grip_n)
            still += a.probe_slip_mm < STILL_MM
            harms += harm
            kept_fixed += f.kept
            kept_adaptive += a.kept
            learned = "-" if a.friction is None else f"{a.friction:.2f}"
            notes = (" (lost in the probe)" if a.lost_in_probe(s.grip_n) else "") + (
                " (probe: nothing slid)" if a.probe_slip_mm < STILL_MM else "")
            name = obj.name + (" *" if obj.held_out else "")
            print(f"{name:<26} {obj.mass_kg * 1e3:5.0f} {s.friction_static:4.2f} "
                  f"{s.friction_kinetic:4.2f} {s.grip_n:5.2f} {seed:>4} | "
                  f"{'kept' if a.kept else 'DROPPED':>8} {a.peak_n:6.2f} {a.slip_mm:6.2f} "
                  f"{learned:>5} | {'kept' if f.kept else 'dropped':>10} {f.slip_mm:6.2f} | "
                  f"{'HARM' if harm else '-'}{notes}")
    print(f"runs {runs} (* held out); fixed at the adaptive peak kept {kept_fixed}; "
          f"adaptive kept {kept_adaptive}; dropped by the adaptive hold where the fixed one "
          f"kept: {harms} (goal 0: {'met' if harms == 0 else 'not met'}); lost in the probe "
          f"(grip never above its start): {lost}; probes stopped with nothing slid: {still}")
    if args.probe_sigmas is not None:
        return  # a sweep: printed only
    name = ("slip_harm" + ("_design" if args.design_only else "")
            + ("" if args.drivetrain == "default" else "_" + args.drivetrain.replace("-", "_")))
    write_results(name, [
        Figure("runs", runs), Figure("fixed at the adaptive peak: kept", kept_fixed),
        Figure("adaptive: kept", kept_adaptive),
        Figure("adaptive dropped where the fixed hold at its peak kept", harms, "", "0",
               harms == 0),
        Figure("lost in the probe (grip never above its start)", lost),
        Figure("probes stopped with nothing slid", still)],
        notes=f"{len(objects)} household objects "
        f"({'design only' if args.design_only else 'held-out ones included'}) x "
        f"{args.seeds} seeds, drivetrain {args.drivetrain}: gripped at "
        f"{START_OVER_LEAST:g} x the least grip, lifted, held {HOLD_S:g} s, load doubled "
        f"over 100 ms, held {AFTER_S:g} s.")


if __name__ == "__main__":
    main()
