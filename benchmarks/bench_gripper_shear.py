"""The shear fingertip end to end: the gripper_shear configuration grasps an object with
mass, the object is lifted, and the driver's force along the fingers is set against the
mock world's truth (finger A's skin force, force.x of ``~/ground_truth``).

Runs ``tactile-sensor bringup gripper_shear --protocol grasp:hold=H,target_force=F`` with
an object (``object.*`` parameters), lifts it through the emulator's control FIFO once the
grasp has answered, records, and compares the two forces' means before the lift and over
two windows after it (the object rings on the stuck skins at the lift).

    python benchmarks/bench_gripper_shear.py [--mass 0.1] [--friction 0.8] [--grip 2.5]
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tactile_sensor"))

from results import Figure, write_results

#: Windows [s] from the lift in which the forces are compared.
WINDOWS_S = ((-0.3, 0.0), (1.0, 4.0), (4.0, 6.0))
HOLD_S = 8.0


def run_lift(work: Path, mass: float, friction: float, grip: float) -> Path | None:
    """Bring up, grasp, lift once the grasp answered; the bag (None: the run failed)."""
    fifo = work / "xm430.ctl"
    config = work / "object.yaml"
    config.write_text(
        "/**/gripper_world:\n  ros__parameters:\n"
        f"    servo_control: {fifo}\n    object:\n      mass_kg: {mass}\n"
        f"      friction_static: {friction}\n      friction_kinetic: {friction}\n")
    bag = work / "bag"
    command = ["tactile-sensor", "bringup", "gripper_shear", "--protocol",
               f"grasp:hold={HOLD_S:g},target_force={grip:g}", "--config", str(config),
               "--record", str(bag), "--port", f"adc_port={work / 'adc'}",
               "--port", f"servo_port={work / 'xm430'}"]
    with subprocess.Popen(command, stderr=subprocess.PIPE, text=True) as proc:
        assert proc.stderr is not None
        for line in proc.stderr:
            sys.stderr.write(line)
            if "grasp result" in line:
                fifo.write_text("object lift\n")
        code = proc.wait()
    return bag if code == 0 else None


def forces(bag: Path) -> dict[str, np.ndarray]:
    """(time [s], force x, y, z [N]) rows of the driver's wrench and of the truth."""
    from rosbags.highlevel import AnyReader

    topics = {"/driver/wrench": "driver", "/gripper_world/ground_truth": "truth",
              "/gripper_world/object/joint_states": "object"}
    rows: dict[str, list[tuple[float, ...]]] = {v: [] for v in topics.values()}
    with AnyReader([bag]) as reader:
        chosen = [c for c in reader.connections if c.topic in topics]
        for con, stamp, raw in reader.messages(connections=chosen):
            msg = reader.deserialize(raw, con.msgtype)
            if topics[con.topic] == "object":  # object_position, object_slip [m]
                rows["object"].append((stamp * 1e-9, *msg.position))
                continue
            f = msg.wrench.force
            rows[topics[con.topic]].append((stamp * 1e-9, f.x, f.y, f.z))
    return {k: np.asarray(v) for k, v in rows.items()}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--mass", type=float, default=0.1, help="object mass [kg]")
    parser.add_argument("--friction", type=float, default=0.8, help="static = kinetic [1]")
    parser.add_argument("--grip", type=float, default=2.5, help="grasp target [N]")
    args = parser.parse_args()
    work = Path(tempfile.mkdtemp(prefix="bench_gripper_shear_"))
    bag = run_lift(work, args.mass, args.friction, args.grip)
    if bag is None:
        print("the bringup failed; see its log above", file=sys.stderr)
        return 1
    f = forces(bag)
    lifted = f["truth"][np.abs(f["truth"][:, 1]) > 0.05, 0]
    if not lifted.size:
        print("the object was never lifted (no force along the fingers)", file=sys.stderr)
        return 1
    figures: list[Figure] = []
    for start, end in WINDOWS_S:
        span = f"{start:+g} to {end:+g} s from the lift"
        means = {}
        for name in ("driver", "truth"):
            rows = f[name]
            t = rows[:, 0] - lifted[0]
            window = rows[(t > start) & (t < end)]
            means[name] = window[:, 1:].mean(axis=0)
            if name == "driver":
                spread = float(window[:, 1].std())
        print(f"{span}: driver Fx {means['driver'][0]:.3f} N (sd {spread:.3f}), "
              f"Fz {means['driver'][2]:.3f} N; truth Fx {means['truth'][0]:.3f} N, "
              f"Fz {means['truth'][2]:.3f} N")
        figures += [Figure(f"{span}: driver Fx", float(means["driver"][0]), "N"),
                    Figure(f"{span}: truth Fx", float(means["truth"][0]), "N"),
                    Figure(f"{span}: driver Fx sd", spread, "N")]
    slip = float(np.abs(f["object"][:, 2]).max()) if f["object"].size else float("nan")
    print(f"the object's largest slip: {slip * 1e3:.2f} mm")
    figures.append(Figure("largest slip", slip, "m"))
    write_results("gripper_shear", figures,
                  notes=f"{args.mass:g} kg, friction {args.friction:g}, grasp "
                  f"{args.grip:g} N; half its weight {args.mass * 9.80665 / 2:.3f} N.")
    return 0


if __name__ == "__main__":
    sys.exit(main())
