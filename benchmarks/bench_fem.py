"""FEM benchmark: default bonded sweep (timing, paper figures) and a mesh study.

Prints nodes (of the quarter model, and of the full body it stands for by symmetry), solve
seconds, Newton iterations, GMRES iterations and factorisations, force/bulge/output at the
largest indentation and the sensitivity; then the sweep on a quarter mesh of at least the
paper's 7005 nodes (``--no-7k`` skips it), then the mesh study on a mesh twice as fine in each
direction (``--no-study`` skips it: it takes minutes with scipy's SuperLU).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

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
    m = model.mesh
    full = np.prod([2 * np.unique(m.p[0]).size - 1, 2 * np.unique(m.p[1]).size - 1,
                    np.unique(m.p[2]).size])
    print(f"{label}: nodes {res.nodes} (full body by symmetry: {full}), steps {params.steps}, "
          f"solve {res.seconds:.2f} s, total {total:.2f} s, Newton iterations "
          f"{model.stats['iterations']}, GMRES iterations {model.stats['krylov']}, "
          f"factorisations {model.stats['factorisations']}")
    print(f"  at {params.max_indentation * 1e3:.1f} mm: force {f:.3f} N, bulge {b * 1e3:.4f} "
          f"mm, output {o:.4f} V, sensitivity {o / f:.4f} V/N")
    return f, b


def main() -> None:
    base = PhysicsParams()
    f1, b1 = run(base, "default mesh")
    if "--no-7k" not in sys.argv:
        run(base.replace(mesh_nx=12, mesh_ny=12, mesh_nz=42), "quarter mesh >= 7005 nodes")
    if "--no-study" in sys.argv:
        return
    fine = base.replace(mesh_nx=2 * base.mesh_nx, mesh_ny=2 * base.mesh_ny,
                        mesh_nz=2 * base.mesh_nz)
    f2, b2 = run(fine, "2x finer mesh")
    print(f"mesh study: force changes {abs(f2 / f1 - 1) * 100:.2f} %, bulge changes "
          f"{abs(b2 / b1 - 1) * 100:.2f} % (target < 2 %)")


if __name__ == "__main__":
    main()
