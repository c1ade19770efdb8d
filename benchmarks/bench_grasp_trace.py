"""One whole grasp on the mock, kept as a trace for the docs' figure: contact, the hold at
the target, and the release, as the gripper node runs them.

The Grasp and the Release run through the node's goal runner and servo link on the XM430
emulator and the gripper world, with the tactile force the driver would publish (the
paper's noise, the default filter, 5 ms transport): the set-up of ``grasp_hold.py``. The
fingers start fully open; between the goals they hold for ``--hold`` seconds, as
``tactile-sensor bringup gripper --protocol grasp`` holds. The trace keeps the world's
true force on finger A, the sensed force the goal saw, the opening and the target, sampled
every 2 ms and decimated.

    python benchmarks/bench_grasp_trace.py [--target 1.5] [--hold 1.0]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import threading
import time
from pathlib import Path
from types import SimpleNamespace

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tactile_sensor"))

from bench_gripper import skin  # noqa: E402
from grasp_hold import (  # noqa: E402
    ROD_M,
    Bench,
    ControlLoop,
    TactileFeed,
    open_bench,
)
from results import Figure, write_results  # noqa: E402

from tactile_sensor.control.actions import accept_grasp, accept_release  # noqa: E402
from tactile_sensor.control.tactile_force import TactileForce  # noqa: E402
from tactile_sensor.sim.gripper_world import GripperWorld  # noqa: E402

SAMPLE_PERIOD_S = 0.002


class Sampler(threading.Thread):
    """The world's truth and the newest sensed force every ``SAMPLE_PERIOD_S``."""

    def __init__(self, bench: Bench, forces: TactileForce) -> None:
        super().__init__(daemon=True)
        self.bench, self.forces = bench, forces
        self.rows: list[tuple[float, float, float, float]] = []
        self.running = True

    def run(self) -> None:
        while self.running:
            state = self.bench.world.latest
            sensed = self.forces.latest[0] if self.forces.latest else float("nan")
            self.rows.append((self.bench.world_time(), state.force_a_n, sensed,
                              state.opening_m))
            time.sleep(SAMPLE_PERIOD_S)


def grasp_hold_release(bench: Bench, target_n: float, hold_s: float
                       ) -> tuple[dict[str, list[float]], list[str], dict[str, float]]:
    """The trace, the two results' messages, and the instants [s from the goal] of the
    release's start and end."""
    settings = bench.settings
    servo, forces, runner, link = bench.goal_runner()
    grasp = SimpleNamespace(target_force=target_n, closing_speed=0.0, timeout=0.0)
    release = SimpleNamespace(opening=0.0)  # fully open, where the grasp started
    sampler = Sampler(bench, forces)
    with TactileFeed(bench.world, bench.emulator._t0, forces, 0), ControlLoop(servo):
        servo.await_sample(1.0)
        t0 = bench.world_time()
        sampler.start()
        grasped = runner.run(link, lambda: accept_grasp(grasp, settings))
        time.sleep(hold_s)
        released_from = bench.world_time() - t0
        opened = runner.run(link, lambda: accept_release(release, settings))
        released_at = bench.world_time() - t0
        time.sleep(0.2)
        sampler.running = False
        sampler.join()
    rows = sampler.rows
    trace = {"t_s": [r[0] - t0 for r in rows], "true_force_n": [r[1] for r in rows],
             "sensed_force_n": [r[2] for r in rows], "opening_m": [r[3] for r in rows],
             "target_n": [target_n] * len(rows),
             "release_start_s": [released_from] * len(rows),
             "release_end_s": [released_at] * len(rows)}
    return trace, [grasped.message, opened.message], {"release_start_s": released_from,
                                                      "release_end_s": released_at}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--target", type=float, default=1.5,
                        help="the grasp's target force [N] (the grasp protocol's 1.5 N)")
    parser.add_argument("--hold", type=float, default=1.0,
                        help="how long the fingers hold between grasp and release [s]")
    args = parser.parse_args(argv)
    if not (0.0 < args.target < 6.0 and 0.0 <= args.hold <= 10.0):
        print("bench_grasp_trace: --target must be in (0, 6) N and --hold in [0, 10] s.",
              file=sys.stderr)
        return 2
    world = GripperWorld(skin()[0], rod_diameter_m=ROD_M)
    with tempfile.TemporaryDirectory() as tmp:
        emulator, client = open_bench(Path(tmp) / "xm430", world)
        try:
            bench = Bench(world, emulator, client)
            trace, messages, marks = grasp_hold_release(bench, args.target, args.hold)
        finally:
            client.close()
            emulator.stop()
    held = [f for t, f in zip(trace["t_s"], trace["true_force_n"], strict=True)
            if marks["release_start_s"] - 0.5 <= t < marks["release_start_s"]]
    figures = [Figure("peak true force", max(trace["true_force_n"]), "N"),
               Figure("true force over the last 0.5 s of the hold, mean",
                      sum(held) / len(held) if held else float("nan"), "N"),
               Figure("release took", marks["release_end_s"] - marks["release_start_s"], "s"),
               Figure("opening after the release", trace["opening_m"][-1] * 1e3, "mm")]
    for figure in figures:
        print(f"{figure.name}: {figure.value:.3f} {figure.unit}")
    print("\n".join(messages))
    write_results("grasp_trace", figures, series=trace, notes="; ".join(messages))
    return 0


if __name__ == "__main__":
    sys.exit(main())
