"""FEM benchmark: the default prediction sweep (timing, paper figures) and a mesh study.

The product's sweep (``fem.extrapolated_sweep``) solves the default mesh and one with half
the elements per direction and Richardson-extrapolates. This prints, per mesh, nodes (of the
quarter model, and of the full body it stands for by symmetry), solve seconds, Newton and
GMRES iterations and factorisations, and force/bulge at the largest indentation; then the
extrapolated default sweep with its output and sensitivity and its total time; then (unless
``--no-study``) the mesh study: the same on a mesh twice as fine in each direction, whose
own extrapolation uses the default mesh as its half, with the observed convergence order
p = log2((f_h/2 - f_h) / (f_h - f_2h)) from the three meshes. ``--7k`` adds a raw sweep on a
quarter mesh of at least the paper's 7005 nodes.

The raw default and half sweeps always run (also with ``--no-study``), each with the split of
its time: residual evaluations (the stress), tangent assemblies, factorisations and
triangular solves, with their counts, which do not depend on the machine's load. Timings on a
shared machine are noisy: take the minimum of several runs, and note the load average that
is printed. A busy machine slows OpenBLAS' threads badly (the residual's GEMMs and SuperLU's
solves); ``OPENBLAS_NUM_THREADS=1`` shows the single-thread figure.

``--refresh-study`` sweeps the default mesh again for each ageing threshold of the GMRES
preconditioner (``fem.sweep._KRYLOV_REFRESH``: more GMRES iterations before a refactorisation) and
prints its time (best of two), factorisations and GMRES iterations: where the trade between
the two costs has its minimum, which bounds what the cold sweep can gain from that trade.

The 2x mesh takes tens of minutes (a factorisation of its 64k unknowns takes ~25 s) and
shows its progress; its first load steps need cutting (``SkinModel.sweep``), and a solve
that still fails is reported, not raised.
"""

from __future__ import annotations

import math
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tactile_sensor"))

from results import Figure, write_results

from tactile_sensor.physics.errors import ConvergenceError
from tactile_sensor.physics.fem import SkinModel, SweepResult, richardson
from tactile_sensor.physics.fem import sweep as solver
from tactile_sensor.physics.params import PhysicsParams
from tactile_sensor.physics.prediction import compute_curve, curve_from_sweep


def scaled(params: PhysicsParams, factor: float) -> PhysicsParams:
    return params.replace(mesh_nx=math.ceil(params.mesh_nx * factor),
                          mesh_ny=math.ceil(params.mesh_ny * factor),
                          mesh_nz=max(2, math.ceil(params.mesh_nz * factor)))


def raw(params: PhysicsParams, label: str, verbose: bool = False) -> SweepResult:
    return raw_with_stats(params, label, verbose)[0]


def raw_with_stats(params: PhysicsParams, label: str, verbose: bool = False
                   ) -> tuple[SweepResult, dict[str, float]]:
    model = SkinModel(params)
    start = time.perf_counter()

    def show(_fraction: float, message: str) -> None:
        print(f"  {label}, {time.perf_counter() - start:6.0f} s: {message}", flush=True)

    res = model.sweep(show if verbose else None)
    m = model.mesh
    full = np.prod([2 * np.unique(m.p[0]).size - 1, 2 * np.unique(m.p[1]).size - 1,
                    np.unique(m.p[2]).size])
    print(f"{label} ({params.mesh_nx}x{params.mesh_ny}x{params.mesh_nz}): nodes {res.nodes} "
          f"(full body by symmetry: {full}), solve {res.seconds:.2f} s, Newton iterations "
          f"{model.stats['iterations']}, GMRES iterations {model.stats['krylov']}, "
          f"factorisations {model.stats['factorisations']}, step cuts {model.stats['cuts']}; at "
          f"{params.max_indentation * 1e3:.1f} mm force {res.force_n[-1]:.4f} N, bulge "
          f"{res.bulge_m[-1] * 1e3:.5f} mm", flush=True)
    s = model.stats
    rest = res.seconds - sum(s[k] for k in ("residual_s", "tangent_s", "factorise_s",
                                             "solve_s"))
    print(f"  split: residuals {s['residual_s']:.2f} s ({s['residuals']}), tangents "
          f"{s['tangent_s']:.2f} s ({s['factorisations']}), factorisations "
          f"{s['factorise_s']:.2f} s, solves {s['solve_s']:.2f} s ({s['solves']}), "
          f"other {rest:.2f} s", flush=True)
    return res, s


def refresh_study(base: PhysicsParams, thresholds: list[int]) -> list[Figure]:
    """The default-mesh sweep at each preconditioner-ageing threshold (best of two)."""
    figures = []
    kept = solver._KRYLOV_REFRESH
    try:
        for threshold in thresholds:
            solver._KRYLOV_REFRESH = threshold
            runs = [raw_with_stats(base, f"default mesh, refresh after {threshold} GMRES "
                                         "iterations") for _ in range(2)]
            res, stats = min(runs, key=lambda r: r[0].seconds)
            figures += [Figure(f"refresh {threshold}: default-mesh sweep", res.seconds, "s"),
                        Figure(f"refresh {threshold}: factorisations",
                               stats["factorisations"], ""),
                        Figure(f"refresh {threshold}: GMRES iterations", stats["krylov"], "")]
    finally:
        solver._KRYLOV_REFRESH = kept
    return figures


def extrapolate(params: PhysicsParams, fine: SweepResult, coarse: SweepResult
                ) -> tuple[float, float]:
    return (float(richardson(fine.force_n[-1], coarse.force_n[-1], 2.0,
                             params.mesh_extrapolation_order_force)),
            float(richardson(fine.bulge_m[-1], coarse.bulge_m[-1], 2.0,
                             params.mesh_extrapolation_order_bulge)))


def change(a: float, b: float) -> str:
    return f"{abs(b / a - 1) * 100:.2f} %"


def main() -> None:
    base = PhysicsParams()
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores, "
          f"OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS', 'unset')}")
    start = time.perf_counter()
    curve = compute_curve(base)
    total = time.perf_counter() - start
    f, o = curve.force_n[-1], curve.output_v[-1]
    print(f"default prediction (extrapolated from {base.mesh_nx}x{base.mesh_ny}x{base.mesh_nz} "
          f"and half): solve {curve.seconds:.2f} s, total {total:.2f} s; at "
          f"{base.max_indentation * 1e3:.1f} mm force {f:.3f} N, bulge "
          f"{curve.bulge_m[-1] * 1e3:.4f} mm, output {o:.4f} V, sensitivity {o / f:.4f} V/N",
          flush=True)
    at = f"at {base.max_indentation * 1e3:.1f} mm"
    figures = [Figure("default prediction: solve", curve.seconds, "s"),
               Figure("default prediction: total", total, "s"),
               Figure(f"force {at}", f, "N", "about 7 N (paper)"),
               Figure(f"output {at}", o, "V"),
               Figure("sensitivity", o / f, "V/N", "about 0.07 V/N (paper)")]
    notes = (f"Load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores at the start, "
             f"OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS', 'unset')}.")
    if "--7k" in sys.argv:
        raw(base.replace(mesh_nx=12, mesh_ny=12, mesh_nz=42), "quarter mesh >= 7005 nodes")
    half = raw(scaled(base, 0.5), "half mesh")
    default, stats = raw_with_stats(base, "default mesh")
    print(f"raw default sweep {default.seconds:.2f} s; half {half.seconds:.2f} s; "
          f"load average now {os.getloadavg()[0]:.1f}", flush=True)
    figures += [Figure("raw default-mesh sweep", default.seconds, "s"),
                Figure("raw half-mesh sweep", half.seconds, "s"),
                Figure("default mesh: factorisations", stats["factorisations"], ""),
                Figure("default mesh: factorising", stats["factorise_s"], "s"),
                Figure("default mesh: tangent assembly", stats["tangent_s"], "s"),
                Figure("default mesh: residuals", stats["residual_s"], "s"),
                Figure("default mesh: triangular solves", stats["solve_s"], "s"),
                Figure("default mesh: GMRES iterations", stats["krylov"], "")]
    if "--refresh-study" in sys.argv:
        figures += refresh_study(base, [2, 4, 8, 12, 16, 24])
    if "--no-study" in sys.argv:
        write_results("fem", figures, notes=notes)
        return
    fine_params = scaled(base, 2.0)
    try:
        fine = raw(fine_params, "2x finer mesh", verbose=True)
    except ConvergenceError as exc:
        print(f"2x finer mesh ({fine_params.steps} steps): no result: {exc}")
        write_results("fem", figures, notes=f"{notes} The 2x finer mesh did not converge.")
        return
    f1, b1 = extrapolate(base, default, half)
    f2, b2 = extrapolate(fine_params, fine, default)
    print(f"mesh study, raw meshes: force changes {change(default.force_n[-1], fine.force_n[-1])}"
          f", bulge changes {change(default.bulge_m[-1], fine.bulge_m[-1])}")
    print(f"mesh study, extrapolated (the product's curve): force {f1:.4f} -> {f2:.4f} N "
          f"({change(f1, f2)}), bulge {b1 * 1e3:.5f} -> {b2 * 1e3:.5f} mm ({change(b1, b2)}); "
          "target < 2 %")
    figures += [Figure("mesh study: extrapolated force change on a 2x finer mesh",
                       100 * abs(f2 / f1 - 1), "%", "< 2 %", abs(f2 / f1 - 1) < 0.02),
                Figure("mesh study: extrapolated bulge change on a 2x finer mesh",
                       100 * abs(b2 / b1 - 1), "%", "< 2 %", abs(b2 / b1 - 1) < 0.02)]
    for name, key in (("force", "force_n"), ("bulge", "bulge_m")):
        a, b, c = (getattr(r, key)[1:] for r in (half, default, fine))
        with np.errstate(divide="ignore", invalid="ignore"):
            orders = np.log2((b - a) / (c - b))
        assumed = getattr(base, f"mesh_extrapolation_order_{name}")
        print(f"observed convergence order of the {name}: p = {orders[-1]:.2f} at "
              f"{base.max_indentation * 1e3:.1f} mm, {np.nanmin(orders):.2f}-"
              f"{np.nanmax(orders):.2f} over the sweep (extrapolation assumes {assumed:g})")
        if math.isfinite(orders[-1]) and orders[-1] > 0:
            limit = float(richardson(c[-1], b[-1], 2.0, orders[-1]))
            product = f1 if name == "force" else b1
            scale, unit = (1.0, "N") if name == "force" else (1e3, "mm")
            print(f"  three-mesh estimate of the converged {name}: {limit * scale:.4f} {unit}; "
                  f"the default prediction is {change(limit, product)} from it")
    plain = curve_from_sweep(base, default.indentation_m, default.force_n, default.bulge_m,
                             default.nodes, default.seconds)
    print(f"default mesh alone, for comparison: sensitivity "
          f"{plain.output_v[-1] / plain.force_n[-1]:.4f} V/N")
    figures.append(Figure("sensitivity, default mesh alone",
                          plain.output_v[-1] / plain.force_n[-1], "V/N"))
    write_results("fem", figures, notes=notes)


if __name__ == "__main__":
    main()
