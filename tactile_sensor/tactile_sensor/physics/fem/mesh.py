"""The structured hexahedral mesh of the skin block, graded toward its singular edges."""

from __future__ import annotations

import itertools

import numpy as np
import skfem

from ..params import FACES, PhysicsParams


def _axis(breaks: list[float], n: int, refine: tuple[float, ...] = (), grading: float = 1.0,
          length: float = 1.0) -> np.ndarray:
    """Node coordinates over sorted breakpoints with about n elements in total.

    Every breakpoint is a node (window edges and symmetry planes stay on element faces).
    The element size grows linearly with the distance from the nearest point of ``refine``,
    from 1 there to ``grading`` at ``length`` and beyond: geometric grading toward edges where
    the solution is singular (a clamped edge meeting a free surface), near which the window's
    bulge on a near-uniform mesh converged at observed order 0.5. The size function is fixed
    and n only scales it, so doubling n about halves every element (the mesh study's "twice
    as fine").
    """
    breaks = sorted(set(breaks))
    lo, hi = breaks[0], breaks[-1]
    xs = np.linspace(lo, hi, 20001)
    size = np.ones_like(xs)
    if refine and grading > 1.0:
        dist = np.min(np.abs(xs[:, None] - np.asarray(refine)[None, :]), axis=1)
        size = np.minimum(grading, 1.0 + (grading - 1.0) * dist / length)
    density = 1.0 / size                    # elements per unit length, up to a scale
    count = np.concatenate([[0.0], np.cumsum(0.5 * (density[1:] + density[:-1])
                                             * np.diff(xs))])
    count *= n / count[-1]
    pts: list[np.ndarray] = []
    for b0, b1 in itertools.pairwise(breaks):
        c0, c1 = np.interp([b0, b1], xs, count)
        k = max(1, round(c1 - c0))
        pts.append(np.interp(np.linspace(c0, c1, k + 1)[:-1], count, xs))
        pts[-1][0] = b0                     # breakpoints exactly
    return np.concatenate([*pts, [hi]])


def build_mesh(params: PhysicsParams, full: tuple[bool, bool] = (False, False)
               ) -> skfem.MeshHex:
    """Structured hexahedral mesh: the quarter x in [0, W/2], y in [0, D/2], z in [0, H],
    mirrored to x in [-W/2, W/2] when ``full[0]`` and likewise y when ``full[1]``.

    Bonded with a module: graded toward the windows' edges, the band's top edge (z), the
    probe's edge (z) and the windowed faces, the singular edges and the faces whose
    displacement the photoreflectors read. Frictionless: uniform (the solution is).
    """
    p = params
    hw, hd = p.width / 2, p.depth / 2
    g, length = p.mesh_grading, p.mesh_grading_length
    if p.boundary != "bonded" or p.module_height <= 0:
        top = (p.height,) if p.boundary == "bonded" else ()   # the probe edge, if bonded
        x, y = _axis([0.0, hw], p.mesh_nx), _axis([0.0, hd], p.mesh_ny)
        z = _axis([0.0, p.height], p.mesh_nz, top, g, length)
    else:
        ww = p.window_width / 2
        z0 = p.window_center_z - p.window_height / 2
        z1 = p.window_center_z + p.window_height / 2
        axes = {FACES[f][0] for f in p.window_faces}       # normals of the windowed faces
        half = (hw, hd)
        per_axis = []
        for k in (0, 1):
            breaks, refine = [0.0, half[k]], []
            # windows on the faces across this axis span |coordinate - offset| < ww; their
            # edges and their mirror images' (|offset -+ ww|) are nodes, so the mirrored
            # mesh of a full model has every window's edges too
            edges = sorted({abs(c + s * ww) for f, c in p.windows if FACES[f][0] == 1 - k
                            for s in (-1, 1)})
            breaks += edges
            refine += edges
            if k in axes:              # windows on this axis' own faces
                refine.append(half[k])
            per_axis.append(_axis(breaks, (p.mesh_nx, p.mesh_ny)[k], tuple(refine), g,
                                  length))
        x, y = per_axis
        z = _axis([0.0, z0, z1, p.module_height, p.height], p.mesh_nz,
                  (z0, z1, p.module_height, p.height), g, length)
    return skfem.MeshHex.init_tensor(_mirror(x, full[0]), _mirror(y, full[1]), z)


def _mirror(axis: np.ndarray, full: bool) -> np.ndarray:
    """The axis [0, h] or, for the full span, its mirror image joined to it."""
    return np.concatenate([-axis[:0:-1], axis]) if full else axis
