"""Total-Lagrangian finite-element model of the skin block pressed by a flat probe.

Nearly incompressible Mooney–Rivlin solid on trilinear hexahedra with the mean-dilatation
(Q1–P0) treatment of the volume term, which avoids volumetric locking: the pressure is one
constant per element, condensed element by element, so the global system holds displacements
only. scikit-fem supplies the mesh, the shape-function gradients and the quadrature; the
hyperelastic residual and tangent are assembled here with vectorised numpy (scikit-fem's
generic form assembly is an order of magnitude slower for this) into a CSR matrix whose
pattern and scatter indices are computed once. Newton reuses the factorisation while it
converges fast (modified Newton) and refactorises when it slows.

Half model: the block is symmetric about x = 0 (the photoreflector window is centred there).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
import skfem

from .errors import ConvergenceError
from .params import PhysicsParams

Progress = Callable[[float, str], None]


@dataclass(frozen=True)
class SweepResult:
    """Per load step: indentation [m], probe reaction force [N], window-averaged bulge [m]."""

    indentation_m: np.ndarray
    force_n: np.ndarray
    bulge_m: np.ndarray
    nodes: int
    seconds: float


# --------------------------------------------------------------------------------------------
# mesh


def _axis(breaks: list[float], n: int, grading: float = 1.0) -> np.ndarray:
    """Node coordinates over sorted breakpoints with about n elements in total.

    Every breakpoint is a node (window edges and symmetry planes stay on element faces).
    With grading > 1 the segment-wise uniform spacing is remapped so the first and last
    elements are about ``grading`` times smaller than the middle ones.
    """
    breaks = sorted(set(breaks))
    lo, hi = breaks[0], breaks[-1]
    if grading > 1.0:
        # map s in [0,1] -> g(s) finer near both ends; breakpoints mapped through g^-1.
        a = (grading - 1.0) / (grading + 1.0)

        def g(s: np.ndarray) -> np.ndarray:
            return s - a * np.sin(2 * np.pi * s) / (2 * np.pi)

        fine = np.linspace(0.0, 1.0, 20001)
        ginv = lambda y: np.interp(y, g(fine), fine)  # noqa: E731
        sbreaks = [float(ginv((b - lo) / (hi - lo))) for b in breaks]
    else:
        sbreaks = [(b - lo) / (hi - lo) for b in breaks]
    pts: list[np.ndarray] = []
    for s0, s1 in zip(sbreaks[:-1], sbreaks[1:], strict=True):
        k = max(1, round(n * (s1 - s0)))
        pts.append(np.linspace(s0, s1, k + 1)[:-1])
    s = np.concatenate([*pts, [1.0]])
    if grading > 1.0:
        s = g(s)
    x = lo + (hi - lo) * s
    for b in breaks:  # snap exactly
        x[np.argmin(abs(x - b))] = b
    return x


def build_mesh(params: PhysicsParams) -> skfem.MeshHex:
    """Structured, graded hexahedral half mesh x in [0, W/2], y in [-D/2, D/2], z in [0, H]."""
    p = params
    hw, hd = p.width / 2, p.depth / 2
    module = p.boundary == "bonded" and p.module_height > 0
    xb = [0.0, hw]
    zb = [0.0, p.height]
    if module:
        xb.append(p.window_width / 2)
        zb += [p.window_center_z - p.window_height / 2, p.window_center_z + p.window_height / 2,
               p.module_height]
    ny = p.mesh_ny + p.mesh_ny % 2
    x = _axis(xb, p.mesh_nx)
    y = _axis([-hd, 0.0, hd], ny)
    z = _axis(zb, p.mesh_nz, p.mesh_grading if p.boundary == "bonded" else 1.0)
    return skfem.MeshHex.init_tensor(x, y, z)


# --------------------------------------------------------------------------------------------
# constitutive law


def _mooney_rivlin(F: np.ndarray, c10: float, c01: float
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Isochoric Mooney–Rivlin: returns (P_iso, A_iso = dP/dF, J, F^-1) per point.

    W = C10 (I1bar - 3) + C01 (I2bar - 3), I1bar = I3^(-1/3) I1, I2bar = I3^(-2/3) I2.
    """
    C = np.swapaxes(F, -1, -2) @ F
    J = np.linalg.det(F)
    Finv = np.linalg.inv(F)
    Cinv = Finv @ np.swapaxes(Finv, -1, -2)
    I1 = np.trace(C, axis1=-2, axis2=-1)
    C2 = C @ C
    I2 = 0.5 * (I1**2 - np.trace(C2, axis1=-2, axis2=-1))
    I3 = J**2
    eye = np.eye(3)
    a = I3 ** (-1.0 / 3.0)
    b = I3 ** (-2.0 / 3.0)
    x1, x2 = I1[..., None, None], I2[..., None, None]
    aa, bb = a[..., None, None], b[..., None, None]
    dI1b = aa * eye - aa * x1 / 3.0 * Cinv
    dI2b = bb * (x1 * eye - C) - 2.0 / 3.0 * bb * x2 * Cinv
    S = 2.0 * (c10 * dI1b + c01 * dI2b)

    def outer(u: np.ndarray, v: np.ndarray) -> np.ndarray:
        return u[..., :, :, None, None] * v[..., None, None, :, :]

    # symmetric 4th-order identity pieces: Isym_ABCD = 1/2 (d_AC d_BD + d_AD d_BC)
    Isym = 0.5 * (np.einsum("ac,bd->abcd", eye, eye) + np.einsum("ad,bc->abcd", eye, eye))
    ICinv = 0.5 * (Cinv[..., :, None, :, None] * Cinv[..., None, :, None, :]
                   + Cinv[..., :, None, None, :] * Cinv[..., None, :, :, None])
    a4 = a[..., None, None, None, None]
    b4 = b[..., None, None, None, None]
    i1, i2 = I1[..., None, None, None, None], I2[..., None, None, None, None]
    E = np.broadcast_to(eye, C.shape)
    d2I1b = (-a4 / 3.0 * (outer(E, Cinv) + outer(Cinv, E)) + a4 * i1 / 9.0 * outer(Cinv, Cinv)
             + a4 * i1 / 3.0 * ICinv)
    M = x1 * eye - C
    d2I2b = (b4 * (outer(E, E) - Isym) - 2.0 / 3.0 * b4 * (outer(M, Cinv) + outer(Cinv, M))
             + 4.0 / 9.0 * b4 * i2 * outer(Cinv, Cinv) + 2.0 / 3.0 * b4 * i2 * ICinv)
    Cmat = 4.0 * (c10 * d2I1b + c01 * d2I2b)  # (..., I, K, J, L) = 4 d2W/dC_IK dC_JL
    P = F @ S
    # A_iKkL = d_ik S_KL + F_iI F_kJ Cmat_IKJL
    shp = F.shape[:-2]
    t = F @ Cmat.reshape(*shp, 3, 27)                    # (.., i, [K J L])
    t = t.reshape(*shp, 3, 3, 3, 3)                       # i K J L
    t = np.swapaxes(t, -1, -2) @ np.swapaxes(F, -1, -2)[..., None, None, :, :]  # i K L k
    A = np.swapaxes(t, -1, -2) + eye[:, None, :, None] * S[..., None, :, None, :]
    return P, A, J, Finv


# --------------------------------------------------------------------------------------------
# model


class SkinModel:
    """The discretised skin block with its boundary conditions, ready to sweep the load."""

    def __init__(self, params: PhysicsParams) -> None:
        self.params = params
        self.mesh = build_mesh(params)
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
        self._setup_constraints()
        self._setup_pattern()

    # -- boundary conditions -------------------------------------------------------------------
    def _setup_constraints(self) -> None:
        p = self.params
        X = self.mesh.p
        tol = 1e-9 * max(p.width, p.height)
        x, y, z = X
        hw, hd = p.width / 2, p.depth / 2
        fixed = np.zeros((self.nodes, 3), dtype=bool)
        bottom = z < tol
        top = z > p.height - tol
        fixed[x < tol, 0] = True                              # symmetry plane x = 0
        if p.boundary == "bonded":
            fixed[bottom, :] = True
            fixed[top, :] = True
            if p.module_height > 0:
                band = z <= p.module_height + tol
                fixed[band & (x > hw - tol), 0] = True
                fixed[band & (y < -hd + tol), 1] = True
                front = band & (y > hd - tol)
                zc, wh, ww = p.window_center_z, p.window_height / 2, p.window_width / 2
                window = front & (x < ww - tol) & (abs(z - zc) < wh - tol)
                fixed[front & ~window, 1] = True
        else:
            fixed[bottom, 2] = True
            fixed[top, 2] = True
            fixed[abs(y) < tol, 1] = True                     # symmetry plane y = 0
        self._top = top
        self._fixed = fixed.ravel()
        self._free = np.flatnonzero(~self._fixed)
        # window patch: area-weighted average of u_y over front-face quads inside the window.
        zc, wh, ww = p.window_center_z, p.window_height / 2, p.window_width / 2
        weights = np.zeros(self.nodes)
        facets = self.mesh.facets
        on_front = np.all(y[facets] > hd - tol, axis=0)
        cx = x[facets].mean(axis=0)
        cz = z[facets].mean(axis=0)
        inside = on_front & (cx < ww) & (abs(cz - zc) < wh)
        for f in np.flatnonzero(inside):
            nodes = facets[:, f]
            area = np.ptp(x[nodes]) * np.ptp(z[nodes])
            np.add.at(weights, nodes, area / 4)
        if weights.sum() == 0:  # window finer than the mesh: nearest front node
            cand = np.flatnonzero(y > hd - tol)
            weights[cand[np.argmin(x[cand] ** 2 + (z[cand] - zc) ** 2)]] = 1.0
        self._patch = weights / weights.sum()

    def _setup_pattern(self) -> None:
        """CSR pattern of the free-free stiffness and the scatter index of every element entry."""
        nfree = self._free.size
        remap = -np.ones(self.ndof, dtype=np.int64)
        remap[self._free] = np.arange(nfree)
        loc = remap[self._edofs]                                     # (e, 24)
        rows = np.repeat(loc, 24, axis=1).ravel()
        cols = np.tile(loc, (1, 24)).ravel()
        keep = (rows >= 0) & (cols >= 0)
        key = rows[keep] * nfree + cols[keep]
        uniq, inverse = np.unique(key, return_inverse=True)
        self._scatter = np.full(rows.size, uniq.size, dtype=np.int64)
        self._scatter[keep] = inverse
        r = uniq // nfree
        c = uniq % nfree
        self._indptr = np.concatenate([[0], np.cumsum(np.bincount(r, minlength=nfree))])
        self._indices = c.astype(np.int32)
        self._nnz = uniq.size
        self._perm = _nested_dissection_order(self.mesh.p, self._free)

    # -- residual and tangent ------------------------------------------------------------------
    def _evaluate(self, u: np.ndarray, tangent: bool
                  ) -> tuple[np.ndarray, sp.csr_matrix | None]:
        p = self.params
        ue = u[self._edofs].reshape(-1, 8, 3)                         # (e, a, i)
        dndx = self._dndx                                             # (e, q, a, K)
        F = np.swapaxes(ue, 1, 2)[:, None] @ dndx + np.eye(3)         # (e, q, i, K)
        P, A, J, Finv = _mooney_rivlin(F, p.c10, p.c01)
        w = self._w
        JFinvT = J[..., None, None] * np.swapaxes(Finv, -1, -2)       # (e, q, i, K)
        theta = (w * J).sum(axis=1) / self._vol
        kappa = p.bulk_modulus
        pres = kappa * (theta - 1.0)                                  # (e,)
        # g_e[a, i] = sum_q w J F^-1_Ki dN_a/dX_K
        g = np.einsum("eq,eqaK,eqiK->eai", w, dndx, JFinvT, optimize=True).reshape(-1, 24)
        Ptot = P + pres[:, None, None, None] * JFinvT
        fe = (w[..., None, None] * (dndx @ np.swapaxes(Ptot, -1, -2))).sum(axis=1)
        fint = np.bincount(self._edofs.ravel(), weights=fe.ravel(), minlength=self.ndof)
        if not tangent:
            return fint, None
        # volumetric geometric part: p J (F^-1_Ki F^-1_Lk - F^-1_Kk F^-1_Li)
        Av = _vol_geometric(Finv, pres[:, None] * J)
        A = A + Av                                                    # (e, q, i, K, k, L)
        ne, nq = w.shape
        At = np.moveaxis(A, 3, 2).reshape(ne, nq, 3, 27)              # (K, [i k L])
        t1 = dndx @ At                                                # (e, q, a, [i k L])
        t1 = t1.reshape(ne, nq, 72, 3) @ np.swapaxes(dndx, -1, -2)    # (e, q, [a i k], b)
        ke = (w[..., None, None] * t1).sum(axis=1).reshape(ne, 8, 3, 3, 8)
        ke = ke.transpose(0, 1, 2, 4, 3).reshape(ne, 24, 24)
        ke += (kappa / self._vol)[:, None, None] * g[:, :, None] * g[:, None, :]
        data = np.bincount(self._scatter, weights=ke.ravel(), minlength=self._nnz + 1)
        K = sp.csr_matrix((data[:-1], self._indices, self._indptr),
                          shape=(self._free.size, self._free.size))
        return fint, K

    # -- solve -------------------------------------------------------------------------------
    def _prescribe(self, u: np.ndarray, d: float) -> None:
        u3 = u.reshape(-1, 3)
        fixed = self._fixed.reshape(-1, 3)
        u3[fixed] = 0.0
        u3[self._top, 2] = -d

    def sweep(self, progress: Progress | None = None) -> SweepResult:
        """Press the top face from 0 to max_indentation in ``steps`` equal steps."""
        p = self.params
        start = time.perf_counter()
        d_all = np.linspace(0.0, p.max_indentation, p.steps + 1)
        forces, bulges = [0.0], [0.0]
        u = np.zeros(self.ndof)
        u_prev = u.copy()
        lu = None
        Kp = self._perm
        for n in range(1, d_all.size):
            d = d_all[n]
            if n == 1:
                u, lu = self._tangent_predictor(u, d, Kp)
            else:
                ratio = (d - d_all[n - 1]) / (d_all[n - 1] - d_all[n - 2])
                guess = u + ratio * (u - u_prev)
                u_prev = u
                u = guess
            self._prescribe(u, d)
            u, lu = self._newton(u, lu, Kp)
            fint, _ = self._evaluate(u, tangent=False)
            forces.append(-2.0 * fint.reshape(-1, 3)[self._top, 2].sum())
            bulges.append(float(self._patch @ u.reshape(-1, 3)[:, 1]))
            if progress is not None:
                progress(n / p.steps, f"load step {n}/{p.steps}: indentation "
                         f"{d * 1e3:.2f} mm, force {forces[-1]:.3f} N")
        return SweepResult(d_all, np.array(forces), np.array(bulges), self.nodes,
                           time.perf_counter() - start)

    def _factorise(self, u: np.ndarray, perm: np.ndarray) -> object:
        _, K = self._evaluate(u, tangent=True)
        assert K is not None
        return (spla.splu(K[perm][:, perm].tocsc(), permc_spec="NATURAL",
                          options={"SymmetricMode": True}), perm)

    def _tangent_predictor(self, u: np.ndarray, d: float, perm: np.ndarray
                           ) -> tuple[np.ndarray, object]:
        """Linearised step from equilibrium u to the new probe position (K_fc du_c by FD).

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
        solver, pm = lu  # type: ignore[misc]
        du = np.empty_like(rhs)
        du[pm] = solver.solve(-rhs[pm])
        moved[self._free] += du
        return moved, lu

    def _newton(self, u: np.ndarray, lu: object, perm: np.ndarray
                ) -> tuple[np.ndarray, object]:
        """Modified Newton: keep the factorisation while the residual falls fast enough."""
        free = self._free
        tol_u = 1e-9 * self.params.height
        last_norm = np.inf
        fresh = False
        for _ in range(80):
            fint, _ = self._evaluate(u, tangent=False)
            r = fint[free]
            norm = np.linalg.norm(r)
            if lu is None or (not fresh and norm > 0.2 * last_norm):
                lu = self._factorise(u, perm)
                fresh = True
            else:
                fresh = False
            solver, pm = lu  # type: ignore[misc]
            du = np.empty_like(r)
            du[pm] = solver.solve(-r[pm])
            alpha = 1.0
            while not self._admissible(u, du * alpha):
                alpha *= 0.5
                if alpha < 1e-3:
                    raise ConvergenceError("An element inverted during the FEM solve; use "
                                           "more load steps or a finer mesh.")
            u[free] += alpha * du
            last_norm = norm
            if alpha == 1.0 and np.abs(du).max() < tol_u:
                return u, lu
        raise ConvergenceError("The FEM Newton solve did not converge; use more load steps "
                               "('steps') or a smaller 'max_indentation'.")

    def _admissible(self, u: np.ndarray, du_free: np.ndarray) -> bool:
        """True when u + du keeps every quadrature point's det F > 0 (no inverted element)."""
        trial = u.copy()
        trial[self._free] += du_free
        ue = trial[self._edofs].reshape(-1, 8, 3)
        F = np.swapaxes(ue, 1, 2)[:, None] @ self._dndx + np.eye(3)
        return bool(np.all(np.linalg.det(F) > 0.05))


def _vol_geometric(Finv: np.ndarray, pj: np.ndarray) -> np.ndarray:
    """p J (F^-1_Ki F^-1_Lk - F^-1_Kk F^-1_Li) as A[..., i, K, k, L]."""
    G = np.swapaxes(Finv, -1, -2)                 # G_iK = F^-1_Ki
    t1 = G[..., :, :, None, None] * G[..., None, None, :, :]          # G_iK G_kL
    t2 = G[..., :, None, None, :] * Finv[..., None, :, :, None]       # G_iL G_kK
    # t1: i K k L -> F^-1_Ki F^-1_Lk ; need F^-1_Ki F^-1_Lk - F^-1_Kk F^-1_Li
    # F^-1_Kk F^-1_Li = G_kK G_iL = t2[i, K, k, L]
    return pj[..., None, None, None, None] * (t1 - t2)


def _nested_dissection_order(points: np.ndarray, free: np.ndarray) -> np.ndarray:
    """Geometric nested-dissection permutation of the free dofs (a good fill-reducing order).

    Recursively bisect the node cloud along its longest extent; separator nodes go last.
    """
    nodes_of = free // 3
    X = points[:, nodes_of]
    order: list[np.ndarray] = []

    def recurse(idx: np.ndarray) -> None:
        if idx.size <= 96:
            order.append(idx)
            return
        pts = X[:, idx]
        ext = np.ptp(pts, axis=1)
        axis = int(np.argmax(ext))
        coords = pts[axis]
        uniq = np.unique(coords)
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
