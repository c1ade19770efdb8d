"""Which wrench components module layouts resolve: four centred windows against two per face.

Solves the wrench paths of ``physics/wrench.py`` (press, shear, tilt about x and y, twist
about z; symmetric loads from the layout's symmetries) for each layout and prints the
sensitivity matrix S6 with each column scaled to its full-scale load [V], the full scales,
and ``observability.wrench_metrics``: the singular values [V], the resolved directions and
each component's signal beyond the forces, against 3 x ``--noise``.

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_torque_layout.py [--offset 0.0055]
        [--noise 0.013] [--steps 3]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tactile_sensor"))

from results import Figure, write_results

from tactile_sensor.physics.observability import full_scale, wrench_matrix, wrench_metrics
from tactile_sensor.physics.params import PhysicsParams
from tactile_sensor.physics.wrench import compute_wrench_set


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--offset", type=float, default=0.0055, help="window offset [m]")
    parser.add_argument("--noise", type=float, default=0.013, help="module noise [V]")
    parser.add_argument("--steps", type=int, default=3, help="indentation levels")
    args = parser.parse_args()
    faces = ("front", "back", "left", "right")
    layouts = [",".join(faces),
               ",".join(f"{f}@{s * args.offset:g}" for f in faces for s in (-1, 1))]
    figures: list[Figure] = []
    for modules in layouts:
        params = PhysicsParams(modules=modules, array_steps=args.steps)
        start = time.perf_counter()
        data = compute_wrench_set(params)
        metrics = wrench_metrics(data, args.noise)
        print(f"{modules}: {time.perf_counter() - start:.0f} s, {data.paths} paths solved")
        print("S6 x full scale [V] (columns Fx Fy Fz Tx Ty Tz):")
        print(np.array2string(wrench_matrix(data) * full_scale(data), precision=4,
                              suppress_small=True))
        print("full scale (N, N m):", np.array2string(full_scale(data), precision=5))
        for name, value in metrics.items():
            if not name.startswith("full_scale"):
                print(f"  {name} {value:.4g}")
                figures.append(Figure(f"{modules}: {name}", float(value)))
        sys.stdout.flush()
    write_results("torque_layout", figures, notes=f"Window offset {args.offset:g} m, module "
                  f"noise {args.noise:g} V, {args.steps} indentation levels.")


if __name__ == "__main__":
    main()
