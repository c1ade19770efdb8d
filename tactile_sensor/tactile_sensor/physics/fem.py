"""Total-Lagrangian finite-element model of the skin block pressed by a flat probe.

Nearly incompressible Mooney–Rivlin solid on trilinear hexahedra with the mean-dilatation
(Q1–P0) treatment of the volume term, which avoids volumetric locking: the pressure is one
constant per element, condensed element by element, so the global system holds displacements
only. scikit-fem supplies the mesh, the shape-function gradients and the quadrature; the
hyperelastic residual and tangent are assembled here with vectorised numpy (scikit-fem's
generic form assembly is an order of magnitude slower for this) into a CSR matrix whose
pattern and scatter indices are computed once. Each Newton correction is solved by GMRES with
a factorised tangent as preconditioner, reused across iterations and load steps until GMRES
needs too many iterations (factorising is what costs; see ``SkinModel._newton``). The mesh is
graded toward the singular edges, and predictions Richardson-extrapolate it with a mesh half
as fine (``extrapolated_sweep``).

Quarter model: the block is symmetric about x = 0 and y = 0. Windows are centred on their
face and come in opposite pairs (a module's wall and the one facing it have the same window —
see ``PhysicsParams.modules``), so pure indentation is symmetric about both planes. A lateral
probe displacement along x breaks the symmetry about x = 0 (but keeps y = 0), so that load
path solves the half model x in [-W/2, W/2]; one along y the other half; both, the full
block. The half and full meshes are the quarter mesh mirrored, so on pure indentation all
three give the same numbers to the solver's tolerance (tested). Likewise a tilt of the probe
about x spans y, a tilt about y spans x, a twist about z both, and windows off their face's
centre without a mirror image span the axis they break (``spans_needed``). Tilt and twist
turn the probe's nodes rigidly about the probe's centre (``SkinModel.probe_motion``); the
probe's torque is the moment of their reactions (``SkinModel.probe_torque``).
"""

from __future__ import annotations

import itertools
import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
import skfem

from .errors import ConvergenceError, PhysicsError
from .params import FACES, PhysicsParams

Progress = Callable[[float, str], None]

_RESIDUAL_TOL = 1e-6  # converged when |out-of-balance force| < this * mu * height^2
#: How far two solves of the same design may differ, relative: both stop anywhere inside the
#: residual tolerance, and where inside depends on the rounding of every sum on the way (the
#: BLAS build, its kernel for this processor, its threads). A study promises its figures to
#: this, not to the bit, on any worker (docs/design-studies.md).
REPRODUCIBLE_RTOL = _RESIDUAL_TOL
_KRYLOV_RTOL = 1e-4   # relative residual of each Newton correction (inexact Newton) ...
_KRYLOV_TARGET = 0.02  # ... or this fraction of the tolerance, whichever is larger: well
#                        below it, so a load step converges in one correction (a second
#                        costs more than the ~2 GMRES iterations per decade this takes)
_KRYLOV_MAX = 40      # GMRES iterations after which a correction is given up (refactorise)
_KRYLOV_REFRESH = 4   # a correction that took more GMRES iterations ages the tangent out:
#                       on the default mesh 8 factorisations and 107 GMRES iterations
#                       instead of 6 and 186 at 12 (a factorisation with its tangent
#                       costs ~25 iterations since it is gathered in place and ordered
#                       by node planes; 5-10 % less CPU per sweep)
_PIVOT_THRESHOLD = 0.1  # SuperLU's diag_pivot_thresh (the tangent is symmetric, near SPD)
_LU_DTYPE = np.float32  # the factorised tangent only preconditions GMRES on the float64
#                         residual, and its ~1e-3 relative error is far below its ageing
#                         error; single precision factorises ~1.5x and solves ~1.4x faster
_NEWTON_MAX = 15      # Newton iterations per load step before the step is cut
_NEWTON_DIVERGED = 10.0  # the step is cut once the residual grows this much over its start
_MAX_CUTS = 4         # a failed load step is halved at most this often (to 1/16 of a step)


@dataclass(frozen=True)
class SweepResult:
    """Per load step: probe position, probe force on the skin, window-averaged bulges.

    ``force_n`` is the probe's force on the skin along -z (positive pressing), ``force_x_n``
    and ``force_y_n`` along +x and +y: each positive along the probe's own displacement when
    it moves along one axis. ``bulges_m`` maps each module face to its window's outward
    displacement [m]; ``bulge_m`` is the first module's (front's, by default).
    ``tangents_m`` maps each module to its window's displacement along the face's
    counter-clockwise tangent t = z x n (n the outward normal: front -x, right +y, back +x,
    left -y) [m], averaged with the same weights: what a graded pigment turns into light.
    ``rotation_rad`` (steps, 3) is the probe's rotation vector (tilt about x, tilt about y,
    twist about z) and ``torque_nm`` (steps, 3) the probe's torque on the skin about the
    probe's centre (Tx, Ty, Tz), right-hand rule about +x, +y, +z: positive along the probe's
    own rotation when it turns about one axis.
    """

    indentation_m: np.ndarray
    force_n: np.ndarray
    bulge_m: np.ndarray
    nodes: int
    seconds: float
    shear_x_m: np.ndarray
    shear_y_m: np.ndarray
    force_x_n: np.ndarray
    force_y_n: np.ndarray
    bulges_m: dict[str, np.ndarray]
    rotation_rad: np.ndarray
    torque_nm: np.ndarray
    tangents_m: dict[str, np.ndarray]


# --------------------------------------------------------------------------------------------
# mesh


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


# --------------------------------------------------------------------------------------------
# constitutive law


def _cofactor(f: np.ndarray) -> np.ndarray:
    """cof F = J F^-T of component-first (3, 3, ...) arrays (in place, as the stress)."""
    cof = np.empty_like(f)
    tmp = np.empty_like(f[0, 0])
    for i in range(3):
        i1, i2 = (i + 1) % 3, (i + 2) % 3
        for j in range(3):
            j1, j2 = (j + 1) % 3, (j + 2) % 3
            np.multiply(f[i1, j1], f[i2, j2], out=cof[i, j])
            cof[i, j] -= np.multiply(f[i1, j2], f[i2, j1], out=tmp)
    return cof


def _mooney_rivlin_piola(F: np.ndarray, c10: float, c01: float, pres: np.ndarray
                         ) -> tuple[np.ndarray, np.ndarray]:
    """First Piola stress and J of the Mooney–Rivlin law plus a given pressure, component-first.

    F has shape (3, 3, N). W = C10 (J^-2/3 I1 - 3) + C01 (J^-4/3 I2 - 3) + volume term (mean
    dilatation, entering through ``pres``). Written out per component: numpy's batched 3 x 3
    inverse and matrix products cost ten times more on this many tiny matrices. Products go
    through one reused work array and accumulate in place: half the time of fresh temporaries
    (1.1 against 2.8 ms per call on the default mesh, on a busy machine).
    """
    f = F
    cof = _cofactor(F)                                         # J F^-T
    tmp = np.empty_like(cof[0, 0])
    J = f[0, 0] * cof[0, 0]
    for k in (1, 2):
        J += np.multiply(f[0, k], cof[0, k], out=tmp)
    C: dict[tuple[int, int], np.ndarray] = {}                  # right Cauchy-Green
    for i in range(3):
        for j in range(i, 3):
            c = f[0, i] * f[0, j]
            c += np.multiply(f[1, i], f[1, j], out=tmp)
            c += np.multiply(f[2, i], f[2, j], out=tmp)
            C[i, j] = C[j, i] = c
    I1 = C[0, 0] + C[1, 1]
    I1 += C[2, 2]
    CC = C[0, 0] * C[0, 0]                                     # C : C
    for key, weight in (((1, 1), 1.0), ((2, 2), 1.0), ((0, 1), 2.0), ((0, 2), 2.0),
                        ((1, 2), 2.0)):
        np.multiply(C[key], C[key], out=tmp)
        if weight != 1.0:
            tmp *= weight
        CC += tmp
    I2 = I1 * I1
    I2 -= CC
    I2 *= 0.5
    j13 = np.cbrt(J) if np.isrealobj(J) else J ** (1.0 / 3.0)
    j23 = j13 * j13
    al = c10 / j23                                             # C10 J^-2/3
    be = c01 / (j23 * j23)                                     # C01 J^-4/3
    g = (-(2.0 / 3.0) * al * I1 - (4.0 / 3.0) * be * I2 + pres * J) / J  # coefficient of cof
    s1 = 2.0 * (al + be * I1)                                  # coefficient of F
    m2 = -2.0 * be                                             # coefficient of F C
    P = np.empty_like(F)
    for i in range(3):
        for j in range(3):
            p = P[i, j]
            np.multiply(f[i, 0], C[0, j], out=p)
            p += np.multiply(f[i, 1], C[1, j], out=tmp)
            p += np.multiply(f[i, 2], C[2, j], out=tmp)
            p *= m2
            p += np.multiply(s1, f[i, j], out=tmp)
            p += np.multiply(g, cof[i, j], out=tmp)
    return P, J


def _mooney_rivlin_tangent(F: np.ndarray, c10: float, c01: float, pres: np.ndarray
                           ) -> tuple[np.ndarray, np.ndarray]:
    """First Piola stress and its tangent A_iKkL = dP_iK/dF_kL (pressure held), closed form.

    Why: the complex-step tangent evaluated the stress nine times in complex arithmetic,
    about three assemblies' worth of work per factorisation. With M = I1 F - F C, cof F and
    the scalars of :func:`_mooney_rivlin_piola`, A is three symmetric rank-one products in
    (iK, kL), the same with K and L swapped, and Kronecker terms of 1, B = F F^T and C:

        A = 4 be F(x)F - 4/3 al/J (F(x)c + c(x)F) - 8/3 be/J (M(x)c + c(x)M)
            + (10/9 al I1 + 28/9 be I2) / J^2 c(x)c + g/J [c(x)c - swap(c(x)c)]
            - 2 be swap(F(x)F) + 2 (al + be I1) d_ik d_KL - 2 be (d_ik C_LK + B_ik d_KL)

    F and A are component-first, shapes (3, 3, ...) and (3, 3, 3, 3, ...).
    """
    shape = F.shape[2:]
    n = int(np.prod(shape))
    f = F.reshape(9, n)
    cof = _cofactor(F).reshape(9, n)
    J = (f[0] * cof[0] + f[1] * cof[1] + f[2] * cof[2])
    F3 = f.reshape(3, 3, n)
    C = np.einsum("kin,kjn->ijn", F3, F3)
    B = np.einsum("ikn,jkn->ijn", F3, F3)
    I1 = C[0, 0] + C[1, 1] + C[2, 2]
    I2 = 0.5 * (I1 * I1 - np.einsum("ijn,ijn->n", C, C))
    FC = np.einsum("ikn,kjn->ijn", F3, C).reshape(9, n)
    M = I1 * f - FC                                            # dI2/dF / 2
    j13 = np.cbrt(J)
    al = c10 / (j13 * j13)
    be = c01 / (j13 * j13) ** 2
    pres = np.broadcast_to(pres, shape).reshape(n)
    Jinv = 1.0 / J
    g = (-(2.0 / 3.0) * al * I1 - (4.0 / 3.0) * be * I2) * Jinv + pres
    P = (2.0 * (al + be * I1)) * f - (2.0 * be) * FC + g * cof
    # rank-one terms: F(x)x + c(x)y + M(x)z with x, y, z collecting the coefficients
    a_fc = -(4.0 / 3.0) * al * Jinv
    a_mc = -(8.0 / 3.0) * be * Jinv
    a_cc = ((10.0 / 9.0) * al * I1 + (28.0 / 9.0) * be * I2) * Jinv * Jinv + g * Jinv
    x = (4.0 * be) * f + a_fc * cof
    y = a_fc * f + a_mc * M + a_cc * cof
    z = a_mc * cof
    A = f[:, None] * x[None]
    A += cof[:, None] * y[None]
    A += M[:, None] * z[None]
    # the same with K and L swapped: -2 be F_iL F_kK - g/J c_iL c_kK
    S = f[:, None] * ((-2.0 * be) * f)[None]
    S -= cof[:, None] * (g * Jinv * cof)[None]
    A6 = A.reshape(3, 3, 3, 3, n)
    A6 += S.reshape(3, 3, 3, 3, n).transpose(0, 3, 2, 1, 4)
    diag = 2.0 * (al + be * I1)
    twobe_C = (2.0 * be) * C.transpose(1, 0, 2)                      # 2 be C_LK at [K, L]
    twobe_B = (2.0 * be) * B
    for i in range(3):
        A6[i, :, i, :] -= twobe_C                                     # d_ik C_LK
        A6[:, i, :, i] -= twobe_B                                     # B_ik d_KL
        for K in range(3):
            A6[i, K, i, K] += diag                                    # d_ik d_KL
    return P.reshape(3, 3, *shape), A6.reshape(3, 3, 3, 3, *shape)


# --------------------------------------------------------------------------------------------
# model


class SkinModel:
    """The discretised skin block with its boundary conditions, ready to sweep the load."""

    def __init__(self, params: PhysicsParams, full: tuple[bool, bool] | None = None) -> None:
        """``full``: whether the model spans the whole width (x) and depth (y); by default
        the quarter, or the half or full block a shear load path needs."""
        self.params = params
        needed = spans_needed(params)
        if full is None:
            full = needed
        elif (needed[0] and not full[0]) or (needed[1] and not full[1]):
            raise PhysicsError("This load path or window layout needs the model to span the "
                               "axis it shears along, turns about or whose mirror the windows "
                               f"break; pass full={needed}.")
        self.full = (bool(full[0]), bool(full[1]))
        self.mesh = build_mesh(params, self.full)
        mesh = self.mesh
        basis = skfem.Basis(mesh, skfem.ElementHex1(), intorder=2)
        nel = mesh.t.shape[1]
        # dNdX[e, q, a, K]
        self._dndx = np.stack([np.stack(basis.basis[a][0].grad, axis=-1)
                               for a in range(8)], axis=2)
        self._w = basis.dx                                   # (e, q)
        self._vol = self._w.sum(axis=1)                      # (e,)
        self._conn = mesh.t.T                                # (e, 8)
        edofs = (3 * self._conn[:, :, None] + np.arange(3)).reshape(nel, 24)
        self._edofs = edofs
        self.ndof = 3 * mesh.p.shape[1]
        self.nodes = mesh.p.shape[1]
        self._gradient = _GradientOperator(self._dndx, self._w, mesh.p[:, self._conn.T])
        self._setup_constraints()
        self._setup_pattern()
        self._stale = False
        # counts, and seconds spent (for the benchmark's split of the sweep's time)
        self.stats: dict[str, float] = {
            "factorisations": 0, "iterations": 0, "krylov": 0, "residuals": 0, "solves": 0,
            "cuts": 0, "residual_s": 0.0, "tangent_s": 0.0, "factorise_s": 0.0,
            "solve_s": 0.0}

    # -- boundary conditions -------------------------------------------------------------------
    def _in_mesh(self, face: str, offset: float) -> tuple[str, float]:
        """The window itself, or the mirror window standing for it in a symmetric model."""
        axis, sign = FACES[face]
        if not (sign > 0 or self.full[axis]):
            face = next(f for f, (a, s) in FACES.items() if a == axis and s > 0)
        if offset < 0 and not self.full[1 - axis]:
            offset = -offset
        return face, offset

    def _setup_constraints(self) -> None:
        p = self.params
        X = self.mesh.p
        tol = 1e-9 * max(p.width, p.height)
        z = X[2]
        half = (p.width / 2, p.depth / 2)
        zc, wh, ww = p.window_center_z, p.window_height / 2, p.window_width / 2
        fixed = np.zeros((self.nodes, 3), dtype=bool)
        bottom = z < tol
        top = z > p.height - tol
        for k in (0, 1):
            if not self.full[k]:
                fixed[X[k] < tol, k] = True                   # symmetry plane x or y = 0
        if p.boundary == "bonded":
            fixed[bottom, :] = True
            fixed[top, :] = True
            if p.module_height > 0:
                band = z <= p.module_height + tol
                for face, (k, sign) in FACES.items():
                    wall = band & (sign * X[k] > half[k] - tol)
                    if not wall.any():
                        continue                              # beyond a symmetry plane
                    window = np.zeros_like(wall)
                    for c in (c for f, c in p.windows if f == face):
                        one = wall & (abs(X[1 - k] - c) < ww - tol) & (abs(z - zc) < wh - tol)
                        if not one.any() and c >= X[1 - k].min() - tol:
                            raise PhysicsError("The mesh has no node inside the "
                                               "photoreflector window; raise mesh_nx, "
                                               "mesh_ny and mesh_nz or enlarge the window.")
                        window |= one
                    fixed[wall & ~window, :] = True
        else:
            fixed[bottom, 2] = True
            fixed[top, 2] = True
        self._top = top
        self._fixed = fixed.ravel()
        self._free = np.flatnonzero(~self._fixed)
        self._patches = {name: self._window_patch(*self._in_mesh(face, c))
                         for name, (face, c) in zip(p.module_faces, p.module_windows,
                                                    strict=True)}
        self._tangent_factors = {name: self._tangent_factor(face, c)
                                 for name, (face, c) in zip(p.module_faces, p.module_windows,
                                                            strict=True)}

    def _tangent_factor(self, face: str, offset: float) -> float:
        """What turns the in-mesh patch's displacement across its face into this window's
        tangential displacement: the tangent's sign on the in-mesh face, times -1 for each
        mirror that stands in for the window in a symmetric model (a mirror reverses the
        counter-clockwise tangent), and 0 for a window centred on a symmetry plane the model
        does not span (the load is mirror-symmetric there: its mean tangential motion is 0,
        while the half window in the mesh would read one side only)."""
        axis = FACES[face][0]
        if offset == 0 and not self.full[1 - axis]:
            return 0.0
        image, moved = self._in_mesh(face, offset)
        mirrors = (image != face) + (moved != offset)
        k, sign = FACES[image]
        along = sign if k == 0 else -sign        # t = z x n: +y on right, -x on front
        return float(along * (-1) ** mirrors)

    def _window_patch(self, face: str, offset: float = 0.0) -> tuple[int, int, np.ndarray]:
        """(axis, outward sign, node weights): the area-weighted average of the face's
        outward displacement over its quads inside the window."""
        p = self.params
        x = self.mesh.p
        k, sign = FACES[face]
        h = (p.width / 2, p.depth / 2)[k]
        tol = 1e-9 * max(p.width, p.height)
        zc, wh, ww = p.window_center_z, p.window_height / 2, p.window_width / 2
        weights = np.zeros(self.nodes)
        facets = self.mesh.facets
        on_face = np.all(sign * x[k][facets] > h - tol, axis=0)
        across = x[1 - k][facets]
        cz = x[2][facets].mean(axis=0)
        inside = on_face & (abs(across.mean(axis=0) - offset) < ww) & (abs(cz - zc) < wh)
        for f in np.flatnonzero(inside):
            nodes = facets[:, f]
            area = np.ptp(across[:, f]) * np.ptp(x[2][nodes])
            np.add.at(weights, nodes, area / 4)
        if weights.sum() == 0:  # window finer than the mesh: nearest node of the face
            cand = np.flatnonzero(sign * x[k] > h - tol)
            weights[cand[np.argmin((x[1 - k][cand] - offset) ** 2 + (x[2][cand] - zc) ** 2)]
                    ] = 1.0
        return k, sign, weights / weights.sum()

    def bulges(self, u: np.ndarray) -> dict[str, float]:
        """Each module's window-averaged outward displacement [m] in state u."""
        u3 = u.reshape(-1, 3)
        return {face: float(sign * (w @ u3[:, k]))
                for face, (k, sign, w) in self._patches.items()}

    def tangents(self, u: np.ndarray) -> dict[str, float]:
        """Each module's window-averaged displacement along its face's counter-clockwise
        tangent [m] in state u (see :class:`SweepResult`)."""
        u3 = u.reshape(-1, 3)
        return {face: self._tangent_factors[face] * float(w @ u3[:, 1 - k])
                for face, (k, _, w) in self._patches.items()}

    def probe_force(self, fint: np.ndarray) -> tuple[float, float, float]:
        """The probe's force on the skin (+x, +y, -z) [N] from the internal forces.

        A symmetric model stands for 2 or 4 copies of itself; along a symmetry plane's
        normal the copies' forces cancel.
        """
        on_top = fint.reshape(-1, 3)[self._top].sum(axis=0)
        copies = (1 if self.full[0] else 2) * (1 if self.full[1] else 2)
        fx = copies * float(on_top[0]) if self.full[0] else 0.0
        fy = copies * float(on_top[1]) if self.full[1] else 0.0
        return fx, fy, -copies * float(on_top[2])

    def probe_torque(self, fint: np.ndarray, u: np.ndarray, t: float
                     ) -> tuple[float, float, float]:
        """The probe's torque on the skin (Tx, Ty, Tz) [N m] about the probe's centre, from
        the reactions at the probe's nodes in their deformed positions, at load fraction t.

        The centre is the top face's centre, carried along by the probe's translation. A
        mirror copy about x = 0 flips Ty and Tz (a torque is a pseudo-vector) and one about
        y = 0 flips Tx and Tz: a component that a missing copy would cancel is 0.
        """
        p = self.params
        top = self._top
        centre = np.array([0.0, 0.0, p.height]) + t * np.array(
            [p.max_shear_x, p.max_shear_y, -p.max_indentation])
        arm = (self.mesh.p[:, top].T + u.reshape(-1, 3)[top]) - centre
        moment = np.cross(arm, fint.reshape(-1, 3)[top]).sum(axis=0)
        copies = (1 if self.full[0] else 2) * (1 if self.full[1] else 2)
        keep = (self.full[1], self.full[0], self.full[0] and self.full[1])
        return tuple(copies * float(m) if k else 0.0    # type: ignore[return-value]
                     for m, k in zip(moment, keep, strict=True))

    def _setup_pattern(self) -> None:
        """CSR pattern of the free-free stiffness and the scatter index of every element entry."""
        nfree = self._free.size
        remap = -np.ones(self.ndof, dtype=np.int64)
        remap[self._free] = np.arange(nfree)
        loc = remap[self._edofs]                                     # (e, 24)
        rows = np.repeat(loc, 24, axis=1).ravel()
        cols = np.tile(loc, (1, 24)).ravel()
        keep = (rows >= 0) & (cols >= 0)
        # int32 keys where they fit: np.unique sorts them ~1.6x faster than int64
        kind = np.int32 if nfree * nfree < 2**31 else np.int64
        key = rows[keep].astype(kind) * kind(nfree) + cols[keep].astype(kind)
        uniq, inverse = np.unique(key, return_inverse=True)
        self._scatter = np.full(rows.size, uniq.size, dtype=np.int64)
        self._scatter[keep] = inverse
        r = uniq // nfree
        c = uniq % nfree
        self._indptr = np.concatenate([[0], np.cumsum(np.bincount(r, minlength=nfree))])
        self._indices = c.astype(np.int32)
        self._nnz = uniq.size
        self._perm = _nested_dissection_order(self.mesh.p, self._free)
        # the factorised matrix is the tangent with rows and columns in that order; where
        # each of its entries sits in the tangent's data, found once, so that a factorisation
        # gathers it (the tangent is symmetric: its permuted CSR is the permuted CSC) instead
        # of permuting rows and columns and converting every time (13 ms of 0.2 s)
        where = sp.csr_matrix((np.arange(1, self._nnz + 1, dtype=np.int64), self._indices,
                               self._indptr), shape=(nfree, nfree))[self._perm][:, self._perm]
        where.sort_indices()
        self._perm_gather = where.data - 1
        self._perm_indices, self._perm_indptr = where.indices, where.indptr

    # -- residual and tangent ------------------------------------------------------------------
    def _internal_force(self, u: np.ndarray) -> np.ndarray:
        """Internal force vector over all dofs (the residual's costly part, evaluated often)."""
        self.stats["residuals"] += 1
        start = time.perf_counter()
        p = self.params
        F = self._gradient.deformation(u[self._edofs])                # (3, 3, e, q)
        J = _det(F)
        if np.any(J <= 0):
            raise ConvergenceError("An element inverted during the FEM solve; use more load "
                                   "steps ('steps') or a finer mesh.")
        w = self._w
        pres = p.bulk_modulus * ((w * J).sum(axis=1) / self._vol - 1.0)  # (e,)
        P, _ = _mooney_rivlin_piola(F, p.c10, p.c01, np.broadcast_to(pres[:, None], J.shape))
        fe = self._gradient.divergence(P)                             # (e, 8, 3)
        fint = np.bincount(self._edofs.ravel(), weights=fe.ravel(), minlength=self.ndof)
        self.stats["residual_s"] += time.perf_counter() - start
        return fint

    def _evaluate(self, u: np.ndarray, tangent: bool
                  ) -> tuple[np.ndarray, sp.csr_matrix | None]:
        """Internal force vector (all dofs) and, if asked, the free-free tangent matrix.

        The material tangent dP/dF (element pressure held) is the closed form of
        :func:`_mooney_rivlin_tangent` (tested against a complex-step derivative of the
        stress the residual uses); the mean-dilatation pressure adds a rank-one term per
        element.
        """
        fint = self._internal_force(u)
        if not tangent:
            return fint, None
        K = sp.csr_matrix((self._tangent_values(u), self._indices, self._indptr),
                          shape=(self._free.size, self._free.size))
        return fint, K

    def _tangent_values(self, u: np.ndarray, dtype: type = np.float64) -> np.ndarray:
        """The free-free tangent's entries in the order of its CSR pattern.

        ``dtype`` is the precision of the material tangent and element matrices: single
        for the preconditioner, which is factorised in single precision anyway (its
        rounding, ~1e-7 relative, is far below the factorisation's), at ~40 % less time.
        """
        start = time.perf_counter()
        p = self.params
        F = self._gradient.deformation(u[self._edofs])                # (3, 3, e, q)
        w = self._w
        J = _det(F)
        pres = p.bulk_modulus * ((w * J).sum(axis=1) / self._vol - 1.0)
        _, A = _mooney_rivlin_tangent(F.astype(dtype, copy=False), p.c10, p.c01,
                                      pres[:, None].astype(dtype, copy=False))
        ke = self._gradient.stiffness(A)
        # mean dilatation: d(theta V_e)/du = sum_q w J F^-T dN
        cof = _cofactor(F)
        g = self._gradient.divergence(cof).reshape(-1, 24)            # (e, 24)
        ke += (p.bulk_modulus / self._vol)[:, None, None] * g[:, :, None] * g[:, None, :]
        data = np.bincount(self._scatter, weights=ke.ravel(), minlength=self._nnz + 1)
        self.stats["tangent_s"] += time.perf_counter() - start
        return data[:-1]

    # -- solve -------------------------------------------------------------------------------
    def _prescribe(self, u: np.ndarray, t: float) -> None:
        """Set the constrained dofs at load fraction t of the path (probe at t * its end)."""
        p = self.params
        u3 = u.reshape(-1, 3)
        fixed = self._fixed.reshape(-1, 3)
        u3[fixed] = 0.0
        if p.boundary == "bonded":
            u3[self._top] = self.probe_motion(self.mesh.p[:, self._top], t)
        else:
            u3[self._top, 2] = -t * p.max_indentation

    def probe_motion(self, points: np.ndarray, t: float) -> np.ndarray:
        """Displacements (n, 3) of ``points`` (3, n) carried rigidly by the probe at load
        fraction t: turned by t x (max_tilt_x, max_tilt_y, max_twist_z) about the probe's
        centre (the top face's centre), then moved by t x (max_shear_x, max_shear_y,
        -max_indentation)."""
        p = self.params
        u = np.tile(t * np.array([p.max_shear_x, p.max_shear_y, -p.max_indentation]),
                    (points.shape[1], 1))
        if p.is_rotation:
            arm = points.T - np.array([0.0, 0.0, p.height])
            turn = rotation_matrix(t * np.array([p.max_tilt_x, p.max_tilt_y, p.max_twist_z]))
            u += arm @ (turn - np.eye(3)).T
        return u

    def sweep(self, progress: Progress | None = None) -> SweepResult:
        """Move the probe linearly from 0 to (max_indentation, max_shear_x, max_shear_y)
        in ``steps`` equal steps.

        A step whose solve fails (an element would invert, or Newton stalls) is retried as two
        halves from the last equilibrium, up to ``_MAX_CUTS`` times: on fine graded meshes the
        smallest elements at the clamped edges are the first to invert, and a shorter
        increment keeps them admissible without making every mesh pay for more steps.
        The result still holds exactly the ``steps`` requested.
        """
        p = self.params
        start = time.perf_counter()
        t_all = np.linspace(0.0, 1.0, p.steps + 1)
        forces = [(0.0, 0.0, 0.0)]
        torques = [(0.0, 0.0, 0.0)]
        bulges = [dict.fromkeys(self._patches, 0.0)]
        tangents = [dict.fromkeys(self._patches, 0.0)]
        history: list[tuple[float, np.ndarray]] = [(0.0, np.zeros(self.ndof))]
        lu = None
        for n in range(1, t_all.size):
            cuts_before = self.stats["cuts"]
            u, lu, fint = self._advance(history, lu, t_all[n], 0)
            forces.append(self.probe_force(fint))
            torques.append(self.probe_torque(fint, u, t_all[n]))
            bulges.append(self.bulges(u))
            tangents.append(self.tangents(u))
            if progress is not None:
                cut = self.stats["cuts"] - cuts_before
                note = f" ({cut} step cut{'s' if cut > 1 else ''})" if cut else ""
                shear = ""
                if p.is_shear:
                    shear = (f", shear ({t_all[n] * p.max_shear_x * 1e3:.2f}, "
                             f"{t_all[n] * p.max_shear_y * 1e3:.2f}) mm, lateral force "
                             f"({forces[-1][0]:.3f}, {forces[-1][1]:.3f}) N")
                progress(n / p.steps, f"load step {n}/{p.steps}: indentation "
                         f"{t_all[n] * p.max_indentation * 1e3:.2f} mm, force "
                         f"{forces[-1][2]:.3f} N{shear}{note}")
        f = np.array(forces)
        per_face = {face: np.array([b[face] for b in bulges]) for face in self._patches}
        along = {face: np.array([t[face] for t in tangents]) for face in self._patches}
        rotation = t_all[:, None] * np.array([p.max_tilt_x, p.max_tilt_y, p.max_twist_z])
        return SweepResult(t_all * p.max_indentation, f[:, 2], per_face[p.module_faces[0]],
                           self.nodes, time.perf_counter() - start,
                           t_all * p.max_shear_x, t_all * p.max_shear_y, f[:, 0], f[:, 1],
                           per_face, rotation, np.array(torques), along)

    def _advance(self, history: list[tuple[float, np.ndarray]], lu: object, d: float,
                 depth: int) -> tuple[np.ndarray, object, np.ndarray]:
        """Equilibrium at load fraction d from the last one in ``history`` (appended to it),
        the factorised tangent and the internal force there."""
        d0, u0 = history[-1]
        try:
            if len(history) == 1:
                u, lu = self._tangent_predictor(u0, d, self._perm)
            else:
                u = _extrapolate(history[-3:], d)
            self._prescribe(u, d)
            u, lu, fint = self._newton(u, lu, self._perm)
        except ConvergenceError:
            if depth >= _MAX_CUTS:
                raise
            self.stats["cuts"] += 1
            self._stale = True       # the tangent may have been factorised at a bad state
            _, lu, _ = self._advance(history, lu, 0.5 * (d0 + d), depth + 1)
            return self._advance(history, lu, d, depth + 1)
        history.append((d, u))
        del history[:-3]
        return u, lu, fint

    def _factorise(self, u: np.ndarray, perm: np.ndarray) -> object:
        self.stats["factorisations"] += 1
        self._stale = False
        values = self._tangent_values(u, _LU_DTYPE)
        if not np.all(np.isfinite(values)):
            raise ConvergenceError("The FEM state became invalid (an element inverted); use "
                                   "more load steps ('steps') or a finer mesh.")
        start = time.perf_counter()
        n = self._free.size
        if perm is self._perm:
            K = sp.csc_matrix((values[self._perm_gather].astype(_LU_DTYPE),
                               self._perm_indices, self._perm_indptr), shape=(n, n))
        else:
            K = sp.csr_matrix((values, self._indices, self._indptr), shape=(n, n))
            K = K[perm][:, perm].tocsc().astype(_LU_DTYPE)
        try:
            lu = (spla.splu(K, permc_spec="NATURAL", diag_pivot_thresh=_PIVOT_THRESHOLD,
                            options={"SymmetricMode": True}), perm)
        except RuntimeError:
            raise ConvergenceError("The FEM tangent is singular (the skin lost stability); "
                                   "use more load steps ('steps') or a smaller "
                                   "'max_indentation'.") from None
        self.stats["factorise_s"] += time.perf_counter() - start
        return lu

    def _lu_solve(self, lu: object, b: np.ndarray) -> np.ndarray:
        """x with K x = b for the factorised tangent (rows and columns permuted)."""
        start = time.perf_counter()
        solver, pm = lu  # type: ignore[misc]
        x = np.empty_like(b)
        x[pm] = solver.solve(b[pm].astype(_LU_DTYPE))
        self.stats["solves"] += 1
        self.stats["solve_s"] += time.perf_counter() - start
        return x

    def _tangent_predictor(self, u: np.ndarray, d: float, perm: np.ndarray
                           ) -> tuple[np.ndarray, object]:
        """Linearised step from equilibrium u to load fraction d (K_fc du_c by FD).

        Moving only the probe nodes puts a large volume error into the top elements, and
        Newton from there diverges for a nearly incompressible solid; the linear response to
        the boundary increment is a consistent starting point.
        """
        lu = self._factorise(u, perm)
        moved = u.copy()
        self._prescribe(moved, d)
        delta = moved - u
        eps = 1e-3
        r0 = self._evaluate(u, tangent=False)[0][self._free]
        r1 = self._evaluate(u + eps * delta, tangent=False)[0][self._free]
        rhs = r0 + (r1 - r0) / eps
        moved[self._free] += self._lu_solve(lu, -rhs)
        return moved, lu

    def _newton(self, u: np.ndarray, lu: object, perm: np.ndarray
                ) -> tuple[np.ndarray, object, np.ndarray]:
        """Inexact Newton: each correction by GMRES on the exact Jacobian, preconditioned by a
        factorised tangent that is reused across iterations and load steps.

        Factorising is most of a full Newton iteration, while a reused tangent alone
        converges only linearly (the pressure of a nearly incompressible solid changes the
        tangent quickly with the state). As a preconditioner it stays good for many steps, so
        the Krylov solve restores Newton's convergence for the price of a few residuals and
        triangular solves. The tangent is refactorised when GMRES fails, or at a load step's
        first correction once the last one needed more than ``_KRYLOV_REFRESH`` iterations;
        a later correction of the same step starts close to equilibrium and needs few
        iterations even on an aged preconditioner, so it never pays to refactorise for it.
        Each correction is solved to a fraction of the tolerance, so that a step usually
        converges in one correction.
        """
        free = self._free
        p = self.params
        tol_r = _RESIDUAL_TOL * p.shear_modulus * p.height**2    # [N], out-of-balance force
        fint = self._internal_force(u)
        r = fint[free]
        r_start = max(float(np.linalg.norm(r)), tol_r)
        for n in range(_NEWTON_MAX):
            r_norm = float(np.linalg.norm(r))
            if r_norm < tol_r:
                return u, lu, fint
            if r_norm > _NEWTON_DIVERGED * r_start:
                break                    # diverging: a shorter load step is cheaper (sweep)
            refresh = lu is None or (self._stale and n == 0)
            du = None
            if not refresh:
                target = max(_KRYLOV_TARGET * tol_r, _KRYLOV_RTOL * r_norm)
                du = self._krylov(u, r, lu, target)
            alpha = None if du is None else self._step_length(u, du)
            if alpha is None:            # stale tangent or a Krylov step that inverts: Newton
                lu = self._factorise(u, perm)
                du = self._lu_solve(lu, -r)
                alpha = self._step_length(u, du)
            if alpha is None:
                raise ConvergenceError("An element inverted during the FEM solve; use more "
                                       "load steps ('steps') or a finer mesh.")
            self.stats["iterations"] += 1
            u = u.copy()
            u[free] += alpha * du
            fint = self._internal_force(u)
            r = fint[free]
        raise ConvergenceError("The FEM Newton solve did not converge; use more load steps "
                               "('steps') or a smaller 'max_indentation'.")

    def _krylov(self, u: np.ndarray, r: np.ndarray, lu: object, target: float
                ) -> np.ndarray | None:
        """Newton correction J du ~ -r with |r + J du| <= target, or None if GMRES fails.

        Right-preconditioned GMRES without restart (at most ``_KRYLOV_MAX`` iterations):
        it minimises the true linear residual, so its estimate is the quantity Newton
        needs, and each iteration costs one residual and one triangular solve. (SciPy's
        gmres preconditions from the left: its stopping test on the preconditioned residual
        disagreed with the true one near convergence, and it costs two solves and a
        residual more per call.) J v comes from a forward difference of the residual: one
        residual costs about as much as a sparse product with an assembled tangent would,
        without assembling it.
        """
        free = self._free
        scale = 1e-7 * self.params.height
        beta = float(np.linalg.norm(r))
        m = _KRYLOV_MAX
        V = np.empty((m + 1, r.size))
        Z = np.empty((m, r.size))
        H = np.zeros((m + 1, m))
        V[0] = -r / beta
        count = 0
        y = np.zeros(0)
        converged = False
        for j in range(m):
            Z[j] = self._lu_solve(lu, V[j])
            h = scale / np.abs(Z[j]).max()
            trial = u.copy()
            trial[free] += h * Z[j]
            w = (self._internal_force(trial)[free] - r) / h
            for i in range(j + 1):                        # modified Gram-Schmidt, twice
                H[i, j] = V[i] @ w
                w -= H[i, j] * V[i]
            for i in range(j + 1):
                c = V[i] @ w
                H[i, j] += c
                w -= c * V[i]
            H[j + 1, j] = float(np.linalg.norm(w))
            count = j + 1
            e1 = np.zeros(j + 2)
            e1[0] = beta
            y, *_ = np.linalg.lstsq(H[:j + 2, :j + 1], e1, rcond=None)
            res = float(np.linalg.norm(e1 - H[:j + 2, :j + 1] @ y))
            if res <= target:
                converged = True
                break
            if H[j + 1, j] <= 1e-14 * beta:
                break                                     # breakdown short of the target
            V[j + 1] = w / H[j + 1, j]
        self.stats["krylov"] += count
        # refactorise at the next step's first correction once the preconditioner has aged
        self._stale = count > _KRYLOV_REFRESH
        return y @ Z[:count] if converged else None

    def _step_length(self, u: np.ndarray, du: np.ndarray) -> float | None:
        """The largest of 1, 1/2, 1/4, ... that keeps every element uninverted, or None."""
        alpha = 1.0
        while not self._admissible(u, du * alpha):
            alpha *= 0.5
            if alpha < 1e-3:
                return None
        return alpha

    def _admissible(self, u: np.ndarray, du_free: np.ndarray) -> bool:
        """True when u + du keeps every quadrature point's det F > 0.05 (no inverted element)."""
        trial = u.copy()
        trial[self._free] += du_free
        return bool(np.all(_det(self._gradient.deformation(trial[self._edofs])) > 0.05))


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


def spans_needed(params: PhysicsParams) -> tuple[bool, bool]:
    """Whether the model must span x and y: the load path or the windows break the mirror
    symmetry about x = 0 (shear along x, tilt about y, twist) or y = 0 (likewise)."""
    p = params
    return (p.max_shear_x != 0 or p.max_tilt_y != 0 or p.max_twist_z != 0
            or not p.mirror_symmetric(0),
            p.max_shear_y != 0 or p.max_tilt_x != 0 or p.max_twist_z != 0
            or not p.mirror_symmetric(1))


def rotation_matrix(vector: np.ndarray) -> np.ndarray:
    """The rotation by ``vector`` (axis times angle [rad], right-hand rule), Rodrigues'
    formula: one rotation for a combined tilt and twist, independent of an order of axes."""
    angle = float(np.linalg.norm(vector))
    if angle == 0.0:
        return np.eye(3)
    kx, ky, kz = np.asarray(vector, float) / angle
    k = np.array([[0.0, -kz, ky], [kz, 0.0, -kx], [-ky, kx, 0.0]])
    return np.eye(3) + math.sin(angle) * k + (1.0 - math.cos(angle)) * (k @ k)


def richardson(fine: np.ndarray, coarse: np.ndarray, ratio: float, order: float
               ) -> np.ndarray:
    """f + (f - f_coarse) / (r^p - 1): the leading C h^p error of both cancels (p = 0: f)."""
    if order == 0:
        return fine
    return fine + (fine - coarse) / (ratio**order - 1.0)


def _extrapolate(history: list[tuple[float, np.ndarray]], d: float) -> np.ndarray:
    """Newton's starting point: the polynomial through the last equilibria, at indentation d.

    A quadratic predictor starts Newton about an order of magnitude closer than a linear
    one on this smooth load path, which saves Newton iterations and hence factorisations.
    """
    u = np.zeros_like(history[-1][1])
    for j, (dj, uj) in enumerate(history):
        weight = 1.0
        for m, (dm, _) in enumerate(history):
            if m != j:
                weight *= (d - dm) / (dj - dm)
        u += weight * uj
    return u


def _det(F: np.ndarray) -> np.ndarray:
    """det F of component-first (3, 3, ...) arrays."""
    return (F[0, 0] * (F[1, 1] * F[2, 2] - F[1, 2] * F[2, 1])
            - F[0, 1] * (F[1, 0] * F[2, 2] - F[1, 2] * F[2, 0])
            + F[0, 2] * (F[1, 0] * F[2, 1] - F[1, 1] * F[2, 0]))


class _GradientOperator:
    """u_e -> F at the quadrature points, and stress -> element forces, as two GEMMs.

    On the structured mesh every element is an axis-aligned box, so dN_a/dX_K at a quadrature
    point is the reference gradient scaled by 1/h_K: the gather over the 8 nodes becomes one
    (3 e x 8) @ (8 x 3 q) product instead of e*q tiny batched products. Any other mesh takes
    the general path.
    """

    def __init__(self, dndx: np.ndarray, w: np.ndarray, xe: np.ndarray) -> None:
        # xe: (3, 8, e) node coordinates per element
        self._dndx, self._w = dndx, w
        ne, nq = w.shape
        h = np.ptp(xe, axis=1).T                                      # (e, 3)
        ref = dndx[0] * h[0]                                          # (q, a, K)
        self._box = bool(np.allclose(dndx, ref[None] / h[:, None, None, :],
                                     rtol=1e-10, atol=0.0))
        # per-component GEMMs that read and write F's (e, q) slabs in place: the transposes
        # of one big GEMM cost more than the products (0.67 -> 0.39 ms and 0.56 -> 0.18 ms
        # per residual on the default mesh)
        self._ref_kq = np.ascontiguousarray(ref.transpose(1, 2, 0).reshape(8, 3 * nq))
        self._ref_qa = [np.ascontiguousarray(ref[:, :, k]) for k in range(3)]  # (q, a)
        hinv = 1.0 / h
        self._w_hinv = np.ascontiguousarray(w[None] * hinv.T[:, :, None])     # (K, e, q)
        # w / (h_K h_L) as (e, 1, 1, q, K, L), the stiffness's layout
        self._w_hh = (w[:, :, None, None] * hinv[:, None, :, None]
                      * hinv[:, None, None, :])[:, None, None]
        # pairs[(q, K, L), (a, b)] = ref[q, a, K] ref[q, b, L]
        self._pairs = np.einsum("qaK,qbL->qKLab", ref, ref).reshape(nq * 9, 64)
        self._hinv = hinv
        self._shape = (ne, nq)

    def deformation(self, ue: np.ndarray) -> np.ndarray:
        """F[i, K, e, q] from element dofs ue (e, 24) ordered (a, i)."""
        ne, nq = self._shape
        ue = ue.reshape(ne, 8, 3)
        if self._box:
            F = np.empty((3, 3, ne, nq), dtype=np.result_type(ue, self._ref_kq))
            for i in range(3):
                g = (ue[:, :, i] @ self._ref_kq).reshape(ne, 3, nq)      # (e, K, q)
                for k in range(3):
                    np.multiply(g[:, k], self._hinv[:, k, None], out=F[i, k])
        else:
            F = np.einsum("eai,eqaK->iKeq", ue, self._dndx, optimize=True)
        F[0, 0] += 1.0
        F[1, 1] += 1.0
        F[2, 2] += 1.0
        return F

    def divergence(self, P: np.ndarray) -> np.ndarray:
        """Element nodal forces fe[e, a, i] = sum_q w dN_a/dX_K P_iK."""
        ne = self._shape[0]
        if self._box:
            fe = np.empty((ne, 8, 3), dtype=np.result_type(P, self._w_hinv))
            for i in range(3):
                S = P[i] * self._w_hinv                                   # (K, e, q)
                acc = S[0] @ self._ref_qa[0]
                acc += S[1] @ self._ref_qa[1]
                acc += S[2] @ self._ref_qa[2]
                fe[:, :, i] = acc
            return fe
        return np.einsum("iKeq,eqaK->eai", P * self._w, self._dndx, optimize=True)

    def stiffness(self, A: np.ndarray) -> np.ndarray:
        """Element matrices ke[e, (a i), (b k)] = sum_q w dN_a/dX_K A_iKkL dN_b/dX_L.

        A has shape (i, K, k, L, e, q). On box elements the sum over q, K, L is one GEMM
        with a constant (72 x 64) matrix of reference-gradient products per (i, k) pair.
        """
        ne, nq = self._shape
        if not self._box:
            ke = np.einsum("eqaK,iKkLeq,eqbL->eaibk", self._dndx, A * self._w, self._dndx,
                           optimize=True)
            return ke.reshape(ne, 24, 24)
        # weights and scalings in one pass that also lays A out for the GEMM
        X = np.empty((ne, 3, 3, nq, 3, 3), dtype=A.dtype)
        w_hh, pairs = (self._w_hh, self._pairs) if A.dtype == np.float64 else \
            (self._w_hh.astype(A.dtype), self._pairs.astype(A.dtype))
        np.multiply(A.transpose(4, 0, 2, 5, 1, 3), w_hh, out=X)      # (e, i, k, q, K, L)
        ke = (X.reshape(ne * 9, nq * 9) @ pairs).reshape(ne, 3, 3, 8, 8)  # (e, i, k, a, b)
        return ke.transpose(0, 3, 1, 4, 2).reshape(ne, 24, 24)


def _nested_dissection_order(points: np.ndarray, free: np.ndarray) -> np.ndarray:
    """Geometric nested-dissection permutation of the free dofs (a good fill-reducing order).

    Recursively bisect the node cloud at its middle plane of nodes across the axis with the
    most planes (the smallest separator on a structured mesh; the longest extent of a graded
    mesh is not always it), down to groups of 24 dofs; separator nodes go last. On the default
    mesh this fills the factors with 8 % fewer entries than bisecting the longest extent down
    to 96 dofs (4.25 against 4.61 million), and factorises ~15 % faster.
    """
    nodes_of = free // 3
    X = points[:, nodes_of]
    order: list[np.ndarray] = []

    def recurse(idx: np.ndarray) -> None:
        if idx.size <= 24:
            order.append(idx)
            return
        pts = X[:, idx]
        planes = [np.unique(pts[k]) for k in range(3)]
        axis = int(np.argmax([q.size for q in planes]))
        coords = pts[axis]
        uniq = planes[axis]
        if uniq.size < 3:
            order.append(idx)
            return
        mid = uniq[uniq.size // 2]
        left = idx[coords < mid]
        right = idx[coords > mid]
        sep = idx[coords == mid]
        recurse(left)
        recurse(right)
        order.append(sep)

    recurse(np.arange(free.size))
    return np.concatenate(order)
