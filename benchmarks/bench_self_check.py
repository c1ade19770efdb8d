"""The gripper's self-check on skins the calibration no longer fits (one command:
``python benchmarks/bench_self_check.py``).

Each case is a skin at a stiffness ratio with an emitter at an output ratio
(``skin.stiffness_ratio``, ``emitter.output_ratio`` of the mock). The close runs offline,
tick by tick at the gripper's 100 Hz, on the mock gripper's own physics: the gripper world
(sim/gripper_world.py) around a fixed 20 mm rod off the centre by ``--rod-offset``, the
XM430's quasi-static motor model (sim/motor_model.py) in current-based position mode, the
module's output through the detector model (physics/detector.py) with the paper-level
ADC noise, 12-bit quantisation, and ten 1 kHz samples averaged per tick. The servo's
position, velocity and current are quantised to its control table's units. The fit
(control/self_check.py) sees only that record and the FEM prediction, never the case's
ratios. It prints each factor with its standard uncertainty and its error.

Goal: a skin at 1.15 x stiffness with an emitter at 0.8: both factors within +-0.03.

Run from the repository root after ``. scripts/env.sh``.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tactile_sensor"))

from grasp_hold import DRIVETRAINS  # noqa: E402
from results import Figure, write_results  # noqa: E402

from tactile_sensor.control.self_check import (  # noqa: E402
    ClosingRecord,
    SelfCheckError,
    SkinPrediction,
    fit_self_check,
)
from tactile_sensor.hardware.xm430_table import A_PER_CURRENT_UNIT  # noqa: E402
from tactile_sensor.physics.detector import DetectorState, module_output_v  # noqa: E402
from tactile_sensor.physics.params import PhysicsParams  # noqa: E402
from tactile_sensor.physics.prediction import load_or_compute_curve  # noqa: E402
from tactile_sensor.sim.adc_device import white_noise_for_dynamic_range  # noqa: E402
from tactile_sensor.sim.gripper_world import GripperWorld  # noqa: E402
from tactile_sensor.sim.motor_model import MotorCommand, MotorModel  # noqa: E402
from tactile_sensor.sim.skin_response import TabulatedSkin  # noqa: E402

CASES = ((1.0, 1.0), (1.15, 0.8), (0.9, 1.1))
RAD_PER_POSITION_UNIT = 2.0 * math.pi / 4096.0
RAD_S_PER_VELOCITY_UNIT = 0.229 * 2.0 * math.pi / 60.0
TICK_S, ADC_S = 0.01, 0.001
ROD_M, START_GAP_M = 0.020, 0.0015
#: The close: finger speed [m/s], Goal Current [A], travel past contact [m].
SPEED_M_S, CURRENT_A, PRESS_M = 0.001, 1.0, 0.0020


def closing_record(curve: object, stiffness: float, emitter: float, rod_offset_m: float,
                   seed: int, drivetrain: str = "default") -> ClosingRecord:
    """One slow close on the rod, as the gripper node records it."""
    rng = np.random.default_rng(seed)
    skin = TabulatedSkin.from_prediction_curve(curve)
    world = GripperWorld(skin, rod_diameter_m=ROD_M, rod_offset_m=rod_offset_m,
                         stiffness_ratio=stiffness)
    g = world.geometry
    start = g.position_rad(ROD_M + 2.0 * (START_GAP_M + abs(rod_offset_m)))
    motor = MotorModel(start, world.load_torque_nm, drivetrain=DRIVETRAINS[drivetrain])
    speed = g.finger_speed_to_rad_s(SPEED_M_S)
    command = MotorCommand(True, g.closed_position_rad, speed, 0.0, CURRENT_A)
    state = DetectorState(emitter_ratio=emitter)
    rest_v = float(module_output_v(skin.voltage_v(0.0), 0.0, 0.0, state))
    sigma = white_noise_for_dynamic_range()
    lsb = 5.0 / 4095.0
    rows: list[tuple[float, float, float, float]] = []
    touched: float | None = None
    for _ in range(int(10.0 / TICK_S)):
        volts = []
        for _ in range(int(TICK_S / ADC_S)):
            s = motor.step(ADC_S, command)
            world.update(0.0, s.rack_position_rad)
            v = float(module_output_v(world.latest.voltages_v[0], 0.0, 0.0, state))
            volts.append(round((v + rng.normal(0.0, sigma)) / lsb) * lsb)
        s = motor.state
        rows.append((round(s.position_rad / RAD_PER_POSITION_UNIT) * RAD_PER_POSITION_UNIT,
                     round(s.velocity_rad_s / RAD_S_PER_VELOCITY_UNIT)
                     * RAD_S_PER_VELOCITY_UNIT,
                     round(s.current_a / A_PER_CURRENT_UNIT) * A_PER_CURRENT_UNIT,
                     rest_v - float(np.mean(volts))))
        if world.latest.indentation_a_m > 0 and touched is None:
            touched = s.position_rad
        if touched is not None and s.position_rad - touched > PRESS_M / g.pitch_radius_m:
            break
    return ClosingRecord.of(*zip(*rows, strict=True))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rod-offset", type=float, default=0.0005,
                        help="the rod's offset from the gripper centre [m]")
    parser.add_argument("--seeds", type=int, default=5, help="closes per case")
    parser.add_argument("--drivetrain", choices=tuple(DRIVETRAINS), default="default",
                        help="the servo's drivetrain (benchmarks/grasp_hold.py)")
    args = parser.parse_args()
    curve = load_or_compute_curve(PhysicsParams())
    prediction = SkinPrediction(tuple(curve.indentation_m.tolist()),
                                tuple(curve.force_n.tolist()), tuple(curve.output_v.tolist()))
    print("stiffness x | emitter x | fitted stiffness (sigma) | fitted gain (sigma) | "
          "worst error stiffness / gain over seeds")
    figures: list[Figure] = []
    for stiffness, emitter in CASES:
        figures += run_case(curve, prediction, stiffness, emitter, args)
    suffix = "" if args.drivetrain == "default" else "_" + args.drivetrain.replace("-", "_")
    write_results("bench_self_check" + suffix, figures, notes=(
        f"{args.seeds} closes per skin, rod {args.rod_offset * 1e3:g} mm off the centre "
        f"towards finger B; seeds 0..; drivetrain {args.drivetrain}"))
    return 0


def run_case(curve: object, prediction: SkinPrediction, stiffness: float, emitter: float,
             args: argparse.Namespace) -> list[Figure]:
    """Print one skin's fits and give its figures (the goal on the 1.15 / 0.8 skin)."""
    key = f"skin {stiffness:g} x, emitter {emitter:g} x"
    fits = []
    for seed in range(args.seeds):
        record = closing_record(curve, stiffness, emitter, args.rod_offset, seed,
                                args.drivetrain)
        try:
            fits.append(fit_self_check(record, prediction))
        except SelfCheckError as exc:
            print(f"{key}, seed {seed}: refused: {exc}")
    figures = [Figure(f"{key}: closes refused", args.seeds - len(fits))]
    if not fits:
        return figures
    f = fits[0]
    err_k = max(abs(x.stiffness - stiffness) for x in fits)
    err_g = max(abs(x.optical_gain - emitter) for x in fits)
    print(f"{stiffness:.2f} | {emitter:.2f} | {f.stiffness:.4f} ({f.stiffness_sigma:.4f}) | "
          f"{f.optical_gain:.4f} ({f.optical_gain_sigma:.4f}) | {err_k:.4f} / {err_g:.4f}")
    goal = (stiffness, emitter) == (1.15, 0.8)
    return [
        *figures,
        Figure(f"{key}: fitted stiffness (seed 0)", round(f.stiffness, 4)),
        Figure(f"{key}: stiffness sigma (seed 0)", round(f.stiffness_sigma, 4)),
        Figure(f"{key}: fitted optical gain (seed 0)", round(f.optical_gain, 4)),
        Figure(f"{key}: optical gain sigma (seed 0)", round(f.optical_gain_sigma, 4)),
        Figure(f"{key}: worst stiffness error", round(err_k, 4), "",
               "<= 0.03" if goal else "", (err_k <= 0.03) if goal else None),
        Figure(f"{key}: worst optical gain error", round(err_g, 4), "",
               "<= 0.03" if goal else "", (err_g <= 0.03) if goal else None)]


if __name__ == "__main__":
    sys.exit(main())
