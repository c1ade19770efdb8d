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

Drifts of the optics (``warm``: +20 K; ``aged``: the emitter at 0.7 of new): the driver
tares with the module as calibrated, the drift ramps in at rest, then the same presses in
the dark; the figure is the force error at 5 N while a press loads, with today's driver
(tared at start, or again before the presses) beside the driver that follows the module
at rest (re-tare at rest, the modulated module's optical gain; sensing/rest_gain.py), for
each kind of module. The drift is ramped in linearly in the skin's photocurrent between
the calibration's state and the drifted one (exact at both ends).

``--demo`` prints only the side-by-side table of ``make demo-ambient``.

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
from tactile_sensor.sensing.rate_calibration import RateCalibration, RateTerm  # noqa: E402
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
#: Drifts of the module's optics (docs/ambient.md): the driver tares with the module as
#: calibrated, then the state ramps in at rest (``DRIFT_RAMP_S``) and the presses begin at
#: ``DRIFT_START_S``, six of the re-tare's time constants after the ramp ended (a module
#: warms over minutes; a minute here keeps the run short).
DRIFTS = {"warm": DetectorState(delta_k=20.0), "aged": DetectorState(emitter_ratio=0.7)}
DRIFT_RAMP_S = (2.0, 62.0)
DRIFT_START_S = 122.0
#: The force the drift goal is stated at, and the gauge's band around it [N].
FORCE_AT_N = 5.0
FORCE_BAND_N = 0.25
#: Today's driver (tared once, at start), today's with a ~/tare before the presses, and
#: the driver that follows the module at rest.
DRIVERS = ("today", "today_tared", "following")


def phases(indentation_m: np.ndarray) -> list[np.ndarray]:
    """Index arrays of each compression phase: the runs of samples with the probe in."""
    inside = np.concatenate([[False], indentation_m > 1e-6, [False]])
    edges = np.flatnonzero(np.diff(inside.astype(int)))
    return [np.arange(a, b) for a, b in zip(edges[::2], edges[1::2], strict=True)]


def driver_config(driver: str, rate_hz: float, filter_name: str) -> ChainConfig:
    """Today's driver (tared once, at start, or again when the presses begin) or the driver
    that follows the module at rest (re-tare at rest, the optical gain; its defaults)."""
    if driver not in DRIVERS:
        raise ValueError(f"unknown driver {driver!r}; one of {', '.join(DRIVERS)}")
    if driver == "following":
        return ChainConfig(rate_hz=rate_hz, filter_name=filter_name)
    return ChainConfig(rate_hz=rate_hz, filter_name=filter_name,
                       rest_retare_time_constant_s=0.0, gain_tracking=False)


def drift_weight(t: np.ndarray) -> np.ndarray:
    """How far the drifted state has come in at ``t`` [s]: 0 (as calibrated) to 1."""
    a, b = DRIFT_RAMP_S
    return np.clip((t - a) / (b - a), 0.0, 1.0)


def module_voltages(t: np.ndarray, lit: LitSource, drifted: LitSource | None,
                    modulated: bool, rate_hz: float) -> tuple[np.ndarray, tuple[int, float]]:
    """The module's codes' voltages (one column, or on and off) and the modulated timing;
    a drift ramps in linearly in the skin's gain (``drift_weight``)."""
    timing = modulation_timing(3, rate_hz, lit) if modulated else (0, 0.0)
    assert timing is not None

    def sample(source: LitSource) -> np.ndarray:
        if not modulated:
            return np.reshape(source(t), (len(t), 1))
        on, off = source.pair(t, timing[0] * 1e-6, timing[1])
        return np.hstack([np.reshape(on, (len(t), 1)), np.reshape(off, (len(t), 1))])

    voltages = sample(lit)
    if drifted is not None:
        voltages = voltages + drift_weight(t)[:, None] * (sample(drifted) - voltages)
    return voltages, timing


def readings(chain: SignalChain, counts: np.ndarray, t: np.ndarray,
             tare_at_s: float | None) -> list:
    """The chain's readings of ``counts``; a ~/tare at ``tare_at_s`` (None: never)."""
    us = np.rint(t * 1e6).astype(np.int64).tolist()
    split = len(t) if tare_at_s is None else int(np.searchsorted(t, tare_at_s))
    out = []
    for part in (slice(0, split), slice(split, len(t))):
        if part.start == split and tare_at_s is not None:
            chain.tare()
        batch = SampleBatch(epoch=1)
        batch.seq = [k & 0xFFFF for k in range(part.start, part.stop)]
        batch.device_time_us, batch.host_time_ns = us[part], [0] * len(batch.seq)
        batch.counts = [tuple(int(c) for c in row) for row in counts[part]]
        out += chain.process_batch(batch)
    return out


def error_at(force: np.ndarray, truth: np.ndarray, depth: np.ndarray,
             level_n: float = FORCE_AT_N) -> tuple[float, float]:
    """(mean, RMS) force error [N] where the gauge reads ``level_n`` +- ``FORCE_BAND_N``
    while a press loads: the sensitivity's error at that force, noise averaged out."""
    loading = np.concatenate([[False], np.diff(depth) > 0])
    near = loading & (np.abs(truth - level_n) <= FORCE_BAND_N) & np.isfinite(force)
    if not near.any():
        return math.nan, math.nan
    err = force[near] - truth[near]
    return float(err.mean()), float(np.sqrt(np.mean(err ** 2)))


def run(scenario: str, seed: int, filter_name: str = DEFAULT_FILTER,
        modulated: bool = False, driver: str = "today",
        rate_aware: bool = False) -> dict[str, object]:
    """One scenario through one driver; ``rate_aware``: the calibration carries the
    physics' Prony terms (the model node's ``calibration_rate_terms``)."""
    physics = PhysicsParams()
    curve = load_or_compute_curve(physics)
    world = BenchWorld(profile_from_protocol("ambient"), TabulatedSkin.from_prediction_curve(
        curve), RateDependentForce.from_params(physics), output_play_m=physics.output_play)
    rate = MODULATED_RATE_HZ if modulated else RATE_HZ
    start_s = DRIFT_START_S if scenario in DRIFTS else START_DELAY_S
    t = np.arange(0.0, start_s + world.duration_s, 1.0 / rate)
    protocol_t = np.maximum(t - start_s, 0.0)
    rest_v = float(world.module_voltages(np.zeros(1))[0, 0])
    room = headroom_ratio(rest_v, physics.supply_voltage, floor_v=SATURATION_V)
    scene = scenario_scene("dark" if scenario in DRIFTS else scenario, room, rate)

    def lit(state: DetectorState) -> LitSource:
        return LitSource(lambda times: world.module_voltages(np.maximum(times - start_s, 0.0)),
                         scene, state, [rest_v], physics.supply_voltage, origin_s=start_s)

    drifted = lit(DRIFTS[scenario]) if scenario in DRIFTS else None
    voltages, (settle_us, period_s) = module_voltages(t, lit(DetectorState()), drifted,
                                                      modulated, rate)
    calibration = Calibration.from_prediction_curve(curve)
    chain = SignalChain(driver_config(driver, rate, filter_name), RateCalibration(
        calibration, [RateTerm(g, tau) for g, tau in zip(physics.prony_g, physics.prony_tau,
                                                         strict=True)])
        if rate_aware else calibration)
    if modulated:  # the emitter on, then off, with the mock ADC's timing
        chain.set_modulation(Modulation(round(period_s * 1e6), settle_us, 0, 0, 1))
    counts = AdcSampler(rate, AdcNoise(), channels=voltages.shape[1], rng=seed).counts(voltages)
    got = readings(chain, counts, t, start_s - 0.5 if driver == "today_tared" else None)
    force = np.array([r.force_n for r in got])
    blind = np.array([r.blind for r in got])
    truth = np.asarray(world.force_n(protocol_t), dtype=float)
    depth = np.asarray(np.where(t >= start_s, world.indentation_m(protocol_t), 0.0))
    per_phase = []
    for idx in phases(depth):
        seen = idx[np.isfinite(force[idx])]
        err = force[seen] - truth[seen]
        per_phase.append((float(np.sqrt(np.mean(err ** 2))) if seen.size else float("nan"),
                          float(blind[idx].mean())))
    inside = np.concatenate(phases(depth))
    seen = inside[np.isfinite(force[inside])]
    overall = float(np.sqrt(np.mean((force[seen] - truth[seen]) ** 2)))
    gain = chain.optical_gain()
    return {"phases": per_phase, "overall": overall, "blind": float(blind[inside].mean()),
            "tared": chain.tared, "headroom": room, "scene": scene,
            "at_5n": error_at(force, truth, depth),
            "full_scale": calibration.full_scale_force_n,
            "gain": None if gain is None else gain[0], "warning": chain.gain_warning(),
            "trace": (t - start_s, truth, force)}


#: The scenario whose presses the docs page draws, and the drivers drawn (table keys).
TRACE_SCENARIO = "office"
TRACE_STEP_S = 0.01


def trace_series(runs: dict[str, dict[str, object]]) -> dict[str, np.ndarray]:
    """The gauge and each driver's force under ``TRACE_SCENARIO`` on one 10 ms grid (the
    modulated module samples at 500 Hz): the sample at or just before each grid time."""
    t0, truth, _ = runs["today"]["trace"]  # type: ignore[misc]
    grid = np.arange(float(t0[0]), float(t0[-1]), TRACE_STEP_S)
    series = {"t_s": grid, "gauge_n": np.interp(grid, t0, truth)}
    for name, r in runs.items():
        t, _, force = r["trace"]  # type: ignore[misc]
        at = np.clip(np.searchsorted(t, grid, side="right") - 1, 0, len(t) - 1)
        series[f"{name}_n"] = force[at]
    return series


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


def drift_table(seed: int) -> list[Figure]:
    """The goal at +20 K and with the emitter at 0.7: the force error at 5 N, today's
    driver beside the one that follows the module at rest, for each kind of module; the
    drift's part is the error less the same driver's in the dark room (there a static
    calibration misses the skin's rate effect while a press loads)."""
    print(f"force error at {FORCE_AT_N:g} N while loading (mean over the gauge's "
          f"+-{FORCE_BAND_N:g} N band; % of the calibration's full scale), drift ramped in "
          f"at rest {DRIFT_RAMP_S[0]:g}-{DRIFT_RAMP_S[1]:g} s, presses from {DRIFT_START_S:g} s")
    print("module     driver            drift  mean [N]   % FS  drift's part [% FS]  "
          "rms [N]  gain   recalibrate")
    figures = []
    for modulated, filter_name in ((False, DEFAULT_FILTER), (True, NOTCH_FILTER)):
        module = "modulated" if modulated else "stock"
        for driver in (*DRIVERS, *(("following_rate",) if modulated else ())):
            dark_mean = 0.0
            for drift in ("dark", *DRIFTS):
                r = run(drift, seed, filter_name, modulated, driver.removesuffix("_rate"),
                        rate_aware=driver.endswith("_rate"))
                mean, rms = r["at_5n"]  # type: ignore[misc]
                full = r["full_scale"]
                dark_mean = mean if drift == "dark" else dark_mean
                share, part = 100 * abs(mean) / full, 100 * abs(mean - dark_mean) / full  # type: ignore[operator]
                gain = "-" if r["gain"] is None else f"{r['gain']:.3f}"
                print(f"{module:10s} {driver:17s} {drift:6s} {mean:8.3f}  {share:6.2f}  "
                      f"{part:12.2f}         {rms:6.3f}  {gain:6s} "
                      f"{'yes' if r['warning'] else 'no'}")
                key = f"{module} {drift}, {driver}"
                goal = modulated and drift in DRIFTS
                figures.append(Figure(f"{key}: force error at 5 N", round(mean, 4), "N"))
                figures.append(Figure(f"{key}: force error at 5 N, share of full scale",
                                      round(share, 3), "%"))
                if drift in DRIFTS:
                    figures.append(Figure(
                        f"{key}: the drift's part of the force error at 5 N", round(part, 3),
                        "% of full scale", goal="<= 3 %" if goal else "",
                        met=part <= 3.0 if goal else None))
    return figures


def demo(seed: int) -> int:
    """``make demo-ambient``: force RMSE over the four presses under each scenario, in the
    dark, with today's driver, and with each kind of module and the driver that follows it
    at rest (the notch on both), side by side; then the drifts' error at 5 N."""
    scenarios = [*SCENARIOS, *DRIFTS]
    dark = run("dark", seed)["overall"]
    print(f"force RMSE over the four presses of the ambient protocol [N] (dark room, today's "
          f"driver: {dark:.3f} N); x: against it")
    print("scenario   today's driver              stock + notch + re-tare     "
          "modulated + notch + gain")
    columns = ((False, DEFAULT_FILTER, "today"), (False, NOTCH_FILTER, "following"),
               (True, NOTCH_FILTER, "following"))
    for name in scenarios:
        cells = []
        for modulated, filter_name, driver in columns:
            r = run(name, seed, filter_name, modulated, driver)
            rmse, blind = r["overall"], r["blind"]
            cell = f"{rmse:.3f} ({rmse / dark:4.2f}x)"  # type: ignore[operator]
            cells.append(cell + (f", {100 * blind:.0f} % blind" if blind else ""))  # type: ignore[operator]
        print(f"{name:10s} " + "".join(f"{c:28s}" for c in cells))
    drift_table(seed)
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scenario", action="append", choices=SCENARIOS,
                        help="scenario(s) to run (default: all)")
    parser.add_argument("--seed", type=int, default=1, help="noise seed (default 1)")
    parser.add_argument("--demo", action="store_true",
                        help="print the side-by-side table of 'make demo-ambient' only")
    args = parser.parse_args(argv)
    if args.demo:
        return demo(args.seed)
    names = args.scenario or list(SCENARIOS)
    if "dark" not in names:
        names.insert(0, "dark")
    today = {name: run(name, args.seed) for name in names}
    notched = {name: run(name, args.seed, NOTCH_FILTER) for name in names}
    modulated = {name: run(name, args.seed, NOTCH_FILTER, modulated=True) for name in names}
    plain_modulated = {name: run(name, args.seed, modulated=True) for name in names}
    following = {name: run(name, args.seed, NOTCH_FILTER, driver="following")
                 for name in names}
    dark = today["dark"]["overall"]
    print(f"detector headroom at rest: ambient ratio {today['dark']['headroom']:.3f} "
          f"(to {SATURATION_V} V); {CYCLES} presses of 3 mm at 1 mm/s")
    figures = table(today, dark, f"today's driver (filter_type {DEFAULT_FILTER}):", "")
    figures += table(notched, dark, f"filter_type {NOTCH_FILTER} (x dark: against "
                     f"{DEFAULT_FILTER} in the dark):", f"{NOTCH_FILTER}, ")
    figures += table(following, dark, f"filter_type {NOTCH_FILTER}, re-tare at rest "
                     "(x dark: against today's driver in the dark):",
                     f"{NOTCH_FILTER} re-tared at rest, ")
    figures += table(plain_modulated, dark, f"modulated module, 500 Hz, filter_type "
                     f"{DEFAULT_FILTER} (x dark: against today's driver in the dark):",
                     f"modulated {DEFAULT_FILTER}, ")
    figures += table(modulated, dark, f"modulated module, 500 Hz, filter_type {NOTCH_FILTER} "
                     f"(x dark: against today's driver in the dark; own dark "
                     f"{modulated['dark']['overall']:.3f} N):", "modulated, ")
    figures += drift_table(args.seed)
    series = trace_series({"today": today[TRACE_SCENARIO] if TRACE_SCENARIO in today
                           else run(TRACE_SCENARIO, args.seed),
                           "stock": run(TRACE_SCENARIO, args.seed, NOTCH_FILTER,
                                        driver="following"),
                           "modulated": run(TRACE_SCENARIO, args.seed, NOTCH_FILTER,
                                            modulated=True, driver="following")})
    write_results("bench_ambient", figures, series=series, notes=(
        f"seed {args.seed}; {DEFAULT_FILTER} is today's default driver; no driver rejects a "
        f"light step during a press; series: the {TRACE_SCENARIO} scenario, today's driver, "
        f"the stock module with {NOTCH_FILTER} and re-tare at rest, the modulated module"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
