"""ADC ingest and filter benchmark (one command: ``python benchmarks/bench_adc.py``).

1. Ingest: the mock ADC runs in its own process (as a real device would be separate
   hardware) and streams on a pseudo-terminal; this process runs AdcStreamReader feeding
   every sample through SignalChain. For each rate, ``--seconds`` (default 30) of
   streaming must show zero dropped frames, CRC/header errors, resyncs and bytes lost at
   the device; the highest such rate is reported with the CPU it took.
2. Filters: one simulated press (physics chain → paper-level noise and quantisation at
   1 kHz) through SignalChain with each filter; reports the lag (time shift that best
   aligns the output of the noise-free, quantised press with the truth), the RMS error of
   the noisy output during the press, and the noise floor at rest (σ and the resulting
   dynamic range, as the paper computes it). The one-euro filter is nonlinear: its lag
   on the noisy signal differs from the noise-free figure.

Run from the repository root after ``. scripts/env.sh``: ``python benchmarks/bench_adc.py``.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SOURCE = ROOT / "tactile_sensor"
sys.path.insert(0, str(SOURCE))

from results import Figure, write_results  # noqa: E402

from tactile_sensor.hardware.adc_frame import FrameParser, encode_frame  # noqa: E402
from tactile_sensor.hardware.adc_reader import AdcStreamReader  # noqa: E402
from tactile_sensor.hardware.adc_samples import Sample  # noqa: E402
from tactile_sensor.sensing.calibration import Calibration  # noqa: E402
from tactile_sensor.sensing.chain import ChainConfig, SignalChain  # noqa: E402
from tactile_sensor.sensing.filters import DEFAULT_FILTER, FILTERS  # noqa: E402
from tactile_sensor.sim.adc_device import (  # noqa: E402
    PAPER_FULL_SCALE_N,
    PAPER_SENSITIVITY_V_PER_N,
    AdcNoise,
    AdcSampler,
)
from tactile_sensor.sim.bench_world import BenchWorld  # noqa: E402
from tactile_sensor.sim.errors import SimError  # noqa: E402
from tactile_sensor.sim.profiles import LoadProfile  # noqa: E402
from tactile_sensor.sim.skin_response import TabulatedSkin, default_skin  # noqa: E402

LINEAR_CAL = Calibration.from_curve([0.0, 0.49], [0.0, 7.0], "paper: 0.07 V/N")


def paper_linear_skin() -> TabulatedSkin:
    """Stand-in skin from the paper's figures (7 N and 0.49 V at 3 mm), used only when
    the physics package cannot produce its curve; labelled as such in the output."""
    d = np.linspace(0.0, 0.003, 31)
    return TabulatedSkin(d, 7.0 * d / 0.003, 1.986 - 0.49 * d / 0.003, "paper-linear")


def load_skin(kind: str) -> TabulatedSkin:
    if kind == "paper-linear":
        return paper_linear_skin()
    try:
        return default_skin(lambda f, m: print(f"  FEM {f * 100:5.1f} % {m}", flush=True))
    except (SimError, ImportError, AttributeError, TypeError) as exc:
        print(f"  physics curve unavailable ({exc}); using the paper-linear skin")
        return paper_linear_skin()


# -- 1. ingest -------------------------------------------------------------------------------


def chain_cost_us(n: int = 100_000) -> tuple[float, float]:
    """Offline µs per frame for parsing and for the signal chain (no I/O)."""
    stream = b"".join(encode_frame(k, k * 1000, [1600 + k % 50]) for k in range(n))
    parser = FrameParser(channels=1)
    t0 = time.perf_counter()
    for i in range(0, len(stream), 4096):
        parser.feed(stream[i:i + 4096])
    parse_us = (time.perf_counter() - t0) / n * 1e6
    chain = SignalChain(ChainConfig(), LINEAR_CAL)
    samples = [Sample(k & 0xFFFF, k * 1000, 0, (1600 + k % 50,), 1) for k in range(n)]
    t0 = time.perf_counter()
    for s in samples:
        chain.process(s)
    return parse_us, (time.perf_counter() - t0) / n * 1e6


def ingest_run(rate_hz: float, seconds: float, skin_table: Path, workdir: Path) -> dict:
    link = workdir / f"adc_{int(rate_hz)}"
    env = {**os.environ, "PYTHONPATH": str(SOURCE)}
    device = subprocess.Popen(
        [sys.executable, "-m", "tactile_sensor.sim.adc_device", "--link", str(link),
         "--rate", str(rate_hz), "--profile", "compression", "--loop", "--skin-table",
         str(skin_table), "--seed", "1"],
        env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 20.0
        while not link.exists():
            if time.monotonic() > deadline or device.poll() is not None:
                raise RuntimeError(f"mock device did not start: {device.stderr.read()}")
            time.sleep(0.05)
        chain = SignalChain(ChainConfig(rate_hz=rate_hz), LINEAR_CAL)
        count = [0]
        lock = threading.Lock()

        def on_sample(sample: Sample) -> None:
            chain.process(sample)
            count[0] += 1

        with AdcStreamReader(str(link), on_sample, channels=1) as reader:
            time.sleep(1.0)  # connect and settle
            with lock:
                before, n0 = reader.stats(), count[0]
            cpu0, t0 = time.process_time(), time.monotonic()
            time.sleep(seconds)
            after, n1 = reader.stats(), count[0]
            cpu1, t1 = time.process_time(), time.monotonic()
        device.terminate()
        out, _ = device.communicate(timeout=10)
    finally:
        if device.poll() is None:
            device.kill()
    lost = re.search(r"bytes_lost=(\d+)", out)
    result = {
        "rate_hz": rate_hz,
        "ingested_hz": (n1 - n0) / (t1 - t0),
        "dropped": after.dropped_frames - before.dropped_frames,
        "crc_errors": after.crc_errors - before.crc_errors,
        "header_errors": after.header_errors - before.header_errors,
        "resyncs": after.resyncs - before.resyncs,
        "device_bytes_lost": int(lost.group(1)) if lost else -1,
        "cpu_percent": 100.0 * (cpu1 - cpu0) / (t1 - t0),
    }
    result["ok"] = (result["dropped"] == 0 and result["crc_errors"] == 0
                    and result["header_errors"] == 0 and result["resyncs"] == 0
                    and result["device_bytes_lost"] == 0
                    and result["ingested_hz"] >= 0.98 * rate_hz)
    return result


def bench_ingest(rates: list[float], seconds: float) -> list[Figure]:
    print("\n== ingest: mock ADC process -> pty -> AdcStreamReader -> SignalChain ==")
    parse_us, chain_us = chain_cost_us()
    print(f"offline cost per frame: parse {parse_us:.2f} µs + chain {chain_us:.2f} µs "
          f"(ceiling ≈ {1e6 / (parse_us + chain_us):,.0f} frames/s on one core)")
    with tempfile.TemporaryDirectory() as tmp:
        workdir = Path(tmp)
        table = workdir / "skin.json"
        skin = paper_linear_skin()
        d = np.linspace(0.0, 0.003, 31)
        table.write_text(json.dumps({"indentation_m": d.tolist(),
                                     "force_n": skin.force_n(d).tolist(),
                                     "voltage_v": skin.voltage_v(d).tolist()}))
        best, best_cpu = 0.0, float("nan")
        print(f"{'rate Hz':>9} {'ingested':>10} {'dropped':>8} {'crc':>5} {'hdr':>5} "
              f"{'resync':>6} {'dev lost B':>10} {'cpu %':>6}  {seconds:g} s each")
        for rate in rates:
            r = ingest_run(rate, seconds, table, workdir)
            print(f"{r['rate_hz']:9.0f} {r['ingested_hz']:10.0f} {r['dropped']:8d} "
                  f"{r['crc_errors']:5d} {r['header_errors']:5d} {r['resyncs']:6d} "
                  f"{r['device_bytes_lost']:10d} {r['cpu_percent']:6.1f}  "
                  f"{'ok' if r['ok'] else 'DROPS'}", flush=True)
            if not r["ok"]:
                break
            best, best_cpu = rate, r["cpu_percent"]
    print(f"highest rate ingested with zero drops for {seconds:g} s: {best:,.0f} frames/s "
          f"(goal ≥ 5,000: {'met' if best >= 5000 else 'NOT met'})")
    return [Figure("parse cost per frame (offline)", parse_us, "µs"),
            Figure("signal chain cost per frame (offline)", chain_us, "µs"),
            Figure(f"highest rate ingested with zero drops for {seconds:g} s", best,
                   "frames/s", ">= 5000", best >= 5000),
            Figure("reader process CPU at that rate", best_cpu, "%")]


# -- 2. filters ------------------------------------------------------------------------------


def press_readings(filter_name: str, volts: np.ndarray, rate_hz: float) -> np.ndarray:
    """Run the real chain (tare included) over the samples; returns output_v."""
    chain = SignalChain(ChainConfig(rate_hz=rate_hz, filter_name=filter_name), LINEAR_CAL)
    counts = np.rint(volts / chain_volts_per_count()).astype(int)
    out = np.empty(len(volts))
    for k, c in enumerate(counts.tolist()):
        out[k] = chain.process(Sample(k & 0xFFFF, round(k * 1e6 / rate_hz), 0, (c,), 1)).output_v
    return out


def chain_volts_per_count() -> float:
    return 5.0 / 4095


def best_lag_ms(out: np.ndarray, truth: np.ndarray, mask: np.ndarray, rate_hz: float) -> float:
    """Shift τ that minimises the RMS of out(t) − truth(t − τ) over the press, 0.1-sample
    steps; the residual's mean is removed so a tare offset cannot pose as a delay."""
    k = np.arange(len(truth), dtype=float)
    shifts = np.arange(-20.0, 80.0, 0.1)
    rms = [np.std(out[mask] - np.interp(k[mask] - s, k, truth)) for s in shifts]
    return float(shifts[int(np.argmin(rms))] / rate_hz * 1e3)


def bench_filters(seed: int, skin_kind: str) -> list[Figure]:
    print("\n== filters: one simulated press at 1 kHz, paper-level noise ==")
    rate = 1000.0
    skin = load_skin(skin_kind)
    print(f"skin: {skin.source}; noise {AdcNoise()}")
    rows: dict[str, dict[str, float]] = {name: {} for name in FILTERS}
    for speed in (0.001, 0.01):
        profile = LoadProfile(depth_m=0.003, speeds_m_s=(speed,), cycles=1, rest_s=10.0)
        world = BenchWorld(profile, skin, grid_hz=rate)
        t = np.arange(0.0, profile.duration_s, 1.0 / rate)
        v_true = np.asarray(world.photoreflector_voltage(t))
        counts = AdcSampler(rate, AdcNoise(), rng=seed).counts(v_true)[:, 0]
        volts = counts * chain_volts_per_count()
        # the lag of a filter is measured on the quantised but noise-free press: with the
        # paper's noise the best-fit shift scatters by ~3 ms at 1 mm/s on a single run
        clean = AdcSampler(rate, AdcNoise(white_v=0.0, drift_v=0.0)).counts(v_true)[:, 0]
        clean_volts = clean * chain_volts_per_count()
        truth = v_true[0] - v_true
        d = profile.indentation(t)
        press = d > 0.0
        rest = (t > 1.0) & (t < profile.rest_s - 0.1)
        rest |= t > profile.duration_s - profile.rest_s + 1.0
        for name in FILTERS:
            out = press_readings(name, volts, rate)
            row = rows[name]
            row[f"lag_{speed}"] = best_lag_ms(press_readings(name, clean_volts, rate), truth,
                                              press, rate)
            row[f"rms_{speed}"] = float(np.sqrt(np.nanmean((out[press] - truth[press]) ** 2)))
            if speed == 0.001:
                row["noise"] = float(np.std(out[rest]))
    print(f"{'filter':>15} {'lag 1mm/s':>10} {'lag 10mm/s':>11} {'rms err 1':>10} "
          f"{'rms err 10':>11} {'noise σ':>9} {'noise':>7} {'DR':>7}")
    figures = []
    for name, row in rows.items():
        noise_n = row["noise"] / PAPER_SENSITIVITY_V_PER_N
        dr = 20 * math.log10(PAPER_FULL_SCALE_N / noise_n)
        figures += [Figure(f"{name}: lag at 1 mm/s", round(row["lag_0.001"], 1), "ms"),
                    Figure(f"{name}: lag at 10 mm/s", round(row["lag_0.01"], 1), "ms"),
                    Figure(f"{name}: RMS error at 1 mm/s", row["rms_0.001"] * 1e3, "mV"),
                    Figure(f"{name}: RMS error at 10 mm/s", row["rms_0.01"] * 1e3, "mV"),
                    Figure(f"{name}: noise σ at rest", row["noise"] * 1e3, "mV"),
                    Figure(f"{name}: dynamic range", dr, "dB")]
        print(f"{name + (' *' if name == DEFAULT_FILTER else ''):>15} "
              f"{row['lag_0.001']:8.1f}ms {row['lag_0.01']:9.1f}ms "
              f"{row['rms_0.001'] * 1e3:8.1f}mV {row['rms_0.01'] * 1e3:9.1f}mV "
              f"{row['noise'] * 1e3:7.1f}mV {noise_n:5.3f}N {dr:5.1f}dB")
    ma, best = rows["moving_average"], rows[DEFAULT_FILTER]
    less_lag = all(best[f"lag_{s}"] < ma[f"lag_{s}"] for s in (0.001, 0.01))
    quieter = best["noise"] <= ma["noise"]
    print(f"(* default) {DEFAULT_FILTER} vs 9-point average: lag "
          f"{best['lag_0.001']:.1f}/{best['lag_0.01']:.1f} ms vs "
          f"{ma['lag_0.001']:.1f}/{ma['lag_0.01']:.1f} ms, noise {best['noise'] * 1e3:.1f} vs "
          f"{ma['noise'] * 1e3:.1f} mV -> goal {'met' if less_lag and quieter else 'NOT met'}")
    figures.append(Figure(f"default filter ({DEFAULT_FILTER}) against the 9-point average",
                          "less lag and no more noise" if less_lag and quieter else
                          "more lag or more noise", "",
                          "less lag at both speeds, noise no higher", less_lag and quieter))
    return figures


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=30.0,
                        help="streaming time per ingest rate (default 30)")
    parser.add_argument("--rates", default="1000,2000,5000,10000,20000,40000",
                        help="comma-separated ingest rates to try in order [Hz]")
    parser.add_argument("--seed", type=int, default=1, help="noise seed for the filter press")
    parser.add_argument("--skin", choices=("fem", "paper-linear"), default="fem",
                        help="skin response for the filter press: the FEM prediction "
                             "(default; falls back to paper-linear if physics fails) or a "
                             "linear curve from the paper's figures")
    parser.add_argument("--skip-ingest", action="store_true")
    parser.add_argument("--skip-filters", action="store_true")
    args = parser.parse_args(argv)
    figures: list[Figure] = []
    if not args.skip_filters:
        figures += bench_filters(args.seed, args.skin)
    if not args.skip_ingest:
        figures += bench_ingest([float(r) for r in args.rates.split(",")], args.seconds)
    write_results("adc", figures, notes="Filters: one simulated press at 1 kHz with the "
                  "paper's noise; lag on the noise-free press. Ingest: mock ADC in its own "
                  "process streaming on a pseudo-terminal.")
    return 0


if __name__ == "__main__":
    sys.exit(main())
