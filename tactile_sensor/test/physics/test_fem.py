"""FEM verification against closed forms and basic physical behaviour (coarse meshes)."""

from __future__ import annotations

import numpy as np
import pytest
import skfem
from hypothesis import given
from hypothesis import strategies as st

from tactile_sensor.physics import fem
from tactile_sensor.physics.errors import ConvergenceError, PhysicsError
from tactile_sensor.physics.fem import SkinModel
from tactile_sensor.physics.fem import sweep as solver
from tactile_sensor.physics.fem.gradient import _GradientOperator
from tactile_sensor.physics.fem.mesh import _axis
from tactile_sensor.physics.fem.mooney_rivlin import _mooney_rivlin_piola, _mooney_rivlin_tangent
from tactile_sensor.physics.fem.sweep import _RESIDUAL_TOL, _extrapolate
from tactile_sensor.physics.params import PhysicsParams

COARSE = dict(mesh_nx=3, mesh_ny=3, mesh_nz=4)


def closed_form_force(p: PhysicsParams, d: np.ndarray) -> np.ndarray:
    lam = 1.0 - d / p.height
    nominal = 2.0 * (lam - lam**-2) * (p.c10 + p.c01 / lam)
    return -nominal * p.width * p.depth


@pytest.mark.parametrize("c10, c01", [(-33.35, 12180.0), (20000.0, 5000.0)])
def test_frictionless_matches_incompressible_mooney_rivlin(c10, c01):
    p = PhysicsParams(boundary="frictionless", c10=c10, c01=c01, height=0.02, steps=6,
                      **COARSE)
    res = SkinModel(p).sweep()
    expect = closed_form_force(p, res.indentation_m[1:])
    assert np.all(np.abs(res.force_n[1:] / expect - 1.0) < 0.01)


def test_tangent_matches_finite_difference_of_residual():
    p = PhysicsParams(mesh_nx=2, mesh_ny=2, mesh_nz=4, c10=3000.0, module_height=0.0)
    m = SkinModel(p)
    rng = np.random.default_rng(1)
    u = rng.normal(size=m.ndof) * 1e-4
    _, K = m._evaluate(u, True)
    K = K.toarray()
    for j in rng.choice(m._free.size, 4, replace=False):
        du = np.zeros(m.ndof)
        du[m._free[j]] = 1e-8
        fp, _ = m._evaluate(u + du, False)
        fm, _ = m._evaluate(u - du, False)
        col = (fp - fm)[m._free] / 2e-8
        assert np.abs(col - K[:, j]).max() < 1e-6 * np.abs(col).max()


def test_bonded_force_and_bulge_rise_with_indentation():
    p = PhysicsParams(mesh_nx=4, mesh_ny=3, mesh_nz=16, steps=4, max_indentation=0.002)
    res = SkinModel(p).sweep()
    assert np.all(np.diff(res.force_n) > 0)
    assert np.all(np.diff(res.bulge_m) > 0)
    # the bonded block is stiffer than the frictionless one at equal indentation
    free = closed_form_force(p, res.indentation_m[-1:])[0]
    assert res.force_n[-1] > free


@given(st.integers(8, 80), st.floats(1.0, 8.0), st.floats(0.1, 0.9))
def test_graded_axis_keeps_breakpoints_and_grows_away_from_the_refined_point(n, grading, at):
    axis = _axis([0.0, at, 1.0], n, (at,), grading, 0.3)
    h = np.diff(axis)
    assert np.all(h > 0)
    assert axis[0] == 0.0 and axis[-1] == 1.0 and at in axis
    assert abs(h.size - n) <= 2                                   # rounding per segment
    i = int(np.flatnonzero(axis == at)[0])
    near = min(h[i - 1], h[i])                                    # the two beside the point
    assert near <= h.min() * (1 + 1e-9) or near < 1.5 * h.min()
    assert h.max() / h.min() < grading * 1.6 + 0.5


def test_doubling_the_count_halves_every_element():
    """The mesh study's 'twice as fine': the same size function, every element halved."""
    coarse = _axis([0.0, 0.3, 1.0], 20, (0.3,), 6.0, 0.3)
    fine = _axis([0.0, 0.3, 1.0], 40, (0.3,), 6.0, 0.3)
    mid = 0.5 * (fine[1:] + fine[:-1])
    coarse_size = np.diff(coarse)[np.searchsorted(coarse, mid) - 1]
    np.testing.assert_allclose(np.diff(fine) / coarse_size, 0.5, rtol=0.2)


def test_bonded_mesh_is_finest_at_the_window_edges_and_frictionless_is_uniform():
    p = PhysicsParams()
    mesh = fem.build_mesh(p)
    x, z = np.unique(mesh.p[0]), np.unique(mesh.p[2])
    hx, hz = np.diff(x), np.diff(z)
    edge_x = int(np.argmin(abs(x - p.window_width / 2)))
    assert min(hx[edge_x - 1], hx[edge_x]) < 0.5 * hx.max()
    z0 = p.window_center_z - p.window_height / 2
    edge_z = int(np.argmin(abs(z - z0)))
    assert min(hz[edge_z - 1], hz[edge_z]) < 0.5 * hz.max()
    free = fem.build_mesh(p.replace(boundary="frictionless"))
    for k in range(3):
        np.testing.assert_allclose(np.diff(np.unique(free.p[k])),
                                   np.diff(np.unique(free.p[k])).mean(), rtol=1e-9)


def test_mesh_too_coarse_for_the_window_is_refused():
    with pytest.raises(PhysicsError, match="no node inside the photoreflector window"):
        SkinModel(PhysicsParams(mesh_nx=4, mesh_ny=4, mesh_nz=8, mesh_grading=1.0))


def test_progress_is_reported_per_step():
    seen: list[float] = []
    p = PhysicsParams(boundary="frictionless", steps=3, **COARSE)
    SkinModel(p).sweep(lambda f, msg: seen.append(f))
    assert seen == pytest.approx([1 / 3, 2 / 3, 1.0])


def test_too_large_step_reports_convergence_error():
    p = PhysicsParams(boundary="frictionless", steps=1, max_indentation=0.011, height=0.02,
                      bulk_ratio=1e4, **COARSE)
    with pytest.raises(ConvergenceError, match="load steps"):
        SkinModel(p).sweep()


def test_failed_load_step_is_cut_and_the_result_keeps_the_requested_steps(monkeypatch):
    """One 3 mm step of a nearly incompressible block diverges; halving it twice converges,
    and the sweep still reports the one requested step, on the closed form."""
    p = PhysicsParams(boundary="frictionless", steps=1, max_indentation=0.003, height=0.02,
                      **COARSE)
    messages: list[str] = []
    model = SkinModel(p)
    res = model.sweep(lambda _f, msg: messages.append(msg))
    assert model.stats["cuts"] >= 1
    assert res.indentation_m.tolist() == [0.0, 0.003]
    assert res.force_n[-1] == pytest.approx(closed_form_force(p, res.indentation_m[-1:])[0],
                                            rel=0.01)
    assert len(messages) == 1 and "step cut" in messages[0]
    monkeypatch.setattr(solver, "_MAX_CUTS", 0)
    with pytest.raises(ConvergenceError, match="load steps"):
        SkinModel(p).sweep()


def test_box_gradient_fast_path_matches_the_general_one():
    """The GEMM path for box elements must equal the general per-point contraction."""
    m = SkinModel(PhysicsParams(mesh_nx=2, mesh_ny=3, mesh_nz=5, module_height=0.0,
                                mesh_grading=1.7))
    fast = m._gradient
    assert fast._box
    general = _GradientOperator(m._dndx, m._w, m.mesh.p[:, m._conn.T])
    general._box = False
    rng = np.random.default_rng(3)
    ue = rng.normal(size=(m._w.shape[0], 24)) * 1e-3
    np.testing.assert_allclose(fast.deformation(ue), general.deformation(ue), atol=1e-14)
    P = rng.normal(size=(3, 3, *m._w.shape))
    np.testing.assert_allclose(fast.divergence(P), general.divergence(P), rtol=1e-10,
                               atol=1e-14)
    A = rng.normal(size=(3, 3, 3, 3, *m._w.shape))
    np.testing.assert_allclose(fast.stiffness(A), general.stiffness(A), rtol=1e-10,
                               atol=1e-12)


def test_a_distorted_mesh_takes_the_general_path_and_passes_the_patch_test():
    """A linear displacement field gives F = I + G exactly at every point, boxes or not."""
    base = skfem.MeshHex.init_tensor(*(np.linspace(0.0, 0.01, 4),) * 3)
    pts = base.p.copy()
    inner = np.flatnonzero(np.all((pts > 1e-6) & (pts < 0.01 - 1e-6), axis=0))[0]
    pts[:, inner] += 1e-3                                   # one interior node moved
    for mesh, box in ((base, True), (skfem.MeshHex(pts, base.t), False)):
        basis = skfem.Basis(mesh, skfem.ElementHex1(), intorder=2)
        dndx = np.stack([np.stack(basis.basis[a][0].grad, axis=-1) for a in range(8)],
                        axis=2)
        op = _GradientOperator(dndx, basis.dx, mesh.p[:, mesh.t])
        assert op._box is box
        G = np.array([[0.01, -0.02, 0.03], [0.0, 0.015, -0.01], [0.02, 0.0, -0.03]])
        ue = (G @ mesh.p)[:, mesh.t].transpose(2, 1, 0).reshape(-1, 24)
        F = op.deformation(ue)
        np.testing.assert_allclose(F, np.broadcast_to((np.eye(3) + G)[:, :, None, None],
                                                      F.shape), atol=1e-12)


def test_inexact_newton_agrees_with_refactorising_every_iteration(monkeypatch):
    """Reusing a stale tangent as GMRES preconditioner must not change the equilibrium."""
    p = PhysicsParams(mesh_nx=4, mesh_ny=3, mesh_nz=16, steps=5, max_indentation=0.002)
    reused = SkinModel(p)
    res = reused.sweep()
    monkeypatch.setattr(solver, "_KRYLOV_REFRESH", -1)   # every correction ages the tangent out
    fresh = SkinModel(p)
    ref = fresh.sweep()
    assert fresh.stats["factorisations"] > reused.stats["factorisations"]
    # both are converged to the solver's out-of-balance tolerance, not further
    tol_n = _RESIDUAL_TOL * p.shear_modulus * p.height**2
    np.testing.assert_allclose(res.force_n[1:], ref.force_n[1:], rtol=0, atol=2 * tol_n)
    np.testing.assert_allclose(res.bulge_m[1:], ref.bulge_m[1:], rtol=1e-4)


@given(st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3),
       st.floats(0.1, 3.0), st.floats(0.0, 2.0))
def test_predictor_reproduces_a_quadratic_load_path(coef, step, ahead):
    a, b, c = coef
    ds = [0.0, step, 2 * step]
    history = [(d, np.array([a + b * d + c * d * d])) for d in ds]
    d = 2 * step + ahead * step
    assert _extrapolate(history, d)[0] == pytest.approx(a + b * d + c * d * d, abs=1e-9)


def test_a_krylov_step_that_would_invert_elements_falls_back_to_a_newton_step(monkeypatch):
    p = PhysicsParams(mesh_nx=4, mesh_ny=3, mesh_nz=16, steps=5, max_indentation=0.002)
    ref = SkinModel(p).sweep()
    model = SkinModel(p)
    monkeypatch.setattr(model, "_krylov", lambda u, r, lu, atol: np.full(r.shape, -1.0))
    res = model.sweep()    # every Krylov step would crush the block by a metre
    np.testing.assert_allclose(res.force_n, ref.force_n, rtol=1e-5)


def test_extrapolation_off_is_the_mesh_alone():
    p = PhysicsParams(mesh_nx=4, mesh_ny=3, mesh_nz=12, steps=3, max_indentation=0.001,
                      mesh_extrapolation_order_force=0.0, mesh_extrapolation_order_bulge=0.0)
    alone = SkinModel(p).sweep()
    res = fem.extrapolated_sweep(p)
    np.testing.assert_array_equal(res.force_n, alone.force_n)
    np.testing.assert_array_equal(res.bulge_m, alone.bulge_m)


def test_extrapolated_frictionless_block_still_matches_the_closed_form():
    p = PhysicsParams(boundary="frictionless", height=0.02, steps=6, **COARSE)
    res = fem.extrapolated_sweep(p)
    expect = closed_form_force(p, res.indentation_m[1:])
    assert np.all(np.abs(res.force_n[1:] / expect - 1.0) < 0.01)


def test_extrapolation_makes_the_bulge_nearly_mesh_independent():
    """Between a mesh and one twice as fine, the extrapolated bulge moves far less than the
    raw one (the mesh study's point, on meshes small enough for a unit test)."""
    p = PhysicsParams(mesh_nx=6, mesh_ny=6, mesh_nz=18, steps=1, max_indentation=5e-5)
    fine = p.replace(mesh_nx=12, mesh_ny=12, mesh_nz=36)
    raw_coarse, raw_fine = SkinModel(p).sweep(), SkinModel(fine).sweep()
    ext_coarse, ext_fine = fem.extrapolated_sweep(p), fem.extrapolated_sweep(fine)
    raw_change = abs(raw_fine.bulge_m[-1] / raw_coarse.bulge_m[-1] - 1)
    ext_change = abs(ext_fine.bulge_m[-1] / ext_coarse.bulge_m[-1] - 1)
    print(f"bulge change, raw {raw_change:.2%}, extrapolated {ext_change:.2%}")
    assert ext_change < 0.4 * raw_change, (raw_change, ext_change)


def test_extrapolated_sweep_reports_progress_over_both_meshes():
    seen: list[float] = []
    p = PhysicsParams(boundary="frictionless", steps=3, **COARSE)
    fem.extrapolated_sweep(p, lambda f, msg: seen.append(f))
    assert seen == sorted(seen) and seen[-1] == pytest.approx(1.0) and len(seen) == 6


def test_a_half_mesh_too_coarse_for_the_window_names_the_way_out():
    p = PhysicsParams(mesh_nx=2, mesh_ny=2, mesh_nz=12, steps=2, max_indentation=0.001)
    SkinModel(p)  # the mesh itself resolves the window
    with pytest.raises(PhysicsError, match=r"half-as-fine mesh .*1 x 1 x 6.*"
                                           r"mesh_extrapolation_order_force and "
                                           r"mesh_extrapolation_order_bulge to 0"):
        fem.extrapolated_sweep(p)


def _random_deformations(seed: int, n: int, spread: float) -> np.ndarray:
    """(3, 3, n) deformation gradients around the identity with det F > 0.2."""
    rng = np.random.default_rng(seed)
    F = np.eye(3)[:, :, None] + spread * rng.normal(size=(3, 3, 4 * n))
    keep = np.linalg.det(F.transpose(2, 0, 1)) > 0.2
    return F[:, :, keep][:, :, :n]


@given(st.integers(0, 2**31), st.floats(0.01, 0.5), st.floats(-1e4, 3e4),
       st.floats(1e3, 3e4), st.floats(-1e6, 1e6))
def test_closed_form_tangent_equals_the_complex_step_of_the_stress(seed, spread, c10, c01,
                                                                    pres):
    """The closed-form dP/dF must be the derivative of the very stress the residual uses."""
    F = _random_deformations(seed, 16, spread)
    n = F.shape[2]
    P_ref, _ = _mooney_rivlin_piola(F, c10, c01, np.full(n, pres))
    P, A = _mooney_rivlin_tangent(F, c10, c01, np.full(n, pres))
    scale = np.abs(P_ref).max() + abs(c10) + c01 + abs(pres)
    np.testing.assert_allclose(P, P_ref, rtol=0, atol=1e-12 * scale)
    Fc = np.repeat(F[:, :, None].astype(complex), 9, axis=2)
    for m in range(9):
        Fc[m // 3, m % 3, m] += 1e-30j
    Pc, _ = _mooney_rivlin_piola(Fc, c10, c01, np.full((9, n), pres))
    A_ref = (Pc.imag / 1e-30).reshape(3, 3, 3, 3, n)
    np.testing.assert_allclose(A, A_ref, rtol=0, atol=1e-10 * (np.abs(A_ref).max() + scale))


def test_closed_form_tangent_matches_a_central_difference_of_the_stress():
    """Independent of complex arithmetic: dP/dF by central differences, per component."""
    F = _random_deformations(7, 40, 0.3)
    n = F.shape[2]
    pres = np.linspace(-2e4, 2e4, n)
    _, A = _mooney_rivlin_tangent(F, -33.35, 12180.0, pres)
    h = 1e-6
    for k in range(3):
        for L in range(3):
            dF = np.zeros_like(F)
            dF[k, L] = h
            Pp, _ = _mooney_rivlin_piola(F + dF, -33.35, 12180.0, pres)
            Pm, _ = _mooney_rivlin_piola(F - dF, -33.35, 12180.0, pres)
            fd = (Pp - Pm) / (2 * h)
            np.testing.assert_allclose(A[:, :, k, L], fd, rtol=0,
                                       atol=1e-6 * np.abs(fd).max())
    # the tangent of a hyperelastic stress is major-symmetric: A_iKkL = A_kLiK
    np.testing.assert_allclose(A, A.transpose(2, 3, 0, 1, 4), rtol=0,
                               atol=1e-12 * np.abs(A).max())


def test_krylov_correction_meets_its_target_on_the_true_linear_residual():
    """Right-preconditioned GMRES with an aged single-precision tangent: |r + K du| must be
    within the target it was given, measured with the exact float64 tangent (a stopping
    test on the preconditioned residual would not guarantee this)."""
    p = PhysicsParams(mesh_nx=3, mesh_ny=3, mesh_nz=8, max_indentation=0.002)
    m = SkinModel(p)
    u0 = np.zeros(m.ndof)
    lu = m._factorise(u0, m._perm)                          # tangent of the unloaded block
    u = np.zeros(m.ndof)
    m._prescribe(u, 0.3)
    u, _ = m._tangent_predictor(u0, 0.3, m._perm)           # a loaded, unbalanced state
    fint, K = m._evaluate(u, True)
    r = fint[m._free]
    target = 1e-4 * float(np.linalg.norm(r))
    du = m._krylov(u, r, lu, target)
    assert du is not None
    assert m.stats["krylov"] > 1                            # the aged tangent needed GMRES
    assert float(np.linalg.norm(r + K @ du)) <= 1.05 * target
    assert m._krylov(u, r, lu, 1e-30) is None               # unreachable: reported, not raised
