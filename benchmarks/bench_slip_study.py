"""Can the sensor see slip, and how fast? The study of ``analysis/slip`` on the FEM skin.

1. Resolution: each layout's tangential and normal force noise at the reflex bandwidths
   (10-100 Hz) from the module noise (39 mV per 1 kHz sample, the paper's 31.5 dB), the
   threshold for one false alarm an hour, and the ratio |Ft| / Fn it resolves at a grip.
2. Slip: objects of 50-300 g, static friction 0.3-1.0 (kinetic = static, and 0.8 x static),
   lifted, held at the least grip the margin detector allows at rest, then their load
   doubled over 100 ms or 10 ms; per bandwidth: how many slipped, the detector's delay from
   the onset (negative: it warned first), when the shear's plateau shows, the normal
   force's change and the vibration's band content against the noise, false alarms at rest.

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_slip_study.py [--plot slip_study.png]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tactile_sensor"))

from results import Figure, write_results

from tactile_sensor.analysis.slip.fem import ARRAY_MODULES, fem_skin, layout_grid
from tactile_sensor.analysis.slip.resolution import (
    REFLEX_BANDWIDTHS_HZ,
    local_sensitivity,
    resolution,
)
from tactile_sensor.analysis.slip.signature import Scenario
from tactile_sensor.analysis.slip.study import VIBRATION_BANDS_HZ, Skin, as_row, evaluate

#: Layouts compared: today's fingertip (one module) and the two that observe shear.
LAYOUTS = (("one module (today's gripper)", "front"), ("array, 4 modules", ARRAY_MODULES),
           ("wrench, 8 modules", ",".join(f"{f}@{s}0.0055" for f in
                                          ("front", "back", "left", "right")
                                          for s in ("-", ""))))
MASSES_KG = (0.05, 0.1, 0.2, 0.3)
STATIC_FRICTION = (0.3, 0.5, 0.7, 1.0)
KINETIC_SHARE = (1.0, 0.8)
DOUBLING_S = (0.1, 0.01)
GRIPS_N = (1.0, 2.0, 5.0)
#: The bandwidth the study chose (docs/gripper.md) and the friction errors tried there.
CHOSEN_HZ = 20.0
LEARNED = (0.9, 1.1)
#: Indentation [m] at which each layout's sensitivity is taken for the resolution table.
TABLE_INDENTATION_M = 0.001


def resolution_table(figures: list[Figure]) -> None:
    print("Resolution (1 false alarm an hour; |Ft|/Fn resolved from 0 at grips "
          + ", ".join(f"{g:g}" for g in GRIPS_N) + " N):")
    for name, modules in LAYOUTS:
        sens = local_sensitivity(layout_grid(modules), TABLE_INDENTATION_M)
        for hz in REFLEX_BANDWIDTHS_HZ:
            rows = [resolution(sens, hz, g) for g in GRIPS_N]
            res = rows[0]
            ratios = ", ".join(f"{r.resolved_ratio:.3f}" for r in rows)
            print(f"  {name:30s} {hz:5.0f} Hz: sigma Ft {res.tangential_n * 1e3:7.1f} mN, "
                  f"sigma Fn {res.sigma_n[2] * 1e3:6.1f} mN, k {res.k:.2f}, ratio {ratios}")
            figures += [Figure(f"{name} {hz:g} Hz: sigma Ft", res.tangential_n, "N"),
                        Figure(f"{name} {hz:g} Hz: sigma Fn", res.sigma_n[2], "N")]


def objects() -> list[Scenario]:
    return [Scenario(m, mu, mu * share, 1.0, double_s=ramp) for ramp in DOUBLING_S
            for m in MASSES_KG for mu in STATIC_FRICTION for share in KINETIC_SHARE]


def band_peak(rows: list[dict[str, Any]], low: float, high: float) -> float:
    """The largest vibration content in a band over ``rows``, in units of the noise's."""
    return max((r.get(f"vibration_snr_{low:g}_{high:g}hz", 0.0) for r in rows), default=0.0)


def summarise(hz: float, rows: list[dict[str, Any]], figures: list[Figure], label: str
              ) -> None:
    slipped = [r for r in rows if r["onset_after_doubling_ms"] is not None]
    delays = np.array([r["delay_ms"] for r in slipped if r["delay_ms"] is not None])
    missed = sum(r["delay_ms"] is None for r in slipped)
    plateau = np.array([r["plateau_ms"] for r in slipped if r["plateau_ms"] is not None])
    alarms = sum(r["rest_alarms"] for r in rows)
    grip = np.array([r["grip_over_least_doubled"] for r in rows])
    p95 = float(np.percentile(delays, 95)) if delays.size else float("nan")
    print(f"  {hz:5.0f} Hz: slipped {len(slipped)}/{len(rows)}, missed {missed}; delay "
          f"from onset median {np.median(delays) if delays.size else np.nan:6.1f} ms, p95 "
          f"{p95:6.1f}, max {delays.max() if delays.size else np.nan:6.1f}; plateau shows "
          f"after {np.median(plateau) if plateau.size else np.nan:5.1f} ms median "
          f"({np.percentile(plateau, 95) if plateau.size else np.nan:5.1f} p95); rest "
          f"alarms {alarms} in {len(rows) * 20:.0f} s; grip / least for doubled load "
          f"{grip.min():.2f}-{grip.max():.2f} ({np.sum(grip <= 1.5)} <= 1.5); normal change <= "
          f"{max((r['dip_sigmas'] for r in slipped), default=0):.2f} sigma; vibration "
          + ", ".join(f"{a:g}-{b:g} Hz <= {band_peak(slipped, a, b):.2f}"
                      for a, b in VIBRATION_BANDS_HZ) + " x noise")
    figures += [Figure(f"{hz:g} Hz, {label}: objects slipped", len(slipped)),
                Figure(f"{hz:g} Hz, {label}: slips missed", missed),
                Figure(f"{hz:g} Hz, {label}: delay from onset p95", p95, "ms"),
                Figure(f"{hz:g} Hz, {label}: plateau shows p95",
                       float(np.percentile(plateau, 95)) if plateau.size else float("nan"),
                       "ms"),
                Figure(f"{hz:g} Hz, {label}: false alarms at rest", alarms),
                Figure(f"{hz:g} Hz, {label}: grips <= 1.5 x least for the doubled load",
                       int(np.sum(grip <= 1.5)))]


def slip_study(skin: Skin, figures: list[Figure]) -> None:
    print(f"Slip ({len(objects())} objects, array layout, margin detector):")
    rng = np.random.default_rng(51)
    for hz in REFLEX_BANDWIDTHS_HZ:
        rows = [as_row(s, evaluate(s, skin, hz, rng)) for s in objects()]
        for ramp in DOUBLING_S:
            print(f"  load doubled over {ramp * 1e3:g} ms:", end="")
            summarise(hz, [r for r in rows if r["double_s"] == ramp], figures,
                      f"{ramp * 1e3:g} ms doubling")
        sys.stdout.flush()
    print(f"Friction learned wrong, at {CHOSEN_HZ:g} Hz (the hold and the detector believe "
          "it this many times the kinetic friction):")
    for learned in LEARNED:
        rows = [as_row(s, evaluate(s, skin, CHOSEN_HZ, rng, learned=learned))
                for s in objects()]
        print(f"  x {learned:g}:", end="")
        summarise(CHOSEN_HZ, rows, figures, f"friction believed x {learned:g}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--plot", type=Path, help="draw the study's figure to this file")
    args = parser.parse_args()
    figures: list[Figure] = []
    resolution_table(figures)
    skin = fem_skin()
    slip_study(skin, figures)
    series = example_series(skin)
    if args.plot:
        from docs_figures import slip_trace

        slip_trace({k: np.asarray(v) for k, v in series.items()}, args.plot)
        print(f"figure: {args.plot}")
    write_results("slip_study", figures, series=series,
                  notes="Objects per bandwidth: " + str(len(objects())) + "; rows in "
                  "the printout. Module noise 39 mV per sample, white.")


def example_series(skin: Skin) -> dict[str, Any]:
    """One slip at 30 Hz for the figure: 300 g, static friction 0.5, kinetic 0.4."""
    from tactile_sensor.analysis.slip.study import example_trace

    return example_trace(Scenario(0.3, 0.5, 0.4, 1.0), skin, 30.0, np.random.default_rng(3))


if __name__ == "__main__":
    main()
