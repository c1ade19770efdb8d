"""The prediction curve (interpolation, calibration, file form) and its on-disk cache.

Cache tests run real, coarse FEM sweeps with the 'frictionless' boundary (homogeneous
compression: converges in a fraction of a second on any mesh); one bonded sweep on a coarse
mesh that still resolves the photoreflector window checks the paper's configuration.
"""

from __future__ import annotations

import json
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tactile_sensor.physics import prediction
from tactile_sensor.physics.errors import OutOfRangeError, PhysicsError
from tactile_sensor.physics.optics import Photoreflector
from tactile_sensor.physics.params import PhysicsParams
from tactile_sensor.physics.prediction import (
    ARRAYS,
    PredictionCurve,
    curve_from_sweep,
    load_or_compute_curve,
)

COARSE = dict(boundary="frictionless", mesh_nx=2, mesh_ny=2, mesh_nz=4, steps=4)
BONDED_COARSE = dict(boundary="bonded", mesh_nx=4, mesh_ny=2, mesh_nz=18, steps=6)


def synthetic(params: PhysicsParams | None = None, bulge_max_m: float = 0.3e-3
              ) -> PredictionCurve:
    """A curve from a made-up mechanical sweep (quadratic force, linear bulge)."""
    params = params or PhysicsParams()
    d = np.linspace(0.0, params.max_indentation, 7)
    force = 7.0 * (d / d[-1]) ** 1.3
    bulge = bulge_max_m * d / d[-1]
    return curve_from_sweep(params, d, force, bulge, nodes=42, seconds=1.5)


# -- the curve -------------------------------------------------------------------------------


def test_curve_from_sweep_applies_the_optics():
    params = PhysicsParams()
    curve = synthetic(params)
    assert np.allclose(curve.distance_m, params.gap - curve.bulge_m)
    assert np.allclose(curve.voltage_v, Photoreflector(75.0).voltage(curve.distance_m))
    assert curve.output_v[0] == pytest.approx(0.0, abs=1e-12)
    assert np.all(np.diff(curve.output_v) > 0)  # skin nearer -> lower V -> higher output
    assert curve.digest == params.digest()


def test_curve_from_sweep_refuses_skin_past_the_photoreflector():
    with pytest.raises(PhysicsError, match="increase 'gap'"):
        synthetic(PhysicsParams(gap=0.2e-3), bulge_max_m=0.3e-3)


@settings(max_examples=40, deadline=None)
@given(depth=st.floats(0.0, 3e-3))
def test_at_interpolates_linearly_between_steps(depth):
    curve = synthetic()
    points = curve.at(depth)
    i = min(int(np.searchsorted(curve.indentation_m, depth, side="right")) - 1,
            curve.indentation_m.size - 2)
    d0, d1 = curve.indentation_m[i], curve.indentation_m[i + 1]
    w = (depth - d0) / (d1 - d0)
    for name in ARRAYS:
        values = getattr(curve, name)
        expected = (1 - w) * values[i] + w * values[i + 1]
        assert getattr(points, name)[0] == pytest.approx(expected, rel=1e-9, abs=1e-15)


def test_at_hits_the_load_steps_exactly():
    curve = synthetic()
    points = curve.at(curve.indentation_m)
    for name in ARRAYS:
        assert np.array_equal(getattr(points, name), getattr(curve, name))


@pytest.mark.parametrize("bad", [-1e-4, 3.5e-3, float("nan")])
def test_at_refuses_out_of_range_naming_the_value(bad):
    curve = synthetic()
    with pytest.raises(OutOfRangeError, match=f"Indentation {bad:g} m"):
        curve.at([1e-3, bad])


def test_out_of_range_error_is_a_value_error_and_physics_error():
    with pytest.raises(ValueError):
        synthetic().at(1.0)
    assert issubclass(OutOfRangeError, PhysicsError)


def test_at_clamped_holds_the_end_values():
    curve = synthetic()
    points = curve.at_clamped(np.array([-1e-3, 0.0, 5e-3]))
    assert points.force_n.tolist() == [curve.force_n[0], curve.force_n[0], curve.force_n[-1]]
    assert points.output_v[2] == curve.output_v[-1]


def test_calibration_is_strictly_increasing_and_drops_plateaus():
    params = PhysicsParams()
    d = np.linspace(0.0, 3e-3, 6)
    bulge = np.array([0.0, 0.1, 0.1, 0.2, 0.2, 0.3]) * 1e-3  # two plateaus in the output
    curve = curve_from_sweep(params, d, 2.0 * d / 1e-3, bulge, 1, 0.0)
    output, force = curve.calibration()
    assert np.all(np.diff(output) > 0)
    assert output.size == 4
    assert force.tolist() == pytest.approx([0.0, 1.2, 3.6, 6.0])  # first of each plateau
    assert curve.force_from_output(output) == pytest.approx(force)


def test_calibration_refuses_a_flat_output():
    params = PhysicsParams()
    d = np.linspace(0.0, 3e-3, 4)
    curve = curve_from_sweep(params, d, d * 1e3, np.zeros(4), 1, 0.0)
    with pytest.raises(PhysicsError, match="cannot calibrate"):
        curve.calibration()


def test_dict_round_trip_through_json():
    curve = synthetic()
    back = PredictionCurve.from_dict(json.loads(json.dumps(curve.to_dict())))
    for name in ARRAYS:
        assert np.array_equal(getattr(back, name), getattr(curve, name))
    assert (back.nodes, back.seconds, back.digest) == (42, 1.5, curve.digest)


def _mangled(**changes: object) -> dict[str, object]:
    data = synthetic().to_dict()
    for key, value in changes.items():
        if value is None:
            del data[key]
        else:
            data[key] = value
    return data


@pytest.mark.parametrize(("data", "match"), [
    (_mangled(force_n=None), "force_n"),
    (_mangled(nodes=None), "nodes"),
    (_mangled(force_n=["a"] * 7), "could not convert"),
    (_mangled(force_n=[1.0, 2.0]), "differ in length"),
    (_mangled(indentation_m=[0.0, 1.0, 1.0, 2.0, 3.0, 4.0, 5.0]), "do not increase"),
    (_mangled(output_v=[0.0, float("nan"), 1, 2, 3, 4, 5]), "finite"),
    (_mangled(bulge_m=[[0.0]] * 7), "flat lists"),
    (_mangled(indentation_m=[0.0], force_n=[0.0], bulge_m=[0.0], distance_m=[0.0],
              voltage_v=[0.0], output_v=[0.0]), "differ in length"),
    ([1, 2, 3], "JSON object"),
    (None, "JSON object"),
])
def test_from_dict_refuses_corrupt_data(data, match):
    with pytest.raises(PhysicsError, match=match):
        PredictionCurve.from_dict(data)  # type: ignore[arg-type]


# -- real (coarse) sweeps and the cache ----------------------------------------------------------


def test_coarse_frictionless_sweep_gives_a_usable_curve(tmp_path):
    calls: list[tuple[float, str]] = []
    curve = load_or_compute_curve(PhysicsParams(**COARSE), tmp_path,
                                  lambda f, m: calls.append((f, m)))
    assert curve.indentation_m.tolist() == pytest.approx(np.linspace(0, 3e-3, 5).tolist())
    assert np.all(np.diff(curve.force_n) > 0)
    assert np.all(np.diff(curve.bulge_m) > 0)
    assert np.all(np.diff(curve.output_v) > 0)
    output, force = curve.calibration()
    assert output.size == 5 and np.all(np.diff(force) > 0)
    fractions = [f for f, _ in calls]
    assert fractions[0] == 0.0 and fractions[-1] == pytest.approx(1.0)
    assert fractions == sorted(fractions)
    assert "cache miss" in calls[0][1]


def test_frictionless_sweep_matches_closed_form_uniaxial_compression(tmp_path):
    """Sliding top and base: homogeneous compression of a nearly incompressible
    Mooney-Rivlin block, P = 2 (lam - lam^-2)(C10 + C01 / lam), lateral stretch lam^-1/2."""
    params = PhysicsParams(**COARSE)
    curve = load_or_compute_curve(params, tmp_path)
    lam = 1.0 - curve.indentation_m[1:] / params.height
    stress = -2.0 * (lam - lam**-2) * (params.c10 + params.c01 / lam)
    force = stress * params.width * params.depth
    bulge = params.depth / 2 * (lam**-0.5 - 1.0)
    assert curve.force_n[1:] == pytest.approx(force, rel=2e-3)
    assert curve.bulge_m[1:] == pytest.approx(bulge, rel=2e-3)


def test_coarse_bonded_sweep_bulges_at_the_window(tmp_path):
    """The paper's configuration (base fixed, probe bonded, module band with a window).

    Depends on physics/fem/ converging on a coarse mesh that resolves the window."""
    curve = load_or_compute_curve(PhysicsParams(**BONDED_COARSE), tmp_path)
    assert np.all(np.diff(curve.force_n) > 0)
    assert np.all(np.diff(curve.bulge_m) > 0)
    assert 0.0 < curve.bulge_m[-1] < 1e-3
    output, _ = curve.calibration()
    assert output.size == curve.output_v.size


def test_second_load_hits_the_cache(tmp_path, monkeypatch):
    params = PhysicsParams(**COARSE)
    first = load_or_compute_curve(params, tmp_path)
    assert (tmp_path / f"prediction-{params.digest()}.json").is_file()

    def no_fem(*_args: object, **_kwargs: object) -> PredictionCurve:
        raise AssertionError("the FEM ran although the curve was cached")

    monkeypatch.setattr(prediction, "compute_curve", no_fem)
    calls: list[str] = []
    start = time.perf_counter()
    again = load_or_compute_curve(params, tmp_path, lambda f, m: calls.append(m))
    assert time.perf_counter() - start < 0.1
    assert calls == []  # no progress: nothing computed
    assert np.array_equal(again.force_n, first.force_n)
    assert again.digest == params.digest()
    # a parameter that does not change the elastic curve shares the entry
    load_or_compute_curve(params.replace(prony_g=(0.2,), prony_tau=(3.0,)), tmp_path)


def test_different_params_miss_the_cache(tmp_path, monkeypatch):
    params = PhysicsParams(**COARSE)
    load_or_compute_curve(params, tmp_path)
    computed: list[str] = []
    real = prediction.compute_curve

    def counting(p: PhysicsParams, progress: object = None) -> PredictionCurve:
        computed.append(p.digest())
        return real(p, progress)  # type: ignore[arg-type]

    monkeypatch.setattr(prediction, "compute_curve", counting)
    other = params.replace(gap=0.0025)
    curve = load_or_compute_curve(other, tmp_path)
    assert computed == [other.digest()]
    assert curve.distance_m[0] == pytest.approx(0.0025)
    assert len(list(tmp_path.glob("prediction-*.json"))) == 2


@pytest.mark.parametrize("content", [b"{not json", b"\xff\xfe\x00garbage", b"[1, 2]",
                                     b'{"indentation_m": [0, 1]}'])
def test_corrupt_cache_file_is_recomputed_and_replaced(tmp_path, content):
    params = PhysicsParams(**COARSE)
    path = tmp_path / f"prediction-{params.digest()}.json"
    path.write_bytes(content)
    calls: list[str] = []
    curve = load_or_compute_curve(params, tmp_path, lambda f, m: calls.append(m))
    assert calls and "cache miss" in calls[0]
    stored = PredictionCurve.from_dict(json.loads(path.read_text()))
    assert np.array_equal(stored.force_n, curve.force_n)
    assert not list(tmp_path.glob(".prediction-*.tmp"))  # no temporary left behind


def test_two_solvers_missing_one_entry_solve_it_once(tmp_path):
    """The second waits on the entry's lock while the first solves, then reads its file (flock
    excludes two open files of one process as it does two processes)."""
    path = tmp_path / "entry.json"
    solved: list[str] = []
    first_solving, second_missed, release = (threading.Event(), threading.Event(),
                                             threading.Event())

    def cached() -> str | None:
        if threading.current_thread().name == "second":
            second_missed.set()
        return path.read_text() if path.is_file() else None

    def compute() -> str:
        solved.append(threading.current_thread().name)
        if threading.current_thread().name == "first":
            first_solving.set()
            assert release.wait(timeout=60)
        return threading.current_thread().name

    results: dict[str, str] = {}

    def solve() -> None:
        name = threading.current_thread().name
        results[name] = prediction.load_or_compute(path, cached, compute, path.write_text,
                                                   None, "miss")

    first = threading.Thread(target=solve, name="first")
    first.start()
    assert first_solving.wait(timeout=60)
    second = threading.Thread(target=solve, name="second")
    second.start()
    assert second_missed.wait(timeout=60)  # the second found no entry before the first ended
    release.set()
    first.join(timeout=60)
    second.join(timeout=60)
    assert solved == ["first"]
    assert results == {"first": "first", "second": "first"}


def test_unwritable_cache_still_returns_the_curve(tmp_path):
    blocker = tmp_path / "not-a-folder"
    blocker.write_text("a file where the cache folder should be")
    curve = load_or_compute_curve(PhysicsParams(**COARSE), blocker / "cache")
    assert curve.force_n[-1] > 0


def test_default_cache_dir_follows_xdg(monkeypatch, tmp_path):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert prediction.default_cache_dir() == Path(tmp_path) / "tactile_sensor"


# -- shear and several modules -----------------------------------------------------------------


def test_a_file_from_before_shear_loads_with_zero_shear_and_the_front_module():
    data = synthetic().to_dict()
    for key in ("shear_x_m", "shear_y_m", "force_x_n", "force_y_n", "module_bulges_m",
                "module_outputs_v"):
        del data[key]
    curve = PredictionCurve.from_dict(data)
    assert np.all(curve.force_x_n == 0) and np.all(curve.shear_y_m == 0)
    assert list(curve.module_outputs_v) == ["front"]
    np.testing.assert_array_equal(curve.module_outputs_v["front"], curve.output_v)


def test_module_outputs_round_trip_and_bad_ones_are_refused():
    from tactile_sensor.physics.fem import SkinModel

    params = PhysicsParams(mesh_nx=4, mesh_ny=4, mesh_nz=16, steps=2, max_indentation=0.001,
                           max_shear_y=-0.001, modules="front,back")
    res = SkinModel(params).sweep()
    curve = curve_from_sweep(params, res.indentation_m, res.force_n, res.bulge_m, res.nodes,
                             res.seconds, res)
    assert curve.module_outputs_v["back"][-1] > curve.module_outputs_v["front"][-1]
    assert curve.force_y_n[-1] < 0
    back = PredictionCurve.from_dict(json.loads(json.dumps(curve.to_dict())))
    for face in ("front", "back"):
        np.testing.assert_array_equal(back.module_outputs_v[face], curve.module_outputs_v[face])
    np.testing.assert_array_equal(back.force_y_n, curve.force_y_n)
    data = curve.to_dict()
    data["module_outputs_v"]["back"] = data["module_outputs_v"]["back"][:-1]
    with pytest.raises(PhysicsError, match="differ in length"):
        PredictionCurve.from_dict(data)
    data["module_outputs_v"] = [1, 2]
    with pytest.raises(PhysicsError, match="lacks or mangles"):
        PredictionCurve.from_dict(data)


def test_a_curve_needs_an_indentation():
    params = PhysicsParams(max_indentation=0.0, max_shear_x=1e-3)
    with pytest.raises(PhysicsError, match="needs max_indentation > 0"):
        prediction.compute_curve(params)
