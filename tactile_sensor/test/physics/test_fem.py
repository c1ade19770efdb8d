"""FEM verification against closed forms and basic physical behaviour (coarse meshes)."""

from __future__ import annotations

import numpy as np
import pytest

from tactile_sensor.physics.errors import ConvergenceError, PhysicsError
from tactile_sensor.physics.fem import SkinModel
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
