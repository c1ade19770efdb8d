"""Window height study: does a window higher up the side face read shear better?

Four modules (front, back, left, right). For each window centre height the module band
reaches 3 mm above it (as the default 3 mm window in a 6 mm band), or, with ``--band``, has
that fixed height (the window alone moves); the probe presses
3 mm (pure indentation, quarter model) and then, on a second path, presses 3 mm while moving
``--shear`` mm along +x (half model). Printed per height:

- normal sensitivity: the front module's output per newton of normal force [V/N];
- shear sensitivity: right minus left output per newton of lateral force [V/N];
- shear signal: right minus left output [V] at the shear, and its share of the normal
  output (how much of the modules' range shear moves);
- the largest window bulge [mm] (it must stay below the 2 mm gap);
- the normal force at 3 mm (a taller band stiffens the skin).

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_array_window.py [--scale 0.5] [--shear 3]
        [--heights 3 6 10 14] [--band 17]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tactile_sensor"))

from results import Figure, write_results

from tactile_sensor.physics.array_grid import grid_params
from tactile_sensor.physics.fem import SkinModel
from tactile_sensor.physics.params import PhysicsParams
from tactile_sensor.physics.prediction import module_output


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scale", type=float, default=0.5,
                        help="mesh elements per direction relative to the default (0.5: the "
                             "array grid's mesh)")
    parser.add_argument("--shear", type=float, default=3.0, help="lateral probe motion [mm]")
    parser.add_argument("--heights", type=float, nargs="+", default=[3.0, 6.0, 10.0, 14.0],
                        help="window centre heights above the base [mm]")
    parser.add_argument("--band", type=float,
                        help="fixed module band height [mm] (default: window centre + 3 mm)")
    args = parser.parse_args()
    print(f"{'window z':>8} {'band':>5} {'F_n':>6} {'S_n':>7} {'F_t':>6} {'S_t':>7} "
          f"{'R-L':>7} {'R-L/out':>7} {'bulge':>6} {'time':>5}")
    print(f"{'[mm]':>8} {'[mm]':>5} {'[N]':>6} {'[V/N]':>7} {'[N]':>6} {'[V/N]':>7} "
          f"{'[V]':>7} {'':>7} {'[mm]':>6} {'[s]':>5}")
    figures: list[Figure] = []
    for zc in args.heights:
        start = time.perf_counter()
        band = args.band if args.band is not None else zc + 3.0
        p = PhysicsParams(modules="front,back,left,right", window_center_z=zc * 1e-3,
                          module_height=band * 1e-3, array_mesh_scale=args.scale)
        p = grid_params(p)
        pure = SkinModel(p).sweep()
        shear = SkinModel(p.replace(max_shear_x=args.shear * 1e-3)).sweep()
        out = {f: module_output(p, b[-1])[2] for f, b in shear.bulges_m.items()}
        normal = float(module_output(p, pure.bulges_m["front"][-1])[2])
        diff = float(out["right"] - out["left"])
        bulge = max(float(abs(b).max()) for b in shear.bulges_m.values())
        print(f"{zc:8.1f} {band:5.1f} {pure.force_n[-1]:6.3f} "
              f"{normal / pure.force_n[-1]:7.4f} {shear.force_x_n[-1]:6.3f} "
              f"{diff / shear.force_x_n[-1]:7.4f} {diff:7.4f} {diff / normal:7.2f} "
              f"{bulge * 1e3:6.3f} {time.perf_counter() - start:5.1f}", flush=True)
        at = f"window at {zc:g} mm"
        figures += [Figure(f"{at}: normal sensitivity", normal / pure.force_n[-1], "V/N"),
                    Figure(f"{at}: shear sensitivity", diff / shear.force_x_n[-1], "V/N"),
                    Figure(f"{at}: shear signal / normal output", diff / normal),
                    Figure(f"{at}: largest bulge", bulge * 1e3, "mm", "< 2 mm gap",
                           bulge < 2e-3)]
    write_results("array_window", figures, notes=f"Mesh scale {args.scale:g}, shear "
                  f"{args.shear:g} mm, band " + (f"{args.band:g} mm" if args.band is not None
                                                 else "window centre + 3 mm") + ".")


if __name__ == "__main__":
    main()
