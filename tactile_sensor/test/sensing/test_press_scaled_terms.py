"""Torque terms whose gain follows the press: the torque read with gain 1 at every depth,
and no mean offset from output noise.

A synthetic eight-module array whose torque patterns grow with the press (as the FEM's
do: the outputs stiffen with depth faster than the torque), calibrated on load paths at
every depth; the plain linear torque reads a shallow and a deep twist with different gains
and cannot read both at 1.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tactile_sensor.sensing.array_calibration import (
    ArrayCalibration,
    polynomial_terms,
    symmetric_features,
)
from tactile_sensor.sensing.press_scaled_terms import fit_press_scaled, press_groups

FACES = ("front@-0.0055", "front@0.0055", "back@-0.0055", "back@0.0055", "left@-0.0055",
         "left@0.0055", "right@-0.0055", "right@0.0055")
PRESS = 0.046                                                    # V per N of Fz, each module
#: Per N m of each torque, the modules' pattern [V]: Tx on front/back, Ty on left/right,
#: Tz each face's pair in turn.
PATTERN = np.array([[-0.6, -0.6, 0.6, 0.6, 0.1, -0.1, 0.1, -0.1],
                    [-0.1, 0.1, -0.1, 0.1, -0.6, -0.6, 0.6, 0.6],
                    [0.7, -0.7, -0.7, 0.7, 0.7, -0.7, -0.7, 0.7]])
STIFFENING = 0.06                                                # per N of Fz


def outputs_of(fz: np.ndarray, torque: np.ndarray) -> np.ndarray:
    """Outputs [V] (points, 8): the press on every module, each torque's pattern grown by
    1 / (1 - STIFFENING Fz) (1.7 times at 7 N)."""
    return PRESS * fz[:, None] + (torque @ PATTERN) / (1.0 - STIFFENING * fz[:, None])


def calibration(press_scaled: bool) -> ArrayCalibration:
    fz, torque = [], []
    for level in np.arange(1, 13) / 12 * 7.0:                   # pressed to 7 N
        for axis in range(3):
            for sense in (1.0, -1.0):
                t = np.zeros(3)
                t[axis] = sense * 0.02 * level / 7.0
                fz.append(level)
                torque.append(t)
        fz.append(level)
        torque.append(np.zeros(3))
    fz_a, torque_a = np.array(fz), np.array(torque)
    wrench = np.column_stack([np.full((fz_a.size, 2), np.nan), fz_a, torque_a])
    return ArrayCalibration.fit(FACES, outputs_of(fz_a, torque_a), wrench, 2, "synthetic",
                                torque_degree=1, torque_noise_v=0.0,
                                observed=("fz", "tx", "ty", "tz"), press_scaled=press_scaled)


def twist_gain(cal: ArrayCalibration, fz: float) -> float:
    torque = np.array([[0.0, 0.0, 0.01]])
    return float(cal.wrenches(outputs_of(np.array([fz]), torque))[0, 5] / 0.01)


def test_the_linear_torque_cannot_read_a_shallow_and_a_deep_twist_at_gain_one():
    linear = calibration(press_scaled=False)
    shallow, deep = twist_gain(linear, 1.5), twist_gain(linear, 7.0)
    assert max(abs(shallow - 1.0), abs(deep - 1.0)) > 0.1, (shallow, deep)


@settings(max_examples=20, deadline=None)
@given(fz=st.floats(1.0, 7.0))
def test_press_scaled_torque_reads_every_depth_at_gain_one(fz):
    assert abs(twist_gain(calibration(press_scaled=True), fz) - 1.0) < 0.02


def test_output_noise_leaves_no_mean_offset_on_the_press_scaled_torque():
    cal = calibration(press_scaled=True)
    clean = outputs_of(np.full(20000, 7.0), np.zeros((20000, 3)))
    noisy = clean + np.random.default_rng(3).normal(0.0, 0.013, clean.shape)
    torque = cal.wrenches(noisy)[:, 3:]
    spread = torque.std(axis=0) / np.sqrt(torque.shape[0])
    assert np.all(np.abs(torque.mean(axis=0)) < 4.0 * spread), (torque.mean(axis=0), spread)


def test_press_groups_pair_each_flipped_feature_with_the_face_sums():
    _, parity = symmetric_features(FACES)
    groups = press_groups(polynomial_terms(len(FACES), 2), parity)
    press = [k for k, p in enumerate(parity) if p == (0, 0)]
    assert len(groups) == len(parity) - len(press)
    assert all(len(products) == len(press) for _, products in groups)
    # a degree-1 polynomial has no products: the fit is the plain linear one
    assert all(products == () for _, products in press_groups(
        polynomial_terms(len(FACES), 1), parity))


def test_fit_press_scaled_without_products_is_least_squares_on_the_kept_terms():
    rng = np.random.default_rng(0)
    basis = rng.normal(size=(40, 4))
    values = basis @ np.array([1.0, -2.0, 0.0, 0.5])
    keep = np.array([True, True, False, True])
    coef = fit_press_scaled(basis, values, keep, [(0, ()), (1, ())])
    assert coef == pytest.approx([1.0, -2.0, 0.0, 0.5])
