"""Six-column array calibration: torque columns fitted from few wrench points, ``observed``,
modules at offsets, the version-1 file, and the refusals."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from tactile_sensor.sensing.array_calibration import (
    COMPONENTS,
    ArrayCalibration,
    mirror_axes,
    symmetric_features,
)
from tactile_sensor.sensing.errors import CalibrationError

C = 0.0055
EIGHT = tuple(f"{face}@{c:g}" for face in ("front", "back", "left", "right")
              for c in (-C, C))


def known_outputs(w: np.ndarray) -> np.ndarray:
    """Outputs [V] of the eight modules for wrenches (n, 6) by a known, mirror-consistent
    map: each orbit's features respond to the components of their own parity, a little
    non-linearly (sums grow with the square of Fz), then the features are unmixed."""
    fx, fy, fz, tx, ty, tz = w.T
    by_parity = {   # per parity: the right/left orbit's feature, then the front/back one's
        (0, 0): [0.05 * fz + 0.002 * fz**2 + 0.01 * (fx**2 + fy**2),
                 0.045 * fz + 0.003 * fz**2],
        (1, 0): [0.08 * fx + 1.5 * ty + 0.004 * fx * fz, 0.01 * fx - 2.0 * ty],
        (0, 1): [0.01 * fy + 2.0 * tx, 0.08 * fy + 1.5 * tx + 0.004 * fy * fz],
        (1, 1): [3.0 * tz + 0.02 * fx * fy, -2.5 * tz],
    }
    matrix, parity = symmetric_features(EIGHT)
    z = np.stack([by_parity[p].pop(0) for p in parity], axis=1)
    return z @ np.linalg.inv(matrix).T


def grid_points(rng: np.random.Generator, n: int) -> np.ndarray:
    """Press and shear in every direction, no rotation: forces known, torques not."""
    fz = rng.uniform(0.0, 7.0, n)
    angle, shear = rng.uniform(0, 2 * np.pi, n), rng.uniform(0.0, 0.15, n) * fz
    return np.stack([shear * np.cos(angle), shear * np.sin(angle), fz,
                     np.zeros(n), np.zeros(n), np.zeros(n)], axis=1)


def wrench_paths(steps: int = 6) -> np.ndarray:
    """Like physics' wrench set: press, shear, tilt about x and y, twist, each to full load
    in ``steps`` steps with the indentation, and their mirror images."""
    load = np.linspace(0.0, 1.0, steps + 1)[1:, None]
    rows = [np.zeros((1, 6))]
    full = np.array([0.5, 0.5, 0.02, 0.02, 0.008])[:, None]
    for direction in np.eye(6)[[0, 1, 3, 4, 5]] * full:
        for sign in (1.0, -1.0):
            path = load * (sign * direction + np.eye(6)[2] * 7.0)
            rows.append(path)
    rows.append(load * np.eye(6)[2] * 7.0)
    return np.concatenate(rows)


def dataset(seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Outputs and (n, 6) wrenches: grid rows with NaN torque (the fit takes each component
    from the rows that have it), then the wrench paths' rows."""
    rng = np.random.default_rng(seed)
    grid, paths = grid_points(rng, 300), wrench_paths()
    outputs = known_outputs(np.concatenate([grid, paths]))
    wrench = np.concatenate([grid, paths])
    wrench[:300, 3:] = np.nan
    return outputs, wrench


def six_column(torque_noise_v: float = 0.0) -> ArrayCalibration:
    outputs, wrench = dataset()
    return ArrayCalibration.fit(EIGHT, outputs, wrench, 3, "synthetic",
                                torque_noise_v=torque_noise_v)


def test_the_eight_module_layout_is_mirror_symmetric_with_one_feature_per_parity():
    assert mirror_axes(EIGHT) == (True, True)
    matrix, parity = symmetric_features(EIGHT)
    assert sorted(parity) == [(0, 0), (0, 0), (0, 1), (0, 1), (1, 0), (1, 0), (1, 1), (1, 1)]
    assert abs(np.linalg.det(matrix)) > 1.0     # the features determine the outputs
    # the right/left orbit's twist feature: right@c - right@-c - (left@c - left@-c)
    row = matrix[parity.index((1, 1))]
    assert row.tolist() == [0, 0, 0, 0, 1, -1, -1, 1]


def test_torque_from_few_wrench_points_is_accurate_between_their_directions():
    cal = six_column()
    assert cal.observed == COMPONENTS and cal.has_torque
    rng = np.random.default_rng(7)
    # combined loads none of the fit's points had: shear at any angle with tilt and twist
    test = grid_points(rng, 200)
    test[:, 3:5] = rng.uniform(-0.02, 0.02, (200, 2))
    test[:, 5] = rng.uniform(-0.008, 0.008, 200)
    got = cal.wrenches(known_outputs(test))[:, 3:]
    error = np.sqrt(np.mean((got - test[:, 3:]) ** 2, axis=0))
    assert np.all(error / [0.04, 0.04, 0.016] < 0.03), error    # of each torque's range


def test_a_noisy_fit_keeps_the_torque_within_its_noise():
    cal = six_column(torque_noise_v=0.002)
    outputs = known_outputs(wrench_paths())
    noisy = outputs + np.random.default_rng(3).normal(0.0, 0.002, outputs.shape)
    error = cal.wrenches(noisy)[:, 3:] - wrench_paths()[:, 3:]
    assert np.sqrt(np.mean(error**2)) < 0.002     # N m: a tenth of the tilt range


def test_the_torque_keeps_its_mirror_parity():
    """Mirroring about x = 0 (right@c <-> left@c, front@c -> front@-c) flips Fx, Ty, Tz."""
    cal = six_column()
    outputs, _ = dataset(1)
    image = {f"right@{c:g}": f"left@{c:g}" for c in (-C, C)}
    image |= {v: k for k, v in image.items()}
    image |= {f"{face}@{c:g}": f"{face}@{-c:g}" for face in ("front", "back")
              for c in (-C, C)}
    mirrored = outputs[:, [EIGHT.index(image[f]) for f in EIGHT]]
    a, b = cal.wrenches(outputs), cal.wrenches(mirrored)
    np.testing.assert_allclose(b, a * [-1, 1, 1, 1, -1, -1], atol=1e-9)


def test_one_reading_equals_the_batch_path_for_all_six():
    cal = six_column()
    outputs, _ = dataset(2)
    for row in outputs[:20]:
        np.testing.assert_allclose(cal.wrench(row), cal.wrenches(row[None])[0], rtol=1e-10,
                                   atol=1e-12)


def test_unobserved_components_read_nan_and_say_why():
    outputs, wrench = dataset()
    cal = ArrayCalibration.fit(EIGHT, outputs, wrench, 3, "s",
                               observed=["fx", "fy", "fz", "tz"])
    got = cal.wrench(outputs[0])
    assert math.isnan(got[3]) and math.isnan(got[4]) and not math.isnan(got[5])
    assert cal.unobserved == ("tx", "ty")
    assert cal.unobserved_reason() == "tx, ty: the layout's modules cannot observe torque"
    forces_only = ArrayCalibration.fit(EIGHT, outputs[:300], wrench[:300, :3], 3, "s")
    assert all(math.isnan(v) for v in forces_only.wrench(outputs[0])[3:])
    assert "no torque columns" in forces_only.unobserved_reason()


def test_observed_and_the_torque_round_trip_through_the_file(tmp_path):
    outputs, wrench = dataset()
    cal = ArrayCalibration.fit(EIGHT, outputs, wrench, 3, "s", observed=["fx", "fy", "fz",
                                                                          "tz"])
    path = tmp_path / "six.json"
    cal.to_file(path)
    data = json.loads(path.read_text())
    assert data["version"] == 2 and data["observed"] == ["fx", "fy", "fz", "tz"]
    back = ArrayCalibration.from_file(path)
    assert back.observed == cal.observed and back.faces == EIGHT
    np.testing.assert_allclose(back.wrenches(outputs), cal.wrenches(outputs), rtol=1e-12,
                               atol=1e-12)


def test_a_version_1_file_still_loads_as_forces_only(tmp_path):
    outputs, wrench = dataset()
    data = ArrayCalibration.fit(EIGHT, outputs[:300], wrench[:300, :3], 3, "s").to_dict()
    for key in ("observed", "torque_x_nm", "torque_y_nm", "torque_z_nm"):
        data.pop(key, None)
    data["version"] = 1
    path = tmp_path / "v1.json"
    path.write_text(json.dumps(data))
    cal = ArrayCalibration.from_file(path)
    assert cal.observed == ("fx", "fy", "fz") and not cal.has_torque
    assert all(math.isnan(v) for v in cal.wrench(outputs[0])[3:])


@pytest.mark.parametrize("change, match", [
    ({"torque_z_nm": [1.0, 2.0]}, r"torque columns need one coefficient per term \(165\)"),
    ({"observed": ["fx", "fq"]}, "'observed' must be distinct components"),
    ({"observed": "fx"}, "'observed' must be a list"),
    ({"torque_y_nm": None}, "torque columns need one coefficient per term"),
    ({"faces": ["front@", *EIGHT[1:]]}, "'faces' must be distinct module labels"),
    ({"faces": [EIGHT[0], *EIGHT[:-1]]}, "'faces' must be distinct module labels"),
])
def test_a_damaged_six_column_file_names_the_problem(change, match):
    outputs, wrench = dataset()
    data = {**ArrayCalibration.fit(EIGHT, outputs, wrench, 3, "s").to_dict(), **change}
    with pytest.raises(CalibrationError, match=match) as info:
        ArrayCalibration.from_mapping(data, "test")
    assert str(info.value).count(". ") == 0


def test_missing_torque_or_observed_in_a_version_2_file_is_named():
    outputs, wrench = dataset()
    data = ArrayCalibration.fit(EIGHT, outputs, wrench, 3, "s").to_dict()
    del data["torque_x_nm"], data["observed"]
    with pytest.raises(CalibrationError, match="missing observed, torque_x_nm; refit it"):
        ArrayCalibration.from_mapping(data, "test")


def test_a_torque_without_data_or_points_is_refused_in_one_sentence():
    outputs, wrench = dataset()
    with pytest.raises(CalibrationError, match="Cannot fit tz: the fit data has no finite"):
        ArrayCalibration.fit(EIGHT, outputs[:300], wrench[:300], 3, "s",
                             observed=["fx", "fy", "fz", "tz"])
    few = np.concatenate([np.arange(300), [300, 301]])
    with pytest.raises(CalibrationError, match="only 2 points; lower the degree or "
                                               "add load paths"):
        ArrayCalibration.fit(EIGHT, outputs[few], wrench[few], 3, "s")


def test_reordering_keeps_every_component_and_refuses_other_modules():
    cal = six_column()
    order = [3, 1, 2, 0, 7, 6, 5, 4]
    faces = tuple(EIGHT[i] for i in order)
    moved = cal.reordered(faces)
    outputs, _ = dataset(4)
    np.testing.assert_allclose(moved.wrenches(outputs[:, order]), cal.wrenches(outputs),
                               rtol=1e-10, atol=1e-12)
    with pytest.raises(CalibrationError, match=r"is for modules front@-0\.0055, .* not front, "
                                               r"back"):
        cal.reordered(("front", "back", *EIGHT[2:]))


def tilted(w: np.ndarray) -> np.ndarray:
    """The wrenches with the lateral force a tilt adds (as the FEM's: pushing the skin
    along x when tilting about y, -40 N per N m)."""
    out = w.copy()
    out[:, 0] += -40.0 * w[:, 4]
    out[:, 1] += 40.0 * w[:, 3]
    return out


def test_the_force_a_tilt_adds_is_fitted_as_the_forces_slow_part():
    """The grid never tilts, so its force polynomial misreads a tilt's lateral force; the
    slow part, fitted on the wrench paths' forces, puts it back."""
    rng = np.random.default_rng(5)
    loads = tilted(np.concatenate([grid_points(rng, 300), wrench_paths()]))
    outputs = known_outputs(loads)
    wrench = loads.copy()
    wrench[:300, 3:] = np.nan                 # the grid: forces
    wrench[300:, :3] = np.nan                 # the wrench paths: torques (forces: slow only)
    plain = ArrayCalibration.fit(EIGHT, outputs, wrench, 3, "s")
    slow = ArrayCalibration.fit(EIGHT, outputs, wrench, 3, "s", slow_forces=loads[:, :3])
    assert slow.has_slow and not plain.has_slow
    test = grid_points(rng, 200)
    test[:, 3:5] = rng.uniform(-0.02, 0.02, (200, 2))
    test = tilted(test)
    outputs = known_outputs(test)

    def lateral_rmse(cal: ArrayCalibration) -> float:
        return float(np.sqrt(np.mean((cal.wrenches(outputs)[:, :2] - test[:, :2]) ** 2)))

    assert lateral_rmse(plain) > 0.3                       # N: the tilt's force is missed
    assert lateral_rmse(slow) < 0.1 * lateral_rmse(plain)
    back = ArrayCalibration.from_mapping(json.loads(json.dumps(slow.to_dict())), "test")
    assert back.has_slow
    np.testing.assert_allclose(back.wrenches(outputs), slow.wrenches(outputs), rtol=1e-12,
                               atol=1e-12)


def test_a_slow_part_without_torque_or_of_the_wrong_length_is_refused():
    outputs, wrench = dataset()
    data = ArrayCalibration.fit(EIGHT, outputs, wrench, 3, "s",
                                slow_forces=np.zeros((outputs.shape[0], 3))).to_dict()
    assert "force_slow_x_n" in data
    with pytest.raises(CalibrationError, match="missing force_slow_z_n; refit it"):
        ArrayCalibration.from_mapping({k: v for k, v in data.items()
                                       if k != "force_slow_z_n"}, "test")
    with pytest.raises(CalibrationError, match="slow part needs the torque columns"):
        ArrayCalibration.from_mapping({**data, "force_slow_x_n": [1.0]}, "test")
    with pytest.raises(CalibrationError, match="slow part needs the torque columns"):
        ArrayCalibration.from_mapping({k: v for k, v in data.items()
                                       if not k.startswith("torque_")}
                                      | {"observed": ["fx", "fy", "fz"]}, "test")
    with pytest.raises(CalibrationError, match="one \\(Fx, Fy, Fz\\) row per point"):
        ArrayCalibration.fit(EIGHT, outputs, wrench, 3, "s", slow_forces=np.zeros((3, 3)))
