"""Torque load paths (twist, tilt), the probe's reaction torque, off-centre windows and which
wrench components a layout observes."""

from __future__ import annotations

import itertools
import json

import numpy as np
import pytest

from tactile_sensor.physics.array_grid import face_image, symmetries
from tactile_sensor.physics.cli import main
from tactile_sensor.physics.errors import PhysicsError
from tactile_sensor.physics.fem import SkinModel, SweepResult, rotation_matrix
from tactile_sensor.physics.observability import (
    OBSERVE_SNR,
    distinct_output,
    full_scale,
    wrench_matrix,
    wrench_metrics,
)
from tactile_sensor.physics.params import PhysicsParams
from tactile_sensor.physics.prediction import (
    ROTATION_ARRAYS,
    PredictionCurve,
    cache_path,
    cached_curve,
    curve_from_sweep,
    store_curve,
)
from tactile_sensor.physics.wrench import (
    WRENCH_AXES,
    WrenchSet,
    compute_wrench_set,
    map_wrench,
    wrench_paths,
)
from tactile_sensor.studies.report import wrench_finding, wrench_lines, write_results
from tactile_sensor.studies.run import DesignRow, run_study
from tactile_sensor.studies.spec import parse_spec

FOUR = "front,back,left,right"
SMALL = dict(mesh_nx=3, mesh_ny=3, mesh_nz=8, steps=2, max_indentation=0.002, modules=FOUR)
OFFSET = 0.0055
EIGHT = ",".join(f"{f}@{s * OFFSET}" for f in ("front", "back", "left", "right")
                 for s in (-1, 1))


def test_rotation_matrix_is_a_right_handed_rotation():
    r = rotation_matrix(np.array([0.0, 0.0, np.pi / 2]))
    np.testing.assert_allclose(r @ [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], atol=1e-12)
    r = rotation_matrix(np.array([0.3, -0.2, 0.5]))
    np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(r) == pytest.approx(1.0)


@pytest.mark.parametrize("turn", [{"max_twist_z": 0.3}, {"max_tilt_x": 0.15},
                                  {"max_tilt_y": -0.15},
                                  {"max_tilt_x": 0.1, "max_twist_z": -0.2}])
def test_a_rigid_probe_motion_of_the_whole_block_stores_no_energy(turn):
    """The prescription is rigid: moving every node with the probe leaves the block
    unstrained, so the internal forces, the reaction and its torque vanish."""
    p = PhysicsParams(**{**SMALL, "max_shear_x": 0.001, **turn})
    model = SkinModel(p)
    u = model.probe_motion(model.mesh.p, 1.0).ravel()
    x = model.mesh.p.T + u.reshape(-1, 3)
    pairs = np.array(list(itertools.combinations(range(0, model.nodes, 37), 2)))
    before = np.linalg.norm(model.mesh.p.T[pairs[:, 0]] - model.mesh.p.T[pairs[:, 1]], axis=1)
    after = np.linalg.norm(x[pairs[:, 0]] - x[pairs[:, 1]], axis=1)
    np.testing.assert_allclose(after, before, rtol=1e-12, atol=1e-15)
    fint = model._internal_force(u)
    scale = p.shear_modulus * p.width * p.depth * 0.01      # 1 % strain's force [N]
    assert np.abs(fint).max() < 1e-8 * scale
    assert np.abs(model.probe_torque(fint, u, 1.0)).max() < 1e-8 * scale * p.height
    # the probe's own nodes are what _prescribe sets
    prescribed = np.zeros(model.ndof)
    model._prescribe(prescribed, 1.0)
    top = model._top
    np.testing.assert_allclose(prescribed.reshape(-1, 3)[top], u.reshape(-1, 3)[top])


@pytest.mark.parametrize("name, axis", [("max_twist_z", 2), ("max_tilt_x", 0),
                                        ("max_tilt_y", 1)])
def test_the_reaction_torque_follows_the_right_hand_rule(name, axis):
    """Turning the probe by +angle about an axis gives a torque on the skin along that
    axis' + direction, -angle the opposite, and the other two components vanish."""
    torques = {}
    for sign in (1, -1):
        p = PhysicsParams(**{**SMALL, name: sign * 0.1})
        res = SkinModel(p).sweep()
        torques[sign] = res.torque_nm[-1]
        assert res.rotation_rad[-1, axis] == pytest.approx(sign * 0.1)
    assert torques[1][axis] > 0 > torques[-1][axis]
    np.testing.assert_allclose(torques[-1][axis], -torques[1][axis], rtol=1e-5)
    others = [k for k in range(3) if k != axis]
    assert np.abs(torques[1][others]).max() < 1e-6 * torques[1][axis]


def test_a_small_twist_of_a_block_without_module_matches_saint_venant_torsion():
    """Twist without indentation, no module: T ~ mu beta a^4 theta / H for a square
    section (beta = 0.1406); the bonded ends stop warping, so the FEM reads a little stiffer
    (and the coarse mesh more)."""
    theta = 0.01
    p = PhysicsParams(module_height=0.0, max_indentation=0.0, max_twist_z=theta, steps=1,
                      mesh_nx=4, mesh_ny=4, mesh_nz=8)
    res = SkinModel(p).sweep()
    closed = p.shear_modulus * 0.1406 * p.width**4 * theta / p.height
    ratio = res.torque_nm[-1, 2] / closed
    print("twist torque / Saint-Venant:", ratio)
    assert 1.0 < ratio < 1.3


LAYER_SIDE = 0.04                                   # a [m]
LAYER_HEIGHTS = (0.002, 0.001, 0.0005)              # H [m]: H / a = 1/20, 1/40, 1/80


def thin_layer(height: float, mesh: tuple[int, int, int], **load: float) -> PhysicsParams:
    """A bonded square layer a x a x H without module, loaded by ``load`` in one step."""
    return PhysicsParams(height=height, width=LAYER_SIDE, depth=LAYER_SIDE, module_height=0.0,
                         window_center_z=height / 2, steps=1, mesh_nx=mesh[0],
                         mesh_ny=mesh[1], mesh_nz=mesh[2], **load)


def thin_layer_twist_ratio(height: float, mesh: tuple[int, int, int] = (10, 10, 4)) -> float:
    """FEM / closed form of a thin layer twisted by 1 % shear at its edges' midpoints."""
    theta = 0.01 * height / (LAYER_SIDE / 2)
    p = thin_layer(height, mesh, max_indentation=0.0, max_twist_z=theta)
    torque = SkinModel(p).sweep().torque_nm[-1]
    closed = p.shear_modulus * theta * LAYER_SIDE**4 / (6 * height)
    assert np.abs(torque[:2]).max() < 1e-6 * torque[2]
    return float(torque[2] / closed)


def test_a_thin_bonded_layer_twists_with_the_polar_moment_of_its_square():
    """Bonded faces stop the section warping in a thin layer, so each point shears by
    r theta / H and T = mu theta J / H with the square's polar moment J = a^4 / 6. Only
    the free edges differ (the closed form's shear stress crosses them): a layer of width
    ~H whose share falls with H / a, the same edge effect as in simple shear. The
    10 x 10 x 4 mesh (per quarter) under-resolves that layer and reads it smaller than a
    20 x 20 x 8 one (-0.77, -0.23, -0.05 %), both well inside the 0.5 % tolerance."""
    ratios = [thin_layer_twist_ratio(h) for h in LAYER_HEIGHTS]
    print("twist torque / mu theta a^4 / (6 H) at H = 2, 1, 0.5 mm:", ratios)
    errors = [abs(r - 1.0) for r in ratios]
    assert all(r < 1.0 for r in ratios)             # free edges only soften
    assert errors[0] > errors[1] > errors[2]
    assert errors[2] < 0.005


def bonded_layer_tilt_moment(mu: float, bulk: float, side: float, height: float,
                             theta: float, terms: int = 1000) -> float:
    """Moment [N m] of a thin bonded square layer whose top turns by theta about a centre
    line: lubrication theory of a bonded layer (as Gent & Meinecke 1970 for incompressible
    blocks, here with the bulk modulus K).

    The faces are bonded, so the lateral displacement is parabolic through the thickness,
    its mean u = -(H^2 / 12 mu) grad p; the mean pressure p = K (delta / H - div u) with the
    thinning delta = theta y. Hence p - l^2 lap p = K theta y / H, l^2 = K H^2 / (12 mu),
    p = 0 on the free edges; on the square [0, a]^2 a double sine series solves it (y - a/2
    has the coefficients -8a / (m n pi^2), m odd, n even). The normal stress is
    (1 - 2 mu / 3K) p + 2 mu delta / H, so M = (1 - 2 mu / 3K) int p y dA + 2 mu theta I / H,
    I = a^4 / 12. Limits: l << a gives uniaxial strain, (K + 4 mu / 3) theta I / H; l >> a
    the incompressible block, mu theta a^5 / (60 H^3) per unit depth for a long strip.
    Error O(H / a): the edge layer where the pressure drops to zero. The series, cut after
    ``terms`` terms per axis, reads ~0.1 % low when l << a, far less at the tests' l."""
    ell2 = bulk * height**2 / (12 * mu)
    m = np.arange(1, 2 * terms, 2)[:, None]
    n = np.arange(2, 2 * terms + 1, 2)[None, :]
    coefficients = (8 * side / (m * n * np.pi**2)) ** 2
    decay = 1.0 + ell2 * np.pi**2 * (m**2 + n**2) / side**2
    pressure = bulk * theta / height * side**2 / 4 * np.sum(coefficients / decay)
    return float((1 - 2 * mu / (3 * bulk)) * pressure + 2 * mu * theta * side**4 / (12 * height))


def test_the_tilt_series_reaches_its_uniaxial_and_incompressible_limits():
    mu, a, theta = 1e4, 0.04, 1e-3
    h = 1e-6                                                    # l << a: uniaxial strain
    assert bonded_layer_tilt_moment(mu, 10 * mu, a, h, theta) == pytest.approx(
        (10 + 4 / 3) * mu * theta * a**4 / 12 / h, rel=2e-3)
    # l >> a: the incompressible block, whose pressure's moment grows as 1 / H^3 (Gent &
    # Meinecke); the shear stress' 2 mu theta I / H comes on top
    thick, thin = (bonded_layer_tilt_moment(mu, 1e9 * mu, a, h, theta)
                   - 2 * mu * theta * a**4 / (12 * h) for h in (2e-3, 1e-3))
    assert thin / thick == pytest.approx(8.0, rel=1e-3)


def thin_layer_tilt_ratio(height: float, mesh: tuple[int, int, int] = (10, 10, 16)) -> float:
    """FEM / lubrication theory of a thin layer tilted about x by 0.1 % strain at its edge,
    pressed as deep as the tilt lifts it (the least the probe may press)."""
    theta = 0.001 * height / (LAYER_SIDE / 2)
    p = thin_layer(height, mesh, max_indentation=theta * LAYER_SIDE / 2, max_tilt_x=theta)
    torque = SkinModel(p).sweep().torque_nm[-1]
    closed = bonded_layer_tilt_moment(p.shear_modulus, p.bulk_modulus, LAYER_SIDE, height,
                                      theta)
    return float(torque[0] / closed)


def test_a_thin_bonded_layer_tilts_as_lubrication_theory_says():
    """Tilt of the default, nearly incompressible material (K = 1000 mu): l / a = 0.46, 0.23,
    0.11 from the thickest to the thinnest layer, so the layer passes from the
    incompressible block toward uniaxial strain (the closed form is 5 %, 17 % and 39 % of
    (K + 4 mu / 3) theta I / H). The top turns by 0.1 % strain at its edge, pressed as deep
    as the tilt lifts it. The parabolic lateral flow needs elements through the thickness
    (4 read 13 % stiff at H / a = 1/20, 8 read 7 %, 16 read 6 %); a 20 x 20 x 16 mesh reads
    1.046, 1.021, 1.012. A sign or a factor 2 off fails by far."""
    ratios = [thin_layer_tilt_ratio(h) for h in LAYER_HEIGHTS]
    print("tilt torque / lubrication theory at H = 2, 1, 0.5 mm:", ratios)
    errors = [abs(r - 1.0) for r in ratios]
    assert errors[0] > errors[1] > errors[2]
    assert errors[2] < 0.03


def test_a_tilt_about_x_on_the_full_model_has_no_other_torque():
    """The tilt's model spans y only, where Ty and Tz vanish by the mirror; the full block
    must find them zero on its own."""
    p = PhysicsParams(**{**SMALL, "max_tilt_x": 0.1})
    torque = SkinModel(p, (True, True)).sweep().torque_nm[-1]
    assert torque[0] > 0
    assert np.abs(torque[1:]).max() < 1e-6 * torque[0]


def test_torques_of_symmetric_models_cancel_where_a_mirror_copy_would():
    p = PhysicsParams(**{**SMALL, "max_shear_x": 0.001})
    res = SkinModel(p).sweep()                        # half model, spans x
    assert SkinModel(p).full == (True, False)
    assert res.torque_nm[-1, 1] != 0                  # Ty: the pressure's moment under shear
    assert res.torque_nm[-1, 0] == 0 and res.torque_nm[-1, 2] == 0


def test_rotations_span_the_model_they_break_the_symmetry_of():
    assert SkinModel(PhysicsParams(**{**SMALL, "max_tilt_x": 0.05})).full == (False, True)
    assert SkinModel(PhysicsParams(**{**SMALL, "max_tilt_y": 0.05})).full == (True, False)
    assert SkinModel(PhysicsParams(**{**SMALL, "max_twist_z": 0.05})).full == (True, True)
    with pytest.raises(PhysicsError, match=r"full=\(True, True\)"):
        SkinModel(PhysicsParams(**{**SMALL, "max_twist_z": 0.05}), full=(True, False))


@pytest.mark.parametrize("bad, match", [
    ({"max_twist_z": 1.5}, "'max_twist_z' is 1.5 but must be <= 1.0 rad"),
    ({"max_tilt_x": float("nan")}, "'max_tilt_x' must be a finite number"),
    ({"max_tilt_y": -0.6}, "'max_tilt_y' is -0.6 but must be >= -0.5 rad"),
    ({"max_tilt_x": 0.3}, "'max_tilt_x' lifts the probe's edge 3.3 mm"),
    ({"max_tilt_y": 0.01, "max_indentation": 0.0}, "'max_tilt_y' lifts the probe's edge"),
    ({"max_twist_z": 0.1, "boundary": "frictionless", "module_height": 0.0},
     "need the bonded boundary"),
    ({"max_twist_z": "a lot"}, "'max_twist_z' must be a float"),
    ({"wrench_twist": 0.0}, "'wrench_twist' is 0.0 but must be > 0.0 rad"),
    ({"wrench_tilt": 0.6}, "'wrench_tilt' is 0.6 but must be <= 0.5 rad"),
])
def test_bad_rotation_values_are_one_sentence_naming_the_parameter(bad, match):
    with pytest.raises(PhysicsError, match=match) as info:
        PhysicsParams.from_mapping(bad)
    assert str(info.value).count(". ") == 0


def test_a_pure_twist_is_a_load_path():
    p = PhysicsParams(max_indentation=0.0, max_twist_z=0.1)
    assert p.is_rotation and not p.is_shear


def test_wrench_tilt_that_lifts_the_probe_is_refused_before_solving():
    p = PhysicsParams(wrench_tilt=0.4)
    with pytest.raises(PhysicsError, match=r"'wrench_tilt' .* lower wrench_tilt below 0.273"):
        wrench_paths(p)


# -- the torque in the sweep JSON -----------------------------------------------------------

SWEEP = ["--set", "mesh_nx=4", "mesh_ny=4", "mesh_nz=16", "max_indentation=0.002", "steps=2"]
#: What 'model sweep --json' writes for a load path without rotation.
PLAIN_KEYS = {"indentation_m", "force_n", "bulge_m", "distance_m", "voltage_v", "output_v",
              "shear_x_m", "shear_y_m", "force_x_n", "force_y_n", "module_bulges_m",
              "module_outputs_v", "module_tangents_m", "nodes", "seconds", "digest",
              "params"}


def test_a_twisting_sweep_writes_the_torque_along_the_path(capsys, tmp_path):
    """Negative twist, so a sign lost to abs() or to a flipped axis shows."""
    path = tmp_path / "twist.json"
    code = main(["sweep", *SWEEP, "max_twist_z=-0.1", "--json", str(path), "--cache-dir",
                 str(tmp_path / "cache")])
    out, err = capsys.readouterr()
    assert code == 0, err
    data = json.loads(path.read_text())
    assert set(data) == PLAIN_KEYS | set(ROTATION_ARRAYS)
    assert data["twist_z_rad"] == pytest.approx([0.0, -0.05, -0.1])
    assert data["tilt_x_rad"] == data["tilt_y_rad"] == [0.0] * 3
    tz = data["torque_z_nm"]
    assert len(tz) == len(data["torque_x_nm"]) == len(data["indentation_m"]) == 3
    assert tz[2] < tz[1] < 0                         # along the probe's own rotation
    assert max(map(abs, data["torque_x_nm"] + data["torque_y_nm"])) < 1e-6 * abs(tz[2])
    assert "rotation        (0.0000, 0.0000, -0.1000) rad, torque" in out


def test_a_sweep_without_rotation_writes_what_it_wrote_before(capsys, tmp_path):
    path = tmp_path / "press.json"
    code = main(["sweep", *SWEEP, "--json", str(path), "--cache-dir", str(tmp_path)])
    out, err = capsys.readouterr()
    assert code == 0, err
    assert set(json.loads(path.read_text())) == PLAIN_KEYS
    assert "torque" not in out


def twisting_curve(params: PhysicsParams) -> PredictionCurve:
    """A prediction curve from a made-up two-step sweep whose torque columns differ."""
    steps = np.array([0.0, 1.0])
    rotation = np.outer(steps, [params.max_tilt_x, params.max_tilt_y, params.max_twist_z])
    torque = np.outer(steps, [1e-3, -2e-3, 3e-3])
    zero = np.zeros(2)
    sweep = SweepResult(steps * params.max_indentation, steps, steps * 1e-5, 100, 1.0, zero,
                        zero, zero, zero, {"front": steps * 1e-5}, rotation, torque,
                        {"front": zero})
    return curve_from_sweep(params, sweep.indentation_m, sweep.force_n, sweep.bulge_m,
                            sweep.nodes, sweep.seconds, sweep)


def test_the_curve_keeps_each_torque_column_under_its_name(tmp_path):
    p = PhysicsParams(max_indentation=0.002, max_tilt_y=0.05, max_twist_z=0.2)
    curve = twisting_curve(p)
    assert curve.rotates
    np.testing.assert_allclose(curve.tilt_y_rad, [0.0, 0.05])
    np.testing.assert_allclose(curve.twist_z_rad, [0.0, 0.2])
    np.testing.assert_allclose([curve.torque_x_nm[-1], curve.torque_y_nm[-1],
                                curve.torque_z_nm[-1]], [1e-3, -2e-3, 3e-3])
    store_curve(p, curve, tmp_path)
    again = cached_curve(p, tmp_path)
    assert again is not None
    for name in ROTATION_ARRAYS:
        np.testing.assert_array_equal(getattr(again, name), getattr(curve, name))


def test_a_cached_rotating_curve_from_before_the_torque_is_recomputed(tmp_path):
    """Old cache entries lack the rotation: read as none, they would report zero torque."""
    p = PhysicsParams(max_indentation=0.002, max_twist_z=0.2)
    old = twisting_curve(p).to_dict()
    for name in ROTATION_ARRAYS:
        del old[name]
    cache_path(p, tmp_path).write_text(json.dumps(old))
    assert cached_curve(p, tmp_path) is None
    # the same file for a path without rotation is still good, and has no torque
    plain = PhysicsParams(max_indentation=0.002)
    cache_path(plain, tmp_path).write_text(json.dumps(old))
    curve = cached_curve(plain, tmp_path)
    assert curve is not None and not curve.rotates
    assert not np.any(curve.torque_z_nm) and set(curve.to_dict()) == PLAIN_KEYS - {"params"}


def test_a_prediction_file_with_a_short_torque_list_is_refused(tmp_path):
    data = twisting_curve(PhysicsParams(max_indentation=0.002, max_twist_z=0.2)).to_dict()
    data["torque_z_nm"] = data["torque_z_nm"][:1]
    with pytest.raises(PhysicsError, match="differ in length"):
        PredictionCurve.from_dict(data)


# -- module windows off the face's centre ------------------------------------------------------


def test_modules_name_a_face_and_an_offset_in_one_spelling():
    p = PhysicsParams(modules="right@-0.004, front@0.005,front@-5e-3")
    assert p.modules == "front@-0.005,front@0.005,right@-0.004"
    assert p.module_windows == (("front", -0.005), ("front", 0.005), ("right", -0.004))
    assert ("back", 0.005) in p.windows and ("left", -0.004) in p.windows
    assert PhysicsParams(modules="front@0,back").modules == "front,back"
    assert PhysicsParams(modules=FOUR).modules == FOUR
    assert PhysicsParams(modules=FOUR).digest() == PhysicsParams(modules=FOUR).digest()


@pytest.mark.parametrize("modules, match", [
    ("front@", "Parameter 'modules' is 'front@'"),
    ("front@abc", "FACE@OFFSET"),
    ("top@0.001", "distinct faces"),
    ("front@0.001,front@1e-3", "distinct faces"),
    ("front@0.008", "window of module 'front@0.008' reaches past its face's edge"),
    ("front@0.002,front@-0.002", "'front@-0.002' and 'front@0.002' overlap"),
])
def test_bad_module_offsets_are_one_sentence(modules, match):
    with pytest.raises(PhysicsError, match=match):
        PhysicsParams(modules=modules)


def test_off_centre_windows_set_the_mesh_and_the_symmetry():
    p = PhysicsParams(**{**SMALL, "modules": "front@0.005"})
    assert not p.mirror_symmetric(0) and p.mirror_symmetric(1)
    model = SkinModel(p)
    assert model.full == (True, False)
    xs = np.unique(model.mesh.p[0])
    for edge in (0.005 - 0.0045, 0.005 + 0.0045, -0.0005, -0.0095):
        assert np.isclose(xs, edge, atol=1e-12).any()
    # a symmetric pair keeps the quarter model and reads alike in it and in the full one
    q = PhysicsParams(**{**SMALL, "modules": "front@-0.005,front@0.005"})
    quarter, full = SkinModel(q).sweep(), SkinModel(q, (True, True)).sweep()
    assert SkinModel(q).full == (False, False)
    for name in q.module_faces:
        np.testing.assert_allclose(quarter.bulges_m[name], full.bulges_m[name], rtol=1e-5)


def test_module_images_move_offsets_with_the_map():
    swap = np.array([[0.0, 1.0], [1.0, 0.0]])
    assert face_image(np.diag([-1.0, 1.0]), "front@0.005") == "front@-0.005"
    assert face_image(np.diag([1.0, -1.0]), "front@0.005") == "back@0.005"
    assert face_image(swap, "front@0.005") == "right@0.005"
    assert face_image(swap, "left@-0.004") == "back@-0.004"
    eight = PhysicsParams(modules=EIGHT)
    assert len(symmetries(eight)) == 8
    one = symmetries(PhysicsParams(modules="front@0.005"))   # and back@0.005 opposite
    assert len(one) == 2 and np.allclose(one[1], np.diag([1.0, -1.0]))


def test_wrench_maps_mirror_forces_and_flip_torques_as_pseudo_vectors():
    row = np.array([[1.0, 2.0, 3.0, 4.0, 5.0, 6.0]])
    np.testing.assert_allclose(map_wrench(np.diag([-1.0, 1.0]), row),
                               [[-1.0, 2.0, 3.0, 4.0, -5.0, -6.0]])
    swap = np.array([[0.0, 1.0], [1.0, 0.0]])
    np.testing.assert_allclose(map_wrench(swap, row), [[2.0, 1.0, 3.0, -5.0, -4.0, -6.0]])


# -- observability -----------------------------------------------------------------------------


def synthetic(patterns: np.ndarray, modules: list[str]) -> WrenchSet:
    """A wrench set whose outputs are exactly patterns @ wrench over random loads."""
    rng = np.random.default_rng(3)
    wrench = rng.uniform(-1, 1, (40, 6)) * [2.0, 2.0, 7.0, 0.05, 0.05, 0.01]
    outputs = wrench @ patterns.T
    return WrenchSet(wrench, {m: outputs[:, i] for i, m in enumerate(modules)},
                     np.zeros(40, int), "x", 0.0, 1)


def test_observability_counts_directions_above_the_noise_threshold():
    s = np.zeros((4, 6))
    s[:, 2] = 0.05                                   # Fz: every module alike
    s[2:, 0] = [-0.2, 0.2]                           # Fx: left/right
    s[:2, 1] = [0.2, -0.2]                           # Fy: front/back
    s[:2, 3] = [-8.0, 8.0]                           # Tx: the same pattern as Fy
    s[:, 5] = 1e-3                                   # Tz: a whisper of Fz's pattern
    data = synthetic(s, ["front", "back", "left", "right"])
    np.testing.assert_allclose(wrench_matrix(data), s, atol=1e-12)
    m = wrench_metrics(data, 0.013)
    assert (m["observes_fx"], m["observes_fy"], m["observes_fz"]) == (1.0, 1.0, 1.0)
    assert m["observes_tx"] == m["observes_tz"] == m["observed_torques"] == 0.0
    assert m["wrench_rank"] == 3.0
    assert m["distinct_tx_v"] < 1e-9 and m["distinct_tz_v"] < 1e-9
    # a noise 100x lower resolves nothing new: Tx is Fy's pattern, Tz Fz's
    assert wrench_metrics(data, 0.013e-2)["observed_torques"] == 0.0
    # a torque pattern of its own is observed when it clears OBSERVE_SNR x noise
    s[:, 5] = [0.5, 0.5, -0.5, -0.5]
    data = synthetic(s, ["front", "back", "left", "right"])
    scale = full_scale(data)
    clear = distinct_output(wrench_matrix(data) * scale, 5)
    assert wrench_metrics(data, 0.9 * clear / OBSERVE_SNR)["observes_tz"] == 1.0
    assert wrench_metrics(data, 1.1 * clear / OBSERVE_SNR)["observes_tz"] == 0.0


def test_a_wrench_set_without_a_component_has_no_observability():
    data = synthetic(np.ones((2, 6)), ["front", "back"])
    data.wrench[:, 4] = 0.0
    with pytest.raises(PhysicsError, match="no load along one component"):
        wrench_metrics(data, 0.013)


def test_a_damaged_wrench_set_file_is_refused():
    with pytest.raises(PhysicsError, match="damaged"):
        WrenchSet.from_dict({"format": "other"})
    data = synthetic(np.ones((2, 6)), ["front", "back"]).to_dict()
    data["path"] = data["path"][:-1]
    with pytest.raises(PhysicsError, match="different lengths"):
        WrenchSet.from_dict(data)


COARSE = dict(mesh_nx=6, mesh_ny=6, mesh_nz=20, array_steps=2, array_mesh_scale=0.5,
              max_indentation=0.002, wrench_tilt=0.1, wrench_twist=0.2)


@pytest.fixture(scope="module")
def wrench_sets() -> dict[str, WrenchSet]:
    """Four centred windows and two per face off-centre, on a coarse mesh."""
    return {mods: compute_wrench_set(PhysicsParams(modules=mods, **COARSE))
            for mods in (FOUR, EIGHT)}


def test_centred_windows_cannot_tell_a_twist_from_pressing(wrench_sets):
    """Four centred windows are symmetric under a quarter turn and each mirror, so a twist
    moves all four alike (Fz's pattern) and, linearly, not at all; a tilt moves them as the
    shear along the other axis does. Only three directions are resolved."""
    data = wrench_sets[FOUR]
    assert data.paths == 4                          # y paths from x by the x = y symmetry
    scaled = wrench_matrix(data) * full_scale(data)
    tz, fz = scaled[:, 5], scaled[:, 2]
    m = wrench_metrics(data, 0.013)
    print("centred:", {k: round(v, 5) for k, v in m.items() if "singular" in k})
    assert np.linalg.norm(tz - fz * (fz @ tz) / (fz @ fz)) < 1e-3 * np.linalg.norm(fz)
    assert m["distinct_tz_v"] < 1e-3 * m["distinct_fz_v"]
    assert m["wrench_singular_value_4_v"] < 1e-6 * m["wrench_singular_value_1_v"]
    assert m["wrench_rank"] == 3.0 and m["observed_torques"] == 0.0


def test_off_centre_windows_make_the_twist_observable(wrench_sets):
    """Two windows per face give the twist a direction of its own: a singular value of the
    force and twist columns that the centred layout lacks entirely. Whether it clears the
    threshold depends on the noise: at 4 mV (threshold 12 mV) it does on this mesh."""
    data = wrench_sets[EIGHT]
    scaled = wrench_matrix(data) * full_scale(data)
    force_and_twist = np.linalg.svd(scaled[:, [0, 1, 2, 5]], compute_uv=False)
    centred = np.linalg.svd((wrench_matrix(wrench_sets[FOUR])
                             * full_scale(wrench_sets[FOUR]))[:, [0, 1, 2, 5]],
                            compute_uv=False)
    print("two per face, Fx Fy Fz Tz:", force_and_twist, "centred:", centred)
    assert force_and_twist[-1] > 0.01 * force_and_twist[0]
    assert force_and_twist[-1] > 1e6 * centred[-1]
    m = wrench_metrics(data, 0.004)
    print("two per face:", {k: round(v, 5) for k, v in m.items() if "singular" in k})
    assert m["observes_tz"] == 1.0 and m["distinct_tz_v"] > OBSERVE_SNR * 0.004
    assert m["wrench_rank"] >= 4.0
    assert wrench_metrics(wrench_sets[FOUR], 0.004)["observes_tz"] == 0.0
    # mirror pairs of one face read the twist with opposite signs
    tz = dict(zip(data.modules, scaled[:, 5], strict=True))
    assert tz[f"front@{OFFSET}"] == pytest.approx(-tz[f"front@{-OFFSET}"], rel=1e-6)
    assert abs(tz[f"front@{OFFSET}"]) > 0


# -- the study ---------------------------------------------------------------------------------


def _row(design: str, distinct: dict[str, float], observed: tuple[str, ...]) -> DesignRow:
    metrics = {"wrench_rank": float(3 + len(observed)),
               "observed_torques": float(len(observed))}
    for k in range(1, 7):
        metrics[f"wrench_singular_value_{k}_v"] = 0.1 / k
    for a in WRENCH_AXES:
        metrics[f"distinct_{a}_v"] = distinct.get(a, 0.5 if a.startswith("f") else 0.0)
        metrics[f"observes_{a}"] = float(a in observed or a.startswith("f"))
    return DesignRow(design, {"modules": design}, "d" + design, metrics)


def test_the_torque_finding_names_the_numbers_either_way():
    spec = parse_spec({"vary": {"modules": [FOUR, EIGHT]},
                       "metrics": ["wrench_observability"], "noise_v": 0.01})
    none = [_row("paper", {"tx": 0.001}, ()), _row("0", {"tz": 0.02}, ())]
    text = wrench_finding(none, spec)
    assert text.startswith("No layout within the study's bounds observes a torque")
    assert "20 mV (TZ" in text and "30 mV" in text          # 3 x 10 mV threshold
    some = [*none, _row("1", {"tz": 0.2}, ("tz",))]
    text = wrench_finding(some, spec)
    assert text.startswith("1 of 3 solved designs observe a torque") and ": TZ)" in text
    lines = wrench_lines(some, spec)
    assert lines[2].startswith("- design 1") and "observes FX, FY, FZ, TZ (4 of 6" in lines[2]


@pytest.mark.slow
def test_a_torque_study_runs_reports_and_reruns_from_the_cache(tmp_path):
    spec = parse_spec({"name": "torque", "fixed": {**COARSE, "modules": FOUR},
                       "vary": {"window_center_z": [0.003]},
                       "metrics": ["wrench_observability"]})
    assert spec.objectives == {"observed_torques": "max"}
    rows = run_study(spec, workers=1, cache_dir=tmp_path)
    assert all(r.ok for r in rows) and rows[1].metrics == rows[0].metrics
    assert rows[0].metrics["wrench_rank"] == 3.0
    out = write_results(rows, spec, tmp_path / "out", 1.0)
    report = out["report.md"].read_text()
    assert "## Torque: which wrench components each layout observes" in report
    assert "No layout within the study's bounds observes a torque" in report
    assert "observes FX, FY, FZ (3 of 6" in report
    summary = json.loads(out["summary.json"].read_text())
    assert summary["torque"].startswith("No layout")
    messages: list[str] = []
    run_study(spec, workers=1, cache_dir=tmp_path, progress=lambda _f, m: messages.append(m))
    assert any("0 to solve" in m for m in messages)
