"""Tangential displacement under the windows and the graded pigment that reads it."""

from __future__ import annotations

import numpy as np
import pytest

from tactile_sensor.physics.array_grid import face_image, image_tangent
from tactile_sensor.physics.errors import PhysicsError
from tactile_sensor.physics.fem import SkinModel
from tactile_sensor.physics.optics import Photoreflector
from tactile_sensor.physics.params import PhysicsParams
from tactile_sensor.physics.prediction import module_output

OFFSET = 0.0055
EIGHT = ",".join(f"{f}@{s * OFFSET}" for f in ("front", "back", "left", "right")
                 for s in (-1, 1))
TINY = dict(mesh_nx=3, mesh_ny=3, mesh_nz=8, steps=1, modules=EIGHT)


@pytest.fixture(scope="module")
def twists() -> dict[float, object]:
    """A small pure twist either way (no indentation), on a tiny full model."""
    return {s: SkinModel(PhysicsParams(**TINY, max_indentation=0.0, max_twist_z=s * 0.02)
                         ).sweep() for s in (1.0, -1.0)}


@pytest.fixture(scope="module")
def centred_twists() -> dict[float, object]:
    """The same twists with four centred windows, which read no twist through the bulge at
    first order (a mirror maps each onto itself and reverses the twist)."""
    return {s: SkinModel(PhysicsParams(**{**TINY, "modules": "front,back,left,right"},
                                       max_indentation=0.0, max_twist_z=s * 0.02)
                         ).sweep() for s in (1.0, -1.0)}


def test_a_twist_slides_every_window_counter_clockwise(twists):
    """The probe turns counter-clockwise, dragging each side face along its tangent."""
    plus, minus = twists[1.0], twists[-1.0]
    for name in plus.tangents_m:
        assert plus.tangents_m[name][0] == 0.0
        assert plus.tangents_m[name][-1] > 0, name
        assert minus.tangents_m[name][-1] == pytest.approx(-plus.tangents_m[name][-1],
                                                           rel=0.05)


def test_a_mirror_image_reads_the_reversed_tangent_of_its_source(twists):
    """Mirroring about x = 0 turns the +twist into the -twist: module m then reads det(g) x
    the tangent its source window read, which the directly solved -twist confirms."""
    g = np.diag([-1.0, 1.0])
    plus, minus = twists[1.0], twists[-1.0]
    for name in plus.tangents_m:
        source = face_image(g.T, name)
        image = image_tangent(g, plus.tangents_m[source])
        np.testing.assert_allclose(image, minus.tangents_m[name], rtol=1e-4,
                                   atol=1e-6 * np.abs(image).max())
        np.testing.assert_allclose(plus.bulges_m[source], minus.bulges_m[name], rtol=1e-4,
                                   atol=1e-12)
    swap = np.array([[0.0, 1.0], [1.0, 0.0]])       # x = y, also a mirror
    assert image_tangent(swap, np.array([2.0]))[0] == -2.0
    assert image_tangent(np.array([[0.0, -1.0], [1.0, 0.0]]), np.array([2.0]))[0] == 2.0


def test_a_symmetric_model_gives_the_full_models_tangents():
    """In the quarter model a mirror stands in for three of four windows (and reverses
    their tangent); a centred window on a symmetry plane slides by nothing on average."""
    p = PhysicsParams(**{**TINY, "steps": 2, "max_indentation": 0.002,
                         "modules": "front@-0.005,front@0.005,left"})
    quarter, full = SkinModel(p).sweep(), SkinModel(p, (True, True)).sweep()
    assert SkinModel(p).full == (False, False)
    scale = np.abs(full.tangents_m["front@0.005"]).max()
    assert scale > 0
    for name in p.module_faces:
        np.testing.assert_allclose(quarter.tangents_m[name], full.tangents_m[name],
                                   rtol=1e-3, atol=1e-6 * scale)
    np.testing.assert_allclose(full.tangents_m["left"], 0.0, atol=1e-6 * scale)
    assert full.tangents_m["front@0.005"][-1] == pytest.approx(
        -full.tangents_m["front@-0.005"][-1], rel=1e-5)


# -- graded pigment ----------------------------------------------------------------------------


def test_no_gradient_is_todays_output_bit_for_bit():
    p = PhysicsParams()
    assert p.window_pigment_gradient == 0.0
    assert p.digest() == PhysicsParams().replace(window_pigment_gradient=0).digest()
    assert p.digest() == "fd52094d1d89acb5"           # caches written before stay valid
    graded = p.replace(window_pigment_gradient=50.0)
    assert graded.digest() != p.digest() and graded.grid_digest() != p.grid_digest()
    bulge = np.linspace(0.0, 3e-4, 7)
    tangent = np.linspace(-2e-4, 2e-4, 7)
    optics = Photoreflector(p.pigment_white, p.supply_voltage)
    today = float(optics.voltage(p.gap)) - optics.voltage(p.gap - bulge)
    np.testing.assert_array_equal(module_output(p, bulge, tangent)[2], today)
    np.testing.assert_array_equal(module_output(p, bulge)[2], today)


def test_a_graded_pigment_reads_a_twist_at_first_order(centred_twists):
    """Every window slides counter-clockwise onto darker skin: all outputs move one way,
    and the opposite twist moves them the other way by as much (to first order), where the
    uniform skin reads the twist only at second order."""
    p = PhysicsParams(**{**TINY, "modules": "front,back,left,right"}, max_indentation=0.0,
                      max_twist_z=0.02, window_pigment_gradient=50.0)

    def outputs(params: PhysicsParams, s: float) -> np.ndarray:
        r = centred_twists[s]
        return np.array([module_output(params, r.bulges_m[m][-1], r.tangents_m[m][-1])[2]
                         for m in p.module_faces])

    plain = p.replace(window_pigment_gradient=0.0)
    out = {s: outputs(p, s) for s in (1.0, -1.0)}
    uniform = {s: outputs(plain, s) for s in (1.0, -1.0)}
    assert np.all(out[1.0] < 0)            # darker skin: less light, higher voltage
    change = {s: out[s] - uniform[s] for s in out}
    assert np.all(np.abs(change[1.0] + change[-1.0]) < 0.02 * np.abs(change[1.0]))
    np.testing.assert_allclose(uniform[1.0], uniform[-1.0], rtol=0.02)   # second order
    assert np.abs(uniform[1.0]).max() < 0.1 * np.abs(change[1.0]).min()


def test_outputs_are_continuous_in_the_gradient():
    bulge, tangent = np.full(3, 2e-4), np.array([-2e-2, 3e-4, 4e-3])   # the first clamps
    base = PhysicsParams()

    def out(g: float) -> np.ndarray:
        return module_output(base.replace(window_pigment_gradient=g), bulge, tangent)[2]

    for g in (0.0, 30.0, 99.0):
        step = [np.abs(out(min(g + h, 100.0)) - out(g)).max() for h in (1e-3, 1e-6)]
        assert step[1] <= 2e-3 * step[0] + 1e-12, (g, step)    # no jump: shrinks with h
    assert not np.allclose(out(50.0), out(0.0))


def test_the_photoreflector_takes_a_white_share_per_sample():
    x = np.array([1e-3, 1.5e-3, 2e-3])
    shares = np.array([25.0, 75.0, 100.0])
    each = [float(Photoreflector(w).voltage(d)) for w, d in zip(shares, x, strict=True)]
    np.testing.assert_allclose(Photoreflector().voltage(x, shares), each, rtol=1e-15)
    with pytest.raises(PhysicsError, match=r"Pigment white share 120\.0 % must be in 0\.\.100"):
        Photoreflector().voltage(x, [75.0, 120.0, 75.0])


@pytest.mark.parametrize("bad, match", [
    (120.0, "'window_pigment_gradient' is 120.0 but must be <= 100.0 %"),
    (-1.0, "'window_pigment_gradient' is -1.0 but must be >= 0.0 %"),
    (float("nan"), "'window_pigment_gradient' must be a finite number"),
])
def test_a_bad_gradient_is_one_sentence(bad, match):
    with pytest.raises(PhysicsError, match=match) as info:
        PhysicsParams(window_pigment_gradient=bad)
    assert str(info.value).count(". ") == 0
