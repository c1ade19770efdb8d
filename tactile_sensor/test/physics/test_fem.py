"""FEM verification against closed forms and basic physical behaviour (coarse meshes)."""

from __future__ import annotations

import numpy as np
import pytest
import skfem
from hypothesis import given
from hypothesis import strategies as st

from tactile_sensor.physics import fem
from tactile_sensor.physics.errors import ConvergenceError, PhysicsError
from tactile_sensor.physics.fem import SkinModel, _GradientOperator
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


def test_mesh_too_coarse_for_the_window_is_refused():
    with pytest.raises(PhysicsError, match="no node inside the photoreflector window"):
        SkinModel(PhysicsParams(mesh_nx=4, mesh_ny=4, mesh_nz=8))


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
    monkeypatch.setattr(fem, "_KRYLOV_REFRESH", -1)   # every correction ages the tangent out
    fresh = SkinModel(p)
    ref = fresh.sweep()
    assert fresh.stats["factorisations"] > reused.stats["factorisations"]
    np.testing.assert_allclose(res.force_n[1:], ref.force_n[1:], rtol=1e-5)
    np.testing.assert_allclose(res.bulge_m[1:], ref.bulge_m[1:], rtol=1e-5)


@given(st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3),
       st.floats(0.1, 3.0), st.floats(0.0, 2.0))
def test_predictor_reproduces_a_quadratic_load_path(coef, step, ahead):
    a, b, c = coef
    ds = [0.0, step, 2 * step]
    history = [(d, np.array([a + b * d + c * d * d])) for d in ds]
    d = 2 * step + ahead * step
    assert fem._extrapolate(history, d)[0] == pytest.approx(a + b * d + c * d * d, abs=1e-9)


def test_a_krylov_step_that_would_invert_elements_falls_back_to_a_newton_step(monkeypatch):
    p = PhysicsParams(mesh_nx=4, mesh_ny=3, mesh_nz=16, steps=5, max_indentation=0.002)
    ref = SkinModel(p).sweep()
    model = SkinModel(p)
    monkeypatch.setattr(model, "_krylov", lambda u, r, lu, atol: np.full(r.shape, -1.0))
    res = model.sweep()    # every Krylov step would crush the block by a metre
    np.testing.assert_allclose(res.force_n, ref.force_n, rtol=1e-5)
