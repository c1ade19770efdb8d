"""FEM benchmark: default bonded sweep (timing, paper figures) and a mesh study.

Prints nodes, solve seconds, Newton iterations and factorisations, force/bulge/output at the
largest indentation and the sensitivity; then the same sweep on a mesh twice as fine in each
direction (``--no-study`` skips it: it takes minutes with scipy's SuperLU).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tactile_sensor"))

from tactile_sensor.physics.fem import SkinModel
from tactile_sensor.physics.params import PhysicsParams
from tactile_sensor.physics.prediction import curve_from_sweep


def run(params: PhysicsParams, label: str) -> tuple[float, float]:
    start = time.perf_counter()
    model = SkinModel(params)
    res = model.sweep()
    total = time.perf_counter() - start
    curve = curve_from_sweep(params, res.indentation_m, res.force_n, res.bulge_m, res.nodes,
                             res.seconds)
    f, b, o = curve.force_n[-1], curve.bulge_m[-1], curve.output_v[-1]
    print(f"{label}: nodes {res.nodes}, steps {params.steps}, solve {res.seconds:.2f} s, "
          f"total {total:.2f} s, Newton iterations {model.stats['iterations']}, "
          f"factorisations {model.stats['factorisations']}")
    print(f"  at {params.max_indentation * 1e3:.1f} mm: force {f:.3f} N, bulge {b * 1e3:.4f} "
          f"mm, output {o:.4f} V, sensitivity {o / f:.4f} V/N")
    return f, b


def main() -> None:
    base = PhysicsParams()
    f1, b1 = run(base, "default mesh")
    if "--no-study" in sys.argv:
        return
    fine = base.replace(mesh_nx=2 * base.mesh_nx, mesh_ny=2 * base.mesh_ny,
                        mesh_nz=2 * base.mesh_nz)
    f2, b2 = run(fine, "2x finer mesh")
    print(f"mesh study: force changes {abs(f2 / f1 - 1) * 100:.2f} %, bulge changes "
          f"{abs(b2 / b1 - 1) * 100:.2f} % (target < 2 %)")


if __name__ == "__main__":
    main()
