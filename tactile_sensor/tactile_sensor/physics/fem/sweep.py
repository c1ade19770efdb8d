"""The load sweep: each load step solved by inexact Newton, its corrections by GMRES
preconditioned with a factorised tangent that is reused until it ages out."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..errors import ConvergenceError
from .assembly import SkinAssembly
from .mooney_rivlin import _det

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


class SkinModel(SkinAssembly):
    """The discretised skin block, ready to sweep the load."""

    #: Refactorise at the next load step's first correction (the preconditioner aged out).
    _stale = False

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
