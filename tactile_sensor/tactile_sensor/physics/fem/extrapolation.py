"""Mesh extrapolation: a sweep Richardson-extrapolated with one on a mesh half as fine."""

from __future__ import annotations

import math

import numpy as np

from ..errors import PhysicsError
from ..params import PhysicsParams
from .sweep import Progress, SkinModel, SweepResult


def extrapolated_sweep(params: PhysicsParams, progress: Progress | None = None,
                       full: tuple[bool, bool] | None = None) -> SweepResult:
    """The sweep on the parameters' mesh, Richardson-extrapolated with one half as fine.

    Why: the window's bulge converges with a large constant (the default mesh alone reads
    ~7 % low; one fine enough on its own costs minutes), and the half-as-fine sweep costs an
    eighth of the unknowns. With an error C h^p on both meshes, f + (f - f_coarse) / (r^p - 1)
    cancels the leading term. Force and bulge converge at different orders (the force is
    dominated by the edge singularities), each measured by ``benchmarks/bench_fem.py`` from
    three meshes and set as a parameter; an order of 0 keeps that quantity's mesh value.
    The lateral forces take the force's order. ``full`` as for :class:`SkinModel`.
    """
    p_force = params.mesh_extrapolation_order_force
    p_bulge = params.mesh_extrapolation_order_bulge
    if p_force == 0 and p_bulge == 0:
        return SkinModel(params, full).sweep(progress)
    counts = (params.mesh_nx, params.mesh_ny, params.mesh_nz)
    halved = (max(1, math.ceil(params.mesh_nx / 2)), max(1, math.ceil(params.mesh_ny / 2)),
              max(2, math.ceil(params.mesh_nz / 2)))
    coarse_params = params.replace(mesh_nx=halved[0], mesh_ny=halved[1], mesh_nz=halved[2])
    share = 0.15  # of the time, roughly, the coarse sweep takes

    def stage(lo: float, hi: float, label: str) -> Progress | None:
        if progress is None:
            return None
        return lambda f, msg: progress(lo + (hi - lo) * f, f"{label}: {msg}")

    try:
        coarse_model = SkinModel(coarse_params, full)
    except PhysicsError as exc:
        raise PhysicsError(f"The half-as-fine mesh the extrapolation needs ({halved[0]} x "
                           f"{halved[1]} x {halved[2]} elements) is too coarse: {exc} Or set "
                           "mesh_extrapolation_order_force and mesh_extrapolation_order_bulge "
                           "to 0.") from None
    coarse = coarse_model.sweep(stage(0.0, share, "half-as-fine mesh"))
    fine = SkinModel(params, full).sweep(stage(share, 1.0, "mesh"))
    ratio = float(np.prod(counts) / np.prod(halved)) ** (1.0 / 3.0)

    def force(name: str) -> np.ndarray:
        return richardson(getattr(fine, name), getattr(coarse, name), ratio, p_force)

    bulges = {face: richardson(fine.bulges_m[face], coarse.bulges_m[face], ratio, p_bulge)
              for face in fine.bulges_m}
    tangents = {face: richardson(fine.tangents_m[face], coarse.tangents_m[face], ratio,
                                 p_bulge) for face in fine.tangents_m}
    return SweepResult(fine.indentation_m, force("force_n"), bulges[params.module_faces[0]],
                       fine.nodes, fine.seconds + coarse.seconds, fine.shear_x_m,
                       fine.shear_y_m, force("force_x_n"), force("force_y_n"), bulges,
                       fine.rotation_rad, force("torque_nm"), tangents)


def richardson(fine: np.ndarray, coarse: np.ndarray, ratio: float, order: float
               ) -> np.ndarray:
    """f + (f - f_coarse) / (r^p - 1): the leading C h^p error of both cancels (p = 0: f)."""
    if order == 0:
        return fine
    return fine + (fine - coarse) / (ratio**order - 1.0)
