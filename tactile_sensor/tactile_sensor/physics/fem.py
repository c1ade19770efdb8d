"""Total-Lagrangian finite-element model of the skin block pressed by a flat probe.

Nearly incompressible Mooney–Rivlin solid on trilinear hexahedra with the mean-dilatation
(Q1–P0) treatment of the volume term, which avoids volumetric locking: the pressure is one
constant per element, condensed element by element, so the global system holds displacements
only. scikit-fem supplies the mesh, the shape-function gradients and the quadrature; the
hyperelastic residual and tangent are assembled here with vectorised numpy (scikit-fem's
generic form assembly is an order of magnitude slower for this) into a CSR matrix whose
pattern and scatter indices are computed once. Newton reuses the factorisation while it
converges fast (modified Newton) and refactorises when it slows.

Quarter model: the block is symmetric about x = 0 and y = 0. The window is centred on x = 0;
symmetry about y = 0 holds exactly because the module is taken as front/back symmetric (its
back wall has the same window — see ``PhysicsParams.window_width``).
"""

from __future__ import annotations

import itertools
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
import skfem

from .errors import ConvergenceError, PhysicsError
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
    for s0, s1 in itertools.pairwise(sbreaks):
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
    """Structured, graded hexahedral quarter mesh x in [0, W/2], y in [0, D/2], z in [0, H]."""
    p = params
    hw, hd = p.width / 2, p.depth / 2
    module = p.boundary == "bonded" and p.module_height > 0
    xb = [0.0, hw]
    zb = [0.0, p.height]
    if module:
        xb.append(p.window_width / 2)
        zb += [p.window_center_z - p.window_height / 2, p.window_center_z + p.window_height / 2,
               p.module_height]
    x = _axis(xb, p.mesh_nx)
    y = _axis([0.0, hd], p.mesh_ny)
    z = _axis(zb, p.mesh_nz, p.mesh_grading if p.boundary == "bonded" else 1.0)
    return skfem.MeshHex.init_tensor(x, y, z)


# --------------------------------------------------------------------------------------------
# constitutive law


def _kinematics(F: np.ndarray) -> dict[str, np.ndarray]:
    """Invariants and the tensors the Mooney–Rivlin stress and tangent are built from."""
    J = np.linalg.det(F)
    G = np.swapaxes(np.linalg.inv(F), -1, -2)              # F^-T
    C = np.swapaxes(F, -1, -2) @ F
    I1 = np.trace(C, axis1=-2, axis2=-1)
    I2 = 0.5 * (I1**2 - np.einsum("...ij,...ij->...", C, C))
    H = I1[..., None, None] * F - F @ C                    # dI2/dF / 2
    return {"J": J, "G": G, "C": C, "I1": I1, "I2": I2, "H": H}


def _piola(F: np.ndarray, k: dict[str, np.ndarray], c10: float, c01: float,
           pres: np.ndarray) -> np.ndarray:
    """First Piola stress of the isochoric Mooney–Rivlin part plus the element pressure.

    W = C10 (J^-2/3 I1 - 3) + C01 (J^-4/3 I2 - 3) + volume term (mean dilatation).
    """
    J, G, I1, I2, H = k["J"], k["G"], k["I1"], k["I2"], k["H"]
    al = (c10 * J ** (-2.0 / 3.0))[..., None, None]
    be = (c01 * J ** (-4.0 / 3.0))[..., None, None]
    return (al * (2.0 * F - (2.0 / 3.0) * I1[..., None, None] * G)
            + be * (2.0 * H - (4.0 / 3.0) * I2[..., None, None] * G)
            + (pres * J)[..., None, None] * G)


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
        self.stats = {"factorisations": 0, "iterations": 0}

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
        fixed[y < tol, 1] = True                              # symmetry plane y = 0
        if p.boundary == "bonded":
            fixed[bottom, :] = True
            fixed[top, :] = True
            if p.module_height > 0:
                band = z <= p.module_height + tol
                fixed[band & (x > hw - tol), :] = True
                front = band & (y > hd - tol)
                zc, wh, ww = p.window_center_z, p.window_height / 2, p.window_width / 2
                window = front & (x < ww - tol) & (abs(z - zc) < wh - tol)
                fixed[front & ~window, :] = True
                if not window.any():
                    raise PhysicsError("The mesh has no node inside the photoreflector "
                                       "window; raise mesh_nx and mesh_nz or enlarge the "
                                       "window.")
        else:
            fixed[bottom, 2] = True
            fixed[top, 2] = True
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
        """Internal force vector (all dofs) and, if asked, the free-free tangent matrix.

        The tangent dP/dF of this law is a sum of outer products of F, F^-T and
        H = I1 F - F C plus a few index-swapped terms, so the element matrices are built from
        batched matrix products of (8 x 3) shape-gradient images without ever forming the
        9 x 9 material tangent.
        """
        p = self.params
        ue = u[self._edofs].reshape(-1, 8, 3)                         # (e, a, i)
        dn = self._dndx                                               # (e, q, a, K)
        F = np.swapaxes(ue, 1, 2)[:, None] @ dn + np.eye(3)           # (e, q, i, K)
        if np.any(np.linalg.det(F) <= 0):
            raise ConvergenceError("An element inverted during the FEM solve; use more load "
                                   "steps ('steps') or a finer mesh.")
        k = _kinematics(F)
        w = self._w
        J, G = k["J"], k["G"]
        theta = (w * J).sum(axis=1) / self._vol
        kappa = p.bulk_modulus
        pres = kappa * (theta - 1.0)                                  # (e,)
        pq = np.broadcast_to(pres[:, None], J.shape)
        P = _piola(F, k, p.c10, p.c01, pq)
        fe = (w[..., None, None] * (dn @ np.swapaxes(P, -1, -2))).sum(axis=1)
        fint = np.bincount(self._edofs.ravel(), weights=fe.ravel(), minlength=self.ndof)
        if not tangent:
            return fint, None
        ne, nq = w.shape
        I1, I2 = k["I1"], k["I2"]
        al = p.c10 * J ** (-2.0 / 3.0)
        be = p.c01 * J ** (-4.0 / 3.0)
        pj = pq * J
        # images of the shape gradients: v_a = F^-T dN_a, f_a = F dN_a, h_a = H dN_a
        V = dn @ np.swapaxes(G, -1, -2)                               # (e, q, a, i)
        Fm = dn @ np.swapaxes(F, -1, -2)
        Hm = dn @ np.swapaxes(k["H"], -1, -2)
        # outer-product terms: [v f h] M [v f h]^T with a symmetric 3x3 M per point
        c_gg = (4.0 / 9.0) * al * I1 + (16.0 / 9.0) * be * I2 + pj
        c_fg = -(4.0 / 3.0) * al
        c_hg = -(8.0 / 3.0) * be
        c_ff = 4.0 * be
        Q = np.stack([V, Fm, Hm], axis=-1).reshape(ne, nq, 24, 3)     # rows (a, i)
        M = np.zeros((ne, nq, 3, 3))
        M[..., 0, 0] = c_gg
        M[..., 0, 1] = M[..., 1, 0] = c_fg
        M[..., 0, 2] = M[..., 2, 0] = c_hg
        M[..., 1, 1] = c_ff
        QM = (w[..., None, None] * Q) @ M                              # (e, q, 24, 3)
        ke = np.swapaxes(QM, 1, 2).reshape(ne, 24, 3 * nq) @ np.swapaxes(Q, 1, 2).reshape(
            ne, 24, 3 * nq).swapaxes(1, 2)
        # swapped terms: K[a i, b k] += c_T V[a k] V[b i] + c_F f[a k] f[b i]
        c_t = (2.0 / 3.0) * al * I1 + (4.0 / 3.0) * be * I2 - pj
        c_f = -2.0 * be
        R1 = np.concatenate([(w * c_t)[..., None, None] * V, (w * c_f)[..., None, None] * Fm],
                            axis=-1)                                  # (e, q, a, [k k'])
        R2 = np.concatenate([V, Fm], axis=-1)
        R1 = R1.reshape(ne, nq, 8, 2, 3).transpose(0, 2, 4, 1, 3).reshape(ne, 24, 2 * nq)
        R2 = R2.reshape(ne, nq, 8, 2, 3).transpose(0, 2, 4, 1, 3).reshape(ne, 24, 2 * nq)
        sw = (R1 @ R2.swapaxes(1, 2)).reshape(ne, 8, 3, 8, 3)         # (a, k, b, i)
        ke += sw.transpose(0, 1, 4, 3, 2).reshape(ne, 24, 24)
        # isotropic-in-dof terms: delta_ik dN_a (c1 I - 2 be C) dN_b  and  -2 be D_ab b_ik
        Mk = ((2.0 * (al + be * I1))[..., None, None] * np.eye(3)
              - 2.0 * be[..., None, None] * k["C"])
        D8 = ((w[..., None, None] * dn) @ Mk @ np.swapaxes(dn, -1, -2)).sum(axis=1)  # (e, 8, 8)
        ke += np.einsum("eab,ik->eaibk", D8, np.eye(3)).reshape(ne, 24, 24)
        Dq = (dn @ np.swapaxes(dn, -1, -2)).reshape(ne, nq, 64)
        bq = ((-2.0 * w * be)[..., None, None] * (F @ np.swapaxes(F, -1, -2))).reshape(ne, nq, 9)
        Db = (np.swapaxes(Dq, 1, 2) @ bq).reshape(ne, 8, 8, 3, 3)
        ke += Db.transpose(0, 1, 3, 2, 4).reshape(ne, 24, 24)
        # mean-dilatation rank-one term
        g = ((w * J)[..., None, None] * V).sum(axis=1).reshape(ne, 24)  # d(theta V_e)/du
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
            forces.append(-4.0 * fint.reshape(-1, 3)[self._top, 2].sum())
            bulges.append(float(self._patch @ u.reshape(-1, 3)[:, 1]))
            if progress is not None:
                progress(n / p.steps, f"load step {n}/{p.steps}: indentation "
                         f"{d * 1e3:.2f} mm, force {forces[-1]:.3f} N")
        return SweepResult(d_all, np.array(forces), np.array(bulges), self.nodes,
                           time.perf_counter() - start)

    def _factorise(self, u: np.ndarray, perm: np.ndarray) -> object:
        self.stats["factorisations"] += 1
        _, K = self._evaluate(u, tangent=True)
        assert K is not None
        if not np.all(np.isfinite(K.data)):
            raise ConvergenceError("The FEM state became invalid (an element inverted); use "
                                   "more load steps ('steps') or a finer mesh.")
        try:
            return (spla.splu(K[perm][:, perm].tocsc(), permc_spec="NATURAL",
                              diag_pivot_thresh=0.1, options={"SymmetricMode": True}), perm)
        except RuntimeError:
            raise ConvergenceError("The FEM tangent is singular (the skin lost stability); "
                                   "use more load steps ('steps') or a smaller "
                                   "'max_indentation'.") from None

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
        """Full Newton (fresh tangent every iteration) with a safeguard against inversion.

        A reused tangent converges only linearly here: the pressure of a nearly
        incompressible solid makes the tangent change quickly with the state.
        """
        free = self._free
        tol_u = 1e-8 * self.params.height
        for _ in range(30):
            lu = self._factorise(u, perm)
            r = self._evaluate(u, tangent=False)[0][free]
            solver, pm = lu  # type: ignore[misc]
            du = np.empty_like(r)
            du[pm] = solver.solve(-r[pm])
            self.stats["iterations"] += 1
            alpha = 1.0
            while not self._admissible(u, du * alpha):
                alpha *= 0.5
                if alpha < 1e-3:
                    raise ConvergenceError("An element inverted during the FEM solve; use "
                                           "more load steps or a finer mesh.")
            u = u.copy()
            u[free] += alpha * du
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
