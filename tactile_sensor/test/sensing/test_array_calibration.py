"""Array calibration: fit, apply, file round trip and every refusal."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tactile_sensor.sensing.array_calibration import (
    ArrayCalibration,
    monomial_factors,
    polynomial_terms,
)
from tactile_sensor.sensing.errors import CalibrationError

FACES = ("front", "back", "left", "right")


def synthetic(n: int = 200, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Outputs of four modules and forces that are exact quadratics of them."""
    rng = np.random.default_rng(seed)
    o = rng.uniform(0.0, 0.5, size=(n, 4))
    fx = 4.0 * (o[:, 3] - o[:, 2]) + 1.5 * (o[:, 3] ** 2 - o[:, 2] ** 2)
    fy = 4.0 * (o[:, 0] - o[:, 1])
    fz = 3.0 * o.sum(axis=1) + 2.0 * o[:, 0] * o[:, 1]
    return o, np.stack([fx, fy, fz], axis=1)


def test_terms_are_every_monomial_up_to_the_degree():
    terms = polynomial_terms(4, 3)
    assert len(terms) == 35 and terms[0] == (0, 0, 0, 0)
    assert len(set(terms)) == 35 and max(sum(t) for t in terms) == 3
    assert len(polynomial_terms(1, 2)) == 3


@settings(deadline=None)
@given(modules=st.integers(1, 8), degree=st.integers(0, 5), seed=st.integers(0, 2**32 - 1))
def test_monomials_as_products_of_their_factors_equal_the_powers(modules, degree, seed):
    terms = np.array(polynomial_terms(modules, degree))
    z = np.random.default_rng(seed).uniform(-2.0, 2.0, (7, modules))
    factors = np.concatenate([z, np.ones((7, 1))], axis=1)[:, monomial_factors(terms)]
    assert np.allclose(np.prod(factors, axis=2),
                       np.prod(z[:, None, :] ** terms[None, :, :], axis=2), rtol=1e-14, atol=0)


def test_a_fit_recovers_a_polynomial_force_exactly():
    outputs, forces = synthetic()
    cal = ArrayCalibration.fit(FACES, outputs, forces, 2, "synthetic")
    np.testing.assert_allclose(cal.forces(outputs), forces, atol=1e-9)
    single = cal.force({"right": 0.3, "left": 0.1, "front": 0.2, "back": 0.2})
    assert single[0] == pytest.approx(4.0 * 0.2 + 1.5 * (0.09 - 0.01))
    assert single[1] == pytest.approx(0.0, abs=1e-9)
    assert cal.force([0.2, 0.2, 0.1, 0.3]) == pytest.approx(single)


def test_a_degree_too_low_leaves_an_error_and_a_higher_one_removes_it():
    outputs, forces = synthetic()
    linear = ArrayCalibration.fit(FACES, outputs, forces, 1, "")
    assert np.abs(linear.forces(outputs) - forces).max() > 1e-3
    cubic = ArrayCalibration.fit(FACES, outputs, forces, 3, "")
    assert np.abs(cubic.forces(outputs) - forces).max() < 1e-8


@settings(max_examples=20, deadline=None)
@given(degree=st.integers(1, 4), seed=st.integers(0, 1000))
def test_file_round_trip_keeps_every_force(degree, seed, tmp_path_factory):
    outputs, forces = synthetic(seed=seed)
    cal = ArrayCalibration.fit(FACES, outputs, forces, degree, "synthetic")
    path = tmp_path_factory.mktemp("cal") / "array.json"
    cal.to_file(path, fit={"held_out_rmse_n": {"x": 0.1}})
    back = ArrayCalibration.from_file(path)
    assert back.faces == FACES and back.degree == degree
    assert back.source == f"file:{path} (synthetic)"
    np.testing.assert_allclose(back.forces(outputs), cal.forces(outputs), rtol=1e-12,
                               atol=1e-12)
    assert json.loads(path.read_text())["fit"]["held_out_rmse_n"]["x"] == 0.1


def collinear(n: int = 120, seed: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """Like the FEM grid: both pair sums follow one indentation and differ only slightly,
    while Fz has a part no cubic holds; a plain fit buys that part with huge cancelling
    coefficients on the sums' tiny difference."""
    rng = np.random.default_rng(seed)
    d = rng.uniform(0.0, 1.0, n)
    sx, sy = rng.uniform(-0.3, 0.3, (2, n)) * d
    base = 0.25 * d + 0.02 * d**2
    e = 0.002 * d**2
    o = np.stack([base + sy + e, base - sy + e, base - sx - e, base + sx - e], axis=1)
    return o, np.stack([6 * sx, 6 * sy, 7 * d + 3 * d**5], axis=1)


def noise_rmse(cal: ArrayCalibration, outputs: np.ndarray, forces: np.ndarray,
               sigma: float = 0.013) -> np.ndarray:
    rng = np.random.default_rng(9)
    noisy = np.concatenate([outputs + rng.normal(0, sigma, outputs.shape) for _ in range(20)])
    return np.sqrt(np.mean((cal.forces(noisy) - np.tile(forces, (20, 1))) ** 2, axis=0))


def test_a_fit_that_sees_output_noise_does_not_amplify_it():
    outputs, forces = collinear()
    plain = ArrayCalibration.fit(FACES, outputs, forces, 3, "")
    robust = ArrayCalibration.fit(FACES, outputs, forces, 3, "", noise_v=0.005)
    assert noise_rmse(plain, outputs, forces)[2] > 100.0  # kN: the failure being guarded
    assert noise_rmse(robust, outputs, forces)[2] < 0.5  # N
    # and it still fits the noise-free points closely, with the same inputs giving the same
    # calibration (fixed seed)
    assert np.sqrt(np.mean((robust.forces(outputs) - forces) ** 2)) < 0.05
    again = ArrayCalibration.fit(FACES, outputs, forces, 3, "", noise_v=0.005)
    np.testing.assert_array_equal(again.coefficients, robust.coefficients)


@pytest.mark.parametrize("noise_v", [-0.001, float("nan"), 2.0])
def test_a_bad_fit_noise_is_refused(noise_v):
    outputs, forces = synthetic()
    with pytest.raises(CalibrationError, match="output noise must be in"):
        ArrayCalibration.fit(FACES, outputs, forces, 2, "", noise_v=noise_v)


def test_in_range_flags_outputs_beyond_the_fit():
    outputs, forces = synthetic()
    cal = ArrayCalibration.fit(FACES, outputs, forces, 2, "")
    assert cal.in_range(outputs.max(axis=0))
    assert not cal.in_range(outputs.max(axis=0) * 1.2)


def test_the_full_scale_is_the_normal_force_with_every_face_at_its_fitted_maximum():
    outputs, forces = synthetic()
    cal = ArrayCalibration.fit(FACES, outputs, forces, 2, "")
    top = outputs.max(axis=0)  # faces in FACES order: front, back, left, right
    assert cal.full_scale_force_n == pytest.approx(3.0 * top.sum() + 2.0 * top[0] * top[1])


def valid() -> dict:
    outputs, forces = synthetic()
    return ArrayCalibration.fit(FACES, outputs, forces, 2, "s").to_dict()


@pytest.mark.parametrize("change, match", [
    ({"format": "x"}, "not an array calibration file"),
    ({"version": 7}, "version 7 is not supported"),
    ({"faces": ["front", "top"]}, "'faces' must be distinct"),
    ({"faces": "front"}, "'faces' must be a list"),
    ({"force_y_n": [1.0]}, "one coefficient per term"),
    ({"terms": [["a"]]}, "must be numbers"),
    ({"output_scale_v": 0.0}, "output scale > 0"),
    ({"output_max_v": [1.0]}, "one value per face"),
    ({"feature_matrix": [[1.0]]}, "must be square"),
    ({"force_z_n": None}, "one coefficient per term"),
    ({"force_z_n": "abc"}, "must be numbers"),
])
def test_bad_files_name_the_problem(change, match):
    data = {**valid(), **change}
    with pytest.raises(CalibrationError, match=match):
        ArrayCalibration.from_mapping(data, "test")


def test_missing_fields_and_non_objects_are_refused():
    data = valid()
    del data["force_x_n"]
    with pytest.raises(CalibrationError, match="missing force_x_n"):
        ArrayCalibration.from_mapping(data, "test")
    with pytest.raises(CalibrationError, match="expected a JSON object"):
        ArrayCalibration.from_mapping([1, 2], "test")


def test_file_errors_are_one_sentence(tmp_path):
    with pytest.raises(CalibrationError, match="does not exist"):
        ArrayCalibration.from_file(tmp_path / "none.json")
    bad = tmp_path / "bad.json"
    bad.write_text("{nope")
    with pytest.raises(CalibrationError, match="not valid JSON"):
        ArrayCalibration.from_file(bad)
    binary = tmp_path / "binary.json"
    binary.write_bytes(b"\xff\xfe\x00")
    with pytest.raises(CalibrationError, match="Cannot read"):
        ArrayCalibration.from_file(binary)


def test_bad_readings_and_fits_are_refused():
    outputs, forces = synthetic()
    cal = ArrayCalibration.fit(FACES, outputs, forces, 2, "")
    with pytest.raises(CalibrationError, match="No output for module"):
        cal.force({"front": 0.1})
    with pytest.raises(CalibrationError, match="outputs of 4 modules"):
        cal.forces(np.zeros((3, 2)))
    with pytest.raises(CalibrationError, match="degree must be >= 1"):
        ArrayCalibration.fit(FACES, outputs, forces, 0, "")
    with pytest.raises(CalibrationError, match="only 10 points"):
        ArrayCalibration.fit(FACES, outputs[:10], forces[:10], 3, "")
    with pytest.raises(CalibrationError, match="same points"):
        ArrayCalibration.fit(FACES, outputs, forces[:5], 2, "")


def test_features_are_pair_sums_and_differences_with_their_mirror_parity():
    from tactile_sensor.sensing.array_calibration import symmetric_features

    matrix, parity = symmetric_features(("front", "back", "left", "right"))
    assert matrix.tolist() == [[0, 0, 1, 1], [0, 0, -1, 1], [1, 1, 0, 0], [1, -1, 0, 0]]
    assert parity == [(0, 0), (1, 0), (0, 0), (0, 1)]
    matrix, parity = symmetric_features(("front", "left", "right"))
    assert matrix.tolist() == [[0, 1, 1], [0, -1, 1], [1, 0, 0]]
    assert parity == [(0, 0), (1, 0), (0, 0)]  # front has no back: no y parity to use
    matrix, parity = symmetric_features(("front", "left"))
    assert matrix.tolist() == [[1, 0], [0, 1]] and parity == [(0, 0)] * 2


def test_a_fit_is_mirror_symmetric_even_on_noisy_data():
    """Swapping left/right outputs flips Fx and keeps Fy, Fz: by construction, not by luck."""
    outputs, forces = synthetic()
    noisy = forces + np.random.default_rng(5).normal(scale=0.05, size=forces.shape)
    cal = ArrayCalibration.fit(FACES, outputs, noisy, 3, "")
    mirrored = outputs[:, [0, 1, 3, 2]]      # left <-> right
    a, b = cal.forces(outputs), cal.forces(mirrored)
    np.testing.assert_allclose(b[:, 0], -a[:, 0], atol=1e-9)
    np.testing.assert_allclose(b[:, 1:], a[:, 1:], atol=1e-9)


def test_modules_without_their_opposite_get_the_full_polynomial():
    outputs, forces = synthetic()
    cal = ArrayCalibration.fit(("front", "left"), outputs[:, [0, 2]], forces, 2, "")
    assert np.count_nonzero(cal.coefficients[0]) == len(polynomial_terms(2, 2))


def test_a_layout_symmetric_about_one_axis_keeps_that_axis_parity():
    outputs, forces = synthetic()
    cal = ArrayCalibration.fit(("front", "left", "right"), outputs[:, 1:], forces, 2, "")
    mirrored = outputs[:, [1, 3, 2]]         # left <-> right, front stays
    a, b = cal.forces(outputs[:, 1:]), cal.forces(mirrored)
    np.testing.assert_allclose(b[:, 0], -a[:, 0], atol=1e-9)
    np.testing.assert_allclose(b[:, 1:], a[:, 1:], atol=1e-9)


@settings(max_examples=30, deadline=None)
@given(st.lists(st.floats(-0.2, 0.8), min_size=4, max_size=4))
def test_one_reading_equals_the_batch_path(values):
    outputs, forces = synthetic()
    cal = ArrayCalibration.fit(FACES, outputs, forces, 3, "")
    np.testing.assert_allclose(cal.force(values), cal.forces(np.array([values]))[0],
                               rtol=1e-10, atol=1e-10)


def test_a_reading_with_the_wrong_number_of_modules_is_refused():
    outputs, forces = synthetic()
    cal = ArrayCalibration.fit(FACES, outputs, forces, 2, "")
    with pytest.raises(CalibrationError, match=r"outputs of 4 modules .* got 3"):
        cal.force([0.1, 0.2, 0.3])
