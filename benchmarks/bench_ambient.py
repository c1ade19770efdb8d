"""Force accuracy outside the dark room with today's driver (one command:
``python benchmarks/bench_ambient.py``).

The ``ambient`` protocol (config/protocols.yaml: four presses of 3 mm at 1 mm/s) on the
mock bench's physics, offline and sample by sample at 1 kHz as the rig runs it: the FEM
skin, the gauge with the rate effect, the module's output under each light scenario
(sim/ambient_light.py, the same ``LitSource`` the mock ADC samples), paper-level noise and
quantisation, then the driver's signal chain with the FEM calibration (auto-tare at rest,
default filter). For each scenario it prints the force RMSE against the gauge over each
compression phase (probe in contact) and over all four, beside the dark room's, and the
share of samples the driver reported blind.

The modulated module (protocol 3, docs/ambient.md) runs the same presses at 500 Hz, each
sample an emitter-on and an emitter-off code from ``LitSource.pair`` with the mock ADC's
timing (sim/modulated_adc.py), through the same chain reading the emitter's light alone
(``SignalChain.set_modulation``), with the notch filter.

Scenarios (docs/ambient.md): ``dark``; ``office`` (a lamp flickering 0.2 of the emitter's
light at 100 Hz, another switched on (+0.3) while press 1 loads and off (-0.3) while press
2 unloads); ``sunlight`` (steady light using 60 % of the detector's headroom at rest, there
before the tare); ``shadow`` (a hand's shadow takes 0.2 of 0.3 steady light for 0.8 s
during press 3).

Run from the repository root after ``. scripts/env.sh``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tactile_sensor"))

from results import Figure, write_results  # noqa: E402

from tactile_sensor.hardware.adc_samples import SampleBatch  # noqa: E402
from tactile_sensor.physics.detector import DetectorState, headroom_ratio  # noqa: E402
from tactile_sensor.physics.params import PhysicsParams  # noqa: E402
from tactile_sensor.physics.prediction import load_or_compute_curve  # noqa: E402
from tactile_sensor.physics.viscoelastic import RateDependentForce  # noqa: E402
from tactile_sensor.sensing.blind import SATURATION_V  # noqa: E402
from tactile_sensor.sensing.calibration import Calibration  # noqa: E402
from tactile_sensor.sensing.chain import ChainConfig, SignalChain  # noqa: E402
from tactile_sensor.sensing.filters import DEFAULT_FILTER  # noqa: E402
from tactile_sensor.sensing.modulation import Modulation  # noqa: E402
from tactile_sensor.sim.adc_device import AdcNoise, AdcSampler  # noqa: E402
from tactile_sensor.sim.ambient_light import SCENARIOS, LitSource, scenario_scene  # noqa: E402
from tactile_sensor.sim.bench_world import BenchWorld  # noqa: E402
from tactile_sensor.sim.modulated_adc import modulation_timing  # noqa: E402
from tactile_sensor.sim.profiles import profile_from_protocol  # noqa: E402
from tactile_sensor.sim.skin_response import TabulatedSkin  # noqa: E402

RATE_HZ = 1000.0
MODULATED_RATE_HZ = 500.0  # the modulated sketch's and mock's rate (docs/firmware.md)
START_DELAY_S = 5.0  # bench.yaml's protocol.start_delay: the driver tares in this rest
#: Cycles of the ambient protocol: the office steps fall in presses 1 and 2, the shadow in 3.
CYCLES = 4
#: The stock module's software rejection of the lamps' flicker (sensing/mains_notch.py).
NOTCH_FILTER = "savgol_mains"


def phases(indentation_m: np.ndarray) -> list[np.ndarray]:
    """Index arrays of each compression phase: the runs of samples with the probe in."""
    inside = np.concatenate([[False], indentation_m > 1e-6, [False]])
    edges = np.flatnonzero(np.diff(inside.astype(int)))
    return [np.arange(a, b) for a, b in zip(edges[::2], edges[1::2], strict=True)]


def run(scenario: str, seed: int, filter_name: str = DEFAULT_FILTER,
        modulated: bool = False) -> dict[str, object]:
    physics = PhysicsParams()
    curve = load_or_compute_curve(physics)
    world = BenchWorld(profile_from_protocol("ambient"), TabulatedSkin.from_prediction_curve(
        curve), RateDependentForce.from_params(physics), output_play_m=physics.output_play)
    rate = MODULATED_RATE_HZ if modulated else RATE_HZ
    t = np.arange(0.0, START_DELAY_S + world.duration_s, 1.0 / rate)
    protocol_t = np.maximum(t - START_DELAY_S, 0.0)
    rest_v = float(world.module_voltages(np.zeros(1))[0, 0])
    room = headroom_ratio(rest_v, physics.supply_voltage, floor_v=SATURATION_V)
    scene = scenario_scene(scenario, room, rate)
    lit = LitSource(lambda times: world.module_voltages(np.maximum(times - START_DELAY_S, 0.0)),
                    scene, DetectorState(), [rest_v], physics.supply_voltage,
                    origin_s=START_DELAY_S)
    chain = SignalChain(ChainConfig(rate_hz=rate, filter_name=filter_name),
                        Calibration.from_prediction_curve(curve))
    if modulated:  # the emitter on, then off, with the mock ADC's timing
        settle_us, period_s = modulation_timing(3, rate, lit)  # type: ignore[misc]
        chain.set_modulation(Modulation(round(period_s * 1e6), settle_us, 0, 0, 1))
        on, off = lit.pair(t, settle_us * 1e-6, period_s)
        voltages = np.hstack([np.reshape(on, (len(t), 1)), np.reshape(off, (len(t), 1))])
    else:
        voltages = lit(t)
    counts = AdcSampler(rate, AdcNoise(), channels=voltages.shape[1] if modulated else 1,
                        rng=seed).counts(voltages)
    us = np.rint(t * 1e6).astype(np.int64).tolist()
    batch = SampleBatch(epoch=1)
    batch.seq = [k & 0xFFFF for k in range(len(t))]
    batch.device_time_us, batch.host_time_ns = us, [0] * len(t)
    batch.counts = [tuple(int(c) for c in row) for row in counts]
    readings = chain.process_batch(batch)
    force = np.array([r.force_n for r in readings])
    blind = np.array([r.blind for r in readings])
    truth = np.asarray(world.force_n(protocol_t), dtype=float)
    depth = np.where(t >= START_DELAY_S, world.indentation_m(protocol_t), 0.0)
    per_phase = []
    for idx in phases(np.asarray(depth)):
        seen = idx[np.isfinite(force[idx])]
        err = force[seen] - truth[seen]
        per_phase.append((float(np.sqrt(np.mean(err ** 2))) if seen.size else float("nan"),
                          float(blind[idx].mean())))
    inside = np.concatenate([idx for idx in phases(np.asarray(depth))])
    seen = inside[np.isfinite(force[inside])]
    overall = float(np.sqrt(np.mean((force[seen] - truth[seen]) ** 2)))
    return {"phases": per_phase, "overall": overall, "blind": float(blind[inside].mean()),
            "tared": chain.tared, "headroom": room, "scene": scene}


def table(results: dict[str, dict[str, object]], dark: float, title: str,
          key: str) -> list[Figure]:
    """Print one driver's table, RMSE beside the dark room's; its figures."""
    print(title)
    print("scenario   " + "".join(f"press {k + 1} [N]  " for k in range(CYCLES))
          + "all [N]   x dark   blind")
    figures = []
    for name, r in results.items():
        cells = "".join(f"{rmse:8.3f}       " for rmse, _ in r["phases"])  # type: ignore[union-attr]
        ratio = r["overall"] / dark  # type: ignore[operator]
        print(f"{name:10s} {cells}{r['overall']:7.3f}  {ratio:7.2f}  "
              f"{100 * r['blind']:5.1f} %")  # type: ignore[operator]
        figures.append(Figure(f"{key}{name}: force RMSE over the compression phases",
                              round(r["overall"], 4), "N"))  # type: ignore[arg-type]
        figures.append(Figure(f"{key}{name}: RMSE against the dark room's", round(ratio, 3)))
        for k, (rmse, share) in enumerate(r["phases"]):  # type: ignore[union-attr]
            figures.append(Figure(f"{key}{name}: press {k + 1} force RMSE", round(rmse, 4),
                                  "N"))
            if share:
                figures.append(Figure(f"{key}{name}: press {k + 1} blind share",
                                      round(share, 4)))
    return figures


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scenario", action="append", choices=SCENARIOS,
                        help="scenario(s) to run (default: all)")
    parser.add_argument("--seed", type=int, default=1, help="noise seed (default 1)")
    args = parser.parse_args(argv)
    names = args.scenario or list(SCENARIOS)
    if "dark" not in names:
        names.insert(0, "dark")
    today = {name: run(name, args.seed) for name in names}
    notched = {name: run(name, args.seed, NOTCH_FILTER) for name in names}
    modulated = {name: run(name, args.seed, NOTCH_FILTER, modulated=True) for name in names}
    plain_modulated = {name: run(name, args.seed, modulated=True) for name in names}
    dark = today["dark"]["overall"]
    print(f"detector headroom at rest: ambient ratio {today['dark']['headroom']:.3f} "
          f"(to {SATURATION_V} V); {CYCLES} presses of 3 mm at 1 mm/s")
    figures = table(today, dark, f"today's driver (filter_type {DEFAULT_FILTER}):", "")
    figures += table(notched, dark, f"filter_type {NOTCH_FILTER} (x dark: against "
                     f"{DEFAULT_FILTER} in the dark):", f"{NOTCH_FILTER}, ")
    figures += table(plain_modulated, dark, f"modulated module, 500 Hz, filter_type "
                     f"{DEFAULT_FILTER} (x dark: against today's driver in the dark):",
                     f"modulated {DEFAULT_FILTER}, ")
    figures += table(modulated, dark, f"modulated module, 500 Hz, filter_type {NOTCH_FILTER} "
                     f"(x dark: against today's driver in the dark; own dark "
                     f"{modulated['dark']['overall']:.3f} N):", "modulated, ")
    write_results("bench_ambient", figures, notes=f"seed {args.seed}; {DEFAULT_FILTER} is "
                  "today's default driver; no driver rejects a light step during a press")
    return 0


if __name__ == "__main__":
    sys.exit(main())
