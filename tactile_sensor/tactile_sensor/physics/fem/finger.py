"""Total-Lagrangian FEM of a finger bending at a soft joint: what a clipped-on module reads.

The finger (``physics/bend.py``: ``BendGeometry``) is a silicone body of the paper's
Mooney-Rivlin law around two rigid bone cores, the proximal one fixed and the distal one
turned by the prescribed joint angle; between them the silicone alone is the joint. A
tendon runs from a guide on the proximal phalanx to an anchor on the distal one over the
palmar side; its tension is the unknown that holds the angle, so each solve gives the
tension the angle needs (the drive) besides the skin's shape. A fingertip contact is a
force on a palmar patch at the tip, normal to the distal phalanx.

Each module is a rigid U-clip gripping the skin around the dorsal and lateral faces over
its length, open on the palm (the grasp surface and the tendon). Its photoreflector looks
at the skin through a window in the clip, or beyond the clip's end over free skin. The clip
floats: its planar motion (two translations, one rotation) is solved with the skin, and
what the photoreflector reads is where the skin crosses its optical axis, in the clip's
frame (``FingerModel.bulges``).

Half model: the finger is symmetric about its bending plane y = 0, so y >= 0 is meshed and
forces from the mesh are doubled. Every rigid body moves in the x-z plane; its rotation is
about +y (right-hand rule), so a positive joint angle curls the tip toward +x, the palmar
side. The same hexahedra, Mooney-Rivlin kernels and mean-dilatation pressure as the skin
block (``assembly.py``); the systems are small, so each Newton step is a direct solve of
the exact tangent, bordered by the rigid bodies' rows and the tendon's column.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
import skfem

from ..errors import ConvergenceError, PhysicsError
from .gradient import _GradientOperator
from .mooney_rivlin import _cofactor, _det, _mooney_rivlin_piola, _mooney_rivlin_tangent

Progress = Callable[[float, str], None]

_RESIDUAL_TOL = 1e-7   # converged when |out-of-balance| < this * mu * thickness^2 [N]
_NEWTON_MAX = 25
_MAX_CUTS = 6
_ROUNDOFF = 1.6e4  # a Newton stalled within this many tolerances (~10 mN, ~1e-3 of the
#                   7 N tension at 2 N contact) is taken as balanced; docs/bend.md


@dataclass(frozen=True)
class FingerMesh:
    """What the solver needs of a finger: dimensions [m], material [Pa], mesh size [m],
    the modules' clips and windows, the tendon's guide and anchor, the contact patch."""

    thickness: float          # x, the bending direction (palmar +x)
    width: float              # y, across the finger (the module clips across it)
    proximal_length: float    # skin-covered proximal phalanx modelled, z in [-Lp, 0]
    joint_length: float       # the soft joint, z in [0, Lj]
    distal_length: float      # distal phalanx to the tip, z in [Lj, Lj + Ld]
    skin_thickness: float     # skin over the bone cores
    c10: float
    c01: float
    bulk_ratio: float
    mesh_size: float
    tendon_height: float      # guide and anchor x (above the palmar skin)
    tendon_guide_z: float     # on the proximal phalanx
    tendon_anchor_z: float    # on the distal phalanx
    contact_z: float          # centre of the fingertip contact patch on the palmar face
    contact_length: float
    #: per module: (window's arc position, face, window offset across the face, clip
    #: centre's arc position, clip length, window length along z, window width across)
    modules: tuple[tuple[float, str, float, float, float, float, float], ...]

    @property
    def length(self) -> float:
        return self.proximal_length + self.joint_length + self.distal_length

    @property
    def shear_modulus(self) -> float:
        return 2.0 * (self.c10 + self.c01)


@dataclass(frozen=True)
class FingerSweep:
    """One sweep of the joint angle at one tip force: per angle, the tendon tension [N],
    each module's skin bulge toward its photoreflector [m] (positive: the gap closes) and
    the distal phalanx's translation [m]."""

    angle_rad: np.ndarray
    tip_force_n: float
    tension_n: np.ndarray
    bulge_m: np.ndarray         # (angles, modules)
    nodes: int
    seconds: float


def _axis(breaks: Sequence[float], size: float) -> np.ndarray:
    """Nodes over sorted breakpoints, each interval split into elements of at most ``size``."""
    b = sorted({round(float(v), 12) for v in breaks})
    pts = [np.linspace(b0, b1, max(1, math.ceil((b1 - b0) / size - 1e-9)) + 1)[:-1]
           for b0, b1 in itertools.pairwise(b)]
    return np.concatenate([*pts, [b[-1]]])


def _rot(phi: float) -> np.ndarray:
    """Rotation about +y by phi in the (x, z) plane."""
    c, s = math.cos(phi), math.sin(phi)
    return np.array([[c, s], [-s, c]])


def _drot(phi: float) -> np.ndarray:
    c, s = math.cos(phi), math.sin(phi)
    return np.array([[-s, c], [-c, -s]])


class FingerModel:
    """The discretised finger: bodies, constraints, residual and bordered Newton."""

    def __init__(self, geo: FingerMesh) -> None:
        self.geo = g = geo
        hx, hy = g.thickness / 2, g.width / 2
        bx, by = hx - g.skin_thickness, hy - g.skin_thickness
        lj, tip = g.joint_length, g.joint_length + g.distal_length
        xb = [-hx, -bx, bx, hx]
        yb = [0.0, by, hy]
        zb = [-g.proximal_length, 0.0, lj, tip - g.skin_thickness, tip,
              g.contact_z - g.contact_length / 2, g.contact_z + g.contact_length / 2]
        for s, face, off, sc, clip, wl, ww in g.modules:
            # the window's centre lines are nodes too: the optical axis meets the skin there
            zb += [sc - clip / 2, sc + clip / 2, s - wl / 2, s, s + wl / 2]
            if face == "lateral":
                xb += [off - ww / 2, off, off + ww / 2]
            else:
                yb += [ww / 4, ww / 2]
        self.mesh = skfem.MeshHex.init_tensor(_axis(xb, g.mesh_size),
                                              _axis(yb, g.mesh_size),
                                              _axis(zb, g.mesh_size))
        mesh = self.mesh
        basis = skfem.Basis(mesh, skfem.ElementHex1(), intorder=2)
        nel = mesh.t.shape[1]
        self._dndx = np.stack([np.stack(basis.basis[a][0].grad, axis=-1)
                               for a in range(8)], axis=2)
        self._w = basis.dx
        self._vol = self._w.sum(axis=1)
        self._conn = mesh.t.T
        self._edofs = (3 * self._conn[:, :, None] + np.arange(3)).reshape(nel, 24)
        self.nodes = mesh.p.shape[1]
        self.ndof = 3 * self.nodes
        self._gradient = _GradientOperator(self._dndx, self._w, mesh.p[:, self._conn.T])
        self._mu = g.shear_modulus
        self._kappa = g.bulk_ratio * self._mu
        self._setup(bx, by, lj, tip)

    # -- bodies and constraints ------------------------------------------------------------
    def _setup(self, bx: float, by: float, lj: float, tip: float) -> None:
        g = self.geo
        X = self.mesh.p
        tol = 1e-9
        hx, hy = g.thickness / 2, g.width / 2
        core = (np.abs(X[0]) <= bx + tol) & (X[1] <= by + tol)
        fixed = np.zeros((self.nodes, 3), dtype=bool)
        fixed[X[1] < tol, 1] = True                                   # symmetry y = 0
        fixed[(core & (X[2] <= tol)) | (X[2] < -g.proximal_length + tol), :] = True
        owner = -np.ones(self.nodes, dtype=int)                       # rigid body index
        distal = core & (X[2] >= lj - tol) & (X[2] <= tip - g.skin_thickness + tol)
        owner[distal] = 0
        centres = [np.array([0.0, lj])]                               # (x, z) references
        #: per module: (face, window offset, arc position, window width, clip body)
        self.windows: list[tuple[str, float, float, float, int]] = []
        outer = (X[0] < -hx + tol) | (X[1] > hy - tol)                # dorsal or lateral
        for k, (s, face, off, sc, clip, wl, ww) in enumerate(g.modules):
            band = outer & (np.abs(X[2] - sc) <= clip / 2 + tol)
            if face == "dorsal":
                inside = (X[0] < -hx + tol) & (X[1] < ww / 2 - tol)
            else:
                inside = (X[1] > hy - tol) & (np.abs(X[0] - off) < ww / 2 - tol)
            inside &= np.abs(X[2] - s) < wl / 2 - tol
            if np.any(band & (owner >= 0)) or np.any(band & fixed.all(axis=1)):
                raise PhysicsError(f"Module {k + 1}'s clip overlaps another clip or the "
                                   "fixed base; move it along the finger.")
            owner[band & ~inside] = k + 1
            centres.append(np.array([hx * (-1.0 if face == "dorsal" else 0.0), sc]))
            self.windows.append((face, off, s, ww, k + 1))
        self._owner = owner
        self._centres = np.array(centres)
        fixed[owner >= 0, 1] = True                                   # planar bodies
        self._fixed_node = fixed.all(axis=1)
        # unknowns: free skin dofs, then per body (Ux, Uz, phi), the distal phi being
        # replaced by the tendon tension
        skin = (owner < 0)[:, None] & ~fixed
        self._free = np.flatnonzero(skin.ravel())
        self._nb = len(centres)
        self.nq = self._free.size + 3 * self._nb
        self._contact = self._contact_weights()

    def _contact_weights(self) -> np.ndarray:
        X = self.mesh.p
        f = self.mesh.facets
        g = self.geo
        on = np.all(X[0][f] > g.thickness / 2 - 1e-9, axis=0) & \
            (np.abs(X[2][f].mean(axis=0) - g.contact_z) < g.contact_length / 2)
        w = np.zeros(self.nodes)
        for k in np.flatnonzero(on):
            nodes = f[:, k]
            np.add.at(w, nodes, np.ptp(X[1][nodes]) * np.ptp(X[2][nodes]) / 4)
        return w / w.sum()

    # -- kinematics ---------------------------------------------------------------------
    def _displacement(self, q: np.ndarray, theta: float) -> tuple[np.ndarray, sp.csr_matrix]:
        """u (all dofs) and G = du/dq, with the distal body's rotation held at theta."""
        u = np.zeros(self.ndof)
        u[self._free] = q[:self._free.size]
        rows, cols, vals = [self._free], [np.arange(self._free.size)], \
            [np.ones(self._free.size)]
        X = self.mesh.p
        base = self._free.size
        for b in range(self._nb):
            nodes = np.flatnonzero(self._owner == b)
            ux, uz, phi = q[base + 3 * b: base + 3 * b + 3]
            if b == 0:
                phi = theta
            arm = np.stack([X[0, nodes], X[2, nodes]]) - self._centres[b][:, None]
            moved = _rot(phi) @ arm - arm
            u[3 * nodes] = moved[0] + ux
            u[3 * nodes + 2] = moved[1] + uz
            c = base + 3 * b
            rows += [3 * nodes, 3 * nodes + 2]
            cols += [np.full(nodes.size, c), np.full(nodes.size, c + 1)]
            vals += [np.ones(nodes.size), np.ones(nodes.size)]
            if b > 0:                                 # the distal rotation is prescribed
                d = _drot(phi) @ arm
                rows += [3 * nodes, 3 * nodes + 2]
                cols += [np.full(nodes.size, c + 2)] * 2
                vals += [d[0], d[1]]
        G = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows),
                                                  np.concatenate(cols))),
                          shape=(self.ndof, self.nq))
        return u, G

    def _moment_row(self, theta: float) -> np.ndarray:
        """d(u)/d(phi_distal): turns the internal forces into the distal body's moment."""
        X = self.mesh.p
        nodes = np.flatnonzero(self._owner == 0)
        arm = np.stack([X[0, nodes], X[2, nodes]]) - self._centres[0][:, None]
        d = _drot(theta) @ arm
        row = np.zeros(self.ndof)
        row[3 * nodes] = d[0]
        row[3 * nodes + 2] = d[1]
        return row

    def _tendon(self, q: np.ndarray, theta: float) -> tuple[np.ndarray, np.ndarray, float]:
        """Unit direction e (x, z) of the tendon's pull on the anchor, de/dU, and the arm
        e . dR a (the anchor's generalised moment per unit tension)."""
        g = self.geo
        base = self._free.size
        U = q[base:base + 2]
        guide = np.array([g.tendon_height, g.tendon_guide_z])
        a = np.array([g.tendon_height, g.tendon_anchor_z]) - self._centres[0]
        anchor = self._centres[0] + U + _rot(theta) @ a
        d = guide - anchor
        length = float(np.linalg.norm(d))
        e = d / length
        de = -(np.eye(2) - np.outer(e, e)) / length
        return e, de, float(e @ (_drot(theta) @ a))

    # -- material -------------------------------------------------------------------------
    def _forces(self, u: np.ndarray, tangent: bool) -> tuple[np.ndarray, sp.csr_matrix | None]:
        F = self._gradient.deformation(u[self._edofs])
        J = _det(F)
        if np.any(J <= 0):
            raise ConvergenceError("An element inverted during the finger's FEM solve; use "
                                   "more angle steps or a finer mesh.")
        pres = self._kappa * ((self._w * J).sum(axis=1) / self._vol - 1.0)
        P, _ = _mooney_rivlin_piola(F, self.geo.c10, self.geo.c01,
                                    np.broadcast_to(pres[:, None], J.shape))
        fe = self._gradient.divergence(P)
        fint = np.bincount(self._edofs.ravel(), weights=fe.ravel(), minlength=self.ndof)
        if not tangent:
            return fint, None
        _, A = _mooney_rivlin_tangent(F, self.geo.c10, self.geo.c01, pres[:, None])
        ke = self._gradient.stiffness(A)
        gvec = self._gradient.divergence(_cofactor(F)).reshape(-1, 24)
        ke += (self._kappa / self._vol)[:, None, None] * gvec[:, :, None] * gvec[:, None, :]
        r = np.repeat(self._edofs, 24, axis=1).ravel()
        c = np.tile(self._edofs, (1, 24)).ravel()
        K = sp.csr_matrix((ke.ravel(), (r, c)), shape=(self.ndof, self.ndof))
        return fint, K

    # -- equilibrium ----------------------------------------------------------------------
    def _system(self, q: np.ndarray, theta: float, force: float, tangent: bool
                ) -> tuple[np.ndarray, sp.csr_matrix | None]:
        """Residual in q (the distal phi row being the moment balance, its unknown the
        tension) and, if asked, its Jacobian."""
        u, G = self._displacement(q, theta)
        fint, K = self._forces(u, tangent)
        m = self._moment_row(theta)
        base = self._free.size
        tension = q[base + 2] / 2.0                       # the half model carries half
        e, de, arm = self._tendon(q, theta)
        fext = np.zeros(self.ndof)
        push = _rot(theta) @ np.array([-1.0, 0.0])        # into the palmar face
        fext[0::3] += self._contact * push[0] * force / 2.0
        fext[2::3] += self._contact * push[1] * force / 2.0
        r = G.T @ (fint - fext)
        r[base + 2] = m @ (fint - fext)
        r[base:base + 2] -= tension * e
        r[base + 2] -= tension * arm
        if not tangent:
            return r, None
        assert K is not None
        KG = K @ G
        keep = np.ones(self.nq)
        keep[base + 2] = 0.0
        Jm = sp.diags(keep) @ (G.T @ KG)
        moment = sp.csr_matrix(m @ KG)
        rows, cols, vals = [], [], []
        # the free clips' rotation: their nodal forces turn with them (geometric term)
        X = self.mesh.p
        for b in range(1, self._nb):
            nodes = np.flatnonzero(self._owner == b)
            c = base + 3 * b + 2
            arm_b = np.stack([X[0, nodes], X[2, nodes]]) - self._centres[b][:, None]
            d2 = -(_rot(q[c]) @ arm_b)
            rows.append(c)
            cols.append(c)
            vals.append(float(fint[3 * nodes] @ d2[0] + fint[3 * nodes + 2] @ d2[1]))
        # the tendon: its direction follows the anchor (de/dU), its tension is a column
        a = np.array([self.geo.tendon_height, self.geo.tendon_anchor_z]) - self._centres[0]
        dU = tension * de
        darm = tension * (de.T @ (_drot(theta) @ a))
        for i in range(2):
            for j in range(2):
                rows.append(base + i)
                cols.append(base + j)
                vals.append(-dU[i, j])
            rows.append(base + 2)
            cols.append(base + i)
            vals.append(-darm[i])
        rows += [base, base + 1, base + 2]
        cols += [base + 2] * 3
        vals += [-e[0] / 2.0, -e[1] / 2.0, -arm / 2.0]
        C = sp.csr_matrix((vals, (rows, cols)), shape=(self.nq, self.nq))
        R = sp.csr_matrix((moment.data, (np.full(moment.nnz, base + 2), moment.indices)),
                          shape=(self.nq, self.nq))
        return r, (Jm + R + C).tocsc()

    def _admissible(self, q: np.ndarray, theta: float) -> bool:
        u, _ = self._displacement(q, theta)
        return bool(np.all(_det(self._gradient.deformation(u[self._edofs])) > 0.05))

    def _residual(self, q: np.ndarray, theta: float, force: float) -> float:
        """|r| at q, inf where an element would invert."""
        if not self._admissible(q, theta):
            return math.inf
        return float(np.linalg.norm(self._system(q, theta, force, False)[0]))

    def solve(self, q: np.ndarray, theta: float, force: float) -> np.ndarray:
        """Equilibrium at (theta, force) by Newton from q (raises ConvergenceError).

        Each correction is backtracked until the residual falls (or an element would
        invert): the full step from a far start overshoots in the nearly incompressible
        skin under the clips.
        """
        tol = _RESIDUAL_TOL * self._mu * self.geo.thickness ** 2
        q = q.copy()
        for _ in range(_NEWTON_MAX):
            r, J = self._system(q, theta, force, True)
            norm = float(np.linalg.norm(r))
            if norm < tol:
                return q
            dq = spla.spsolve(J, -r)
            if not np.all(np.isfinite(dq)):
                raise ConvergenceError("The finger's FEM tangent is singular; use more "
                                       "angle steps.")
            alpha = 1.0
            while self._residual(q + alpha * dq, theta, force) > (1.0 - 1e-4 * alpha) * norm:
                alpha *= 0.5
                if alpha < 1e-3:
                    if norm < _ROUNDOFF * tol:
                        return q          # balanced to ~10 mN (see _ROUNDOFF)
                    raise ConvergenceError(f"The finger's FEM Newton solve stalled at a "
                                           f"residual of {norm:.2g} N; use more angle steps "
                                           "or a finer mesh.")
            q = q + alpha * dq
        raise ConvergenceError("The finger's FEM Newton solve did not converge; use more "
                               "angle steps or a coarser tip force step.")

    def _path(self, q: np.ndarray, start: tuple[float, float], end: tuple[float, float],
              depth: int = 0) -> np.ndarray:
        """Equilibrium at ``end`` from the one at ``start``, halving the step on failure."""
        try:
            return self.solve(self._predict(q, start, end), *end)
        except ConvergenceError:
            if depth >= _MAX_CUTS:
                raise
            mid = (0.5 * (start[0] + end[0]), 0.5 * (start[1] + end[1]))
            q = self._path(q, start, mid, depth + 1)
            return self._path(q, mid, end, depth + 1)

    def _predict(self, q: np.ndarray, start: tuple[float, float], end: tuple[float, float]
                 ) -> np.ndarray:
        """The linear response at ``start`` to the step to ``end``: Newton's start.

        Turning the distal bone alone puts a large volume error into the elements at its
        faces, and Newton from there crawls for a nearly incompressible solid (as the
        probe's does on the skin block: ``SkinModel._tangent_predictor``).
        """
        eps = 1e-3
        r0, J = self._system(q, *start, True)
        mid = (start[0] + eps * (end[0] - start[0]), start[1] + eps * (end[1] - start[1]))
        r1, _ = self._system(q, *mid, False)
        dq = spla.spsolve(J, -(r0 + (r1 - r0) / eps))
        if not np.all(np.isfinite(dq)):
            return q
        alpha = 1.0
        while not self._admissible(q + alpha * dq, end[0]):
            alpha *= 0.5
            if alpha < 1e-3:
                return q
        return q + alpha * dq

    def bulges(self, q: np.ndarray, theta: float) -> np.ndarray:
        """How far the skin on each photoreflector's optical axis has come toward it [m]
        (positive: the gap closes), in its clip's frame.

        The axis is fixed to the clip; the skin slides past it as well as toward it, so
        each row of surface nodes across the window is followed in the clip's frame and its
        normal coordinate interpolated where it crosses the axis; the rows are averaged
        over the window's width (trapezoid weights).
        """
        u, _ = self._displacement(q, theta)
        x = self.mesh.p + u.reshape(-1, 3).T                          # deformed (3, n)
        X = self.mesh.p
        base = self._free.size
        hx, hy = self.geo.thickness / 2, self.geo.width / 2
        tol = 1e-9
        out = []
        for face, off, s, ww, b in self.windows:
            ux, uz, phi = q[base + 3 * b: base + 3 * b + 3]
            c = self._centres[b]
            rel = np.stack([x[0], x[2]]) - (c + np.array([ux, uz]))[:, None]
            local = _rot(phi).T @ rel + c[:, None]                     # clip frame (x, z)
            if face == "dorsal":
                on, across, lo, hi = X[0] < -hx + tol, X[1], 0.0, ww / 2
            else:
                on, across, lo, hi = X[1] > hy - tol, X[0], off - ww / 2, off + ww / 2
            rows = np.unique(np.round(across[on], 12))
            rows = rows[(rows >= lo - tol) & (rows <= hi + tol)]
            values = []
            for r in rows:
                nodes = np.flatnonzero(on & (np.abs(across - r) < tol))
                order = np.argsort(local[1, nodes])
                z = local[1, nodes][order]
                normal = (-(local[0, nodes] + hx) if face == "dorsal"
                          else x[1, nodes] - hy)[order]
                values.append(float(np.interp(s, z, normal)))
            w = np.ones(1) if rows.size == 1 else np.gradient(rows)
            out.append(float(np.average(values, weights=w)))
        return np.array(out)

    def sweep(self, angles: np.ndarray, force: float, progress: Progress | None = None,
              max_step: float = 0.05) -> FingerSweep:
        """Apply the tip force at the straight finger, then step the angle through
        ``angles`` (increasing, from 0), no step longer than ``max_step`` [rad]."""
        import time

        start = time.perf_counter()
        q = np.zeros(self.nq)
        for f0, f1 in zip(np.linspace(0.0, force, 4)[:-1], np.linspace(0.0, force, 4)[1:],
                          strict=True):
            if f1 > f0:
                q = self._path(q, (0.0, float(f0)), (0.0, float(f1)))
        tension, bulge = [], []
        last = 0.0
        for k, theta in enumerate(angles):
            n = max(1, math.ceil((float(theta) - last) / max_step - 1e-9))
            for a0, a1 in zip(np.linspace(last, theta, n + 1)[:-1],
                              np.linspace(last, theta, n + 1)[1:], strict=True):
                if a1 > a0:
                    q = self._path(q, (float(a0), force), (float(a1), force))
            last = float(theta)
            tension.append(float(q[self._free.size + 2]))
            bulge.append(self.bulges(q, float(theta)))
            if progress is not None:
                progress((k + 1) / len(angles), f"tip force {force:.2f} N, angle "
                         f"{math.degrees(theta):.0f} deg, tension {tension[-1]:.2f} N")
        return FingerSweep(np.asarray(angles, float), float(force), np.array(tension),
                           np.array(bulge).reshape(len(angles), len(self.windows)),
                           self.nodes, time.perf_counter() - start)
