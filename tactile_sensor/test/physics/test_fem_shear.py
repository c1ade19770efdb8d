"""Shear load paths and modules on several faces: closed form, symmetry, antisymmetry."""

from __future__ import annotations

import numpy as np
import pytest

from tactile_sensor.physics.errors import PhysicsError
from tactile_sensor.physics.fem import SkinModel
from tactile_sensor.physics.fem.sweep import _RESIDUAL_TOL
from tactile_sensor.physics.params import PhysicsParams

FOUR = "front,back,left,right"
SMALL = dict(mesh_nx=4, mesh_ny=4, mesh_nz=16, steps=3, max_indentation=0.002, modules=FOUR)


def thin_layer(height: float) -> PhysicsParams:
    """A bonded layer 40 x 40 mm, no module, its top moved sideways by 1 % of its height."""
    return PhysicsParams(height=height, width=0.04, depth=0.04, module_height=0.0,
                         window_center_z=height / 2, max_indentation=0.0,
                         max_shear_x=0.01 * height, steps=1, mesh_nx=10, mesh_ny=10,
                         mesh_nz=4)


def simple_shear_error(height: float) -> float:
    p = thin_layer(height)
    res = SkinModel(p).sweep()
    closed_form = p.shear_modulus * 0.01 * p.width * p.depth    # 2(C10 + C01) gamma A
    return float(res.force_x_n[-1] / closed_form - 1.0)


def test_thin_bonded_layer_in_simple_shear_matches_the_closed_form():
    """Mooney-Rivlin simple shear: tau = 2(C10 + C01) gamma exactly; only the free edges
    (traction-free sides where the closed form has shear stress) differ, and their share
    shrinks with the layer's height over its width."""
    errors = [simple_shear_error(h) for h in (0.002, 0.001, 0.0005)]
    print("simple shear force error at h = 2, 1, 0.5 mm:", errors)
    assert abs(errors[0]) < 0.05
    assert abs(errors[2]) < abs(errors[1]) < abs(errors[0])


def test_quarter_half_and_full_models_agree_on_pure_indentation():
    p = PhysicsParams(**SMALL)
    results = {full: SkinModel(p, full).sweep()
               for full in ((False, False), (True, False), (False, True), (True, True))}
    quarter = results[(False, False)]
    tol_n = _RESIDUAL_TOL * p.shear_modulus * p.height**2
    for full, res in results.items():
        np.testing.assert_allclose(res.force_n, quarter.force_n, rtol=0, atol=4 * tol_n)
        for face in p.module_faces:
            np.testing.assert_allclose(res.bulges_m[face], quarter.bulges_m[face],
                                       rtol=1e-6, atol=1e-12)
        assert np.all(np.abs(res.force_x_n) < 4 * tol_n) and np.all(
            np.abs(res.force_y_n) < 4 * tol_n), full
    assert np.all(np.diff(quarter.force_n) > 0)


def test_the_model_spans_the_axes_the_probe_shears_along():
    p = PhysicsParams(**SMALL)
    assert SkinModel(p).full == (False, False)
    assert SkinModel(p.replace(max_shear_x=1e-3)).full == (True, False)
    assert SkinModel(p.replace(max_shear_y=1e-3)).full == (False, True)
    assert SkinModel(p.replace(max_shear_x=1e-3, max_shear_y=-1e-3)).full == (True, True)
    with pytest.raises(PhysicsError, match="span the axis it shears along"):
        SkinModel(p.replace(max_shear_x=1e-3), full=(False, True))


@pytest.mark.parametrize("axis", ["x", "y"])
def test_opposite_shears_mirror_every_modules_output(axis):
    """+s and -s along an axis are mirror images: each module reads what its mirror module
    read, and the face the probe moves toward bulges out while the opposite one draws in."""
    p = PhysicsParams(**SMALL)
    pure = SkinModel(p).sweep()
    shear = {sign: SkinModel(p.replace(**{f"max_shear_{axis}": sign * 1.5e-3})).sweep()
             for sign in (1, -1)}
    toward, away = ("right", "left") if axis == "x" else ("front", "back")
    mirror = {toward: away, away: toward}
    tol = 1e-6 * np.abs(pure.bulge_m).max()
    for face in p.module_faces:
        np.testing.assert_allclose(shear[1].bulges_m[face],
                                   shear[-1].bulges_m[mirror.get(face, face)], atol=tol)
    change = {face: shear[1].bulges_m[face][-1] - pure.bulges_m[face][-1]
              for face in p.module_faces}
    assert change[toward] > 0 > change[away]
    lateral = shear[1].force_x_n if axis == "x" else shear[1].force_y_n
    mirrored = shear[-1].force_x_n if axis == "x" else shear[-1].force_y_n
    assert np.all(lateral[1:] > 0)           # the probe pushes the skin along its motion
    np.testing.assert_allclose(lateral, -mirrored, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(shear[1].force_n, shear[-1].force_n, rtol=1e-6)


def test_the_default_single_module_mesh_and_windows_are_unchanged():
    """Only front/back windows by default: the side walls stay clamped and the x axis keeps
    the front window's edge (the curve physics.yaml pins)."""
    p = PhysicsParams()
    assert p.window_faces == ("front", "back")
    model = SkinModel(p)
    assert model.full == (False, False)
    assert list(model._patches) == ["front"]
    x, y = np.unique(model.mesh.p[0]), np.unique(model.mesh.p[1])
    assert p.window_width / 2 in x and p.window_width / 2 not in y
    four = SkinModel(p.replace(modules="right,front"))
    assert list(four._patches) == ["front", "right"]
    assert p.window_width / 2 in np.unique(four.mesh.p[1])


def test_a_side_window_too_fine_for_the_mesh_is_refused():
    with pytest.raises(PhysicsError, match="no node inside the photoreflector window"):
        SkinModel(PhysicsParams(mesh_nx=4, mesh_ny=4, mesh_nz=8, mesh_grading=1.0,
                                modules="left"))
