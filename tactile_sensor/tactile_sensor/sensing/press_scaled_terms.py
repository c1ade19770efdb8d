"""Torque terms whose gain follows the press: z_j (a_j + b_j C), C the press features' sum.

Why: a torque's output pattern (a difference of modules, z_j) grows with the indentation
faster than the torque does, so a torque linear in z_j, fitted over every indentation of
the FEM's wrench paths, reads low at some depths and high at others: along the wrench
protocol (3 mm) 0.93 of the shear's torque, 0.955 of the twist's and 0.92 of the tilt's
lateral force. Letting each linear term's gain move with the press (C: the sum of the
features that no mirror flips, i.e. the faces' sums) reads 0.97-1.03 there.

Unbiased under noise, unlike a full degree 2: the noise of z_j and of C comes from
orthogonal rows of the feature matrix (different orbits, or different characters of one),
so the mean of their product is zero; only squares of one feature (the noise's variance)
would shift the mean, and no such term is used. Each b_j is one coefficient shared by the
products z_j z_c over the press features c, so two nearly equal face sums cannot take
cancelling coefficients.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np


def press_groups(terms: Sequence[Sequence[int]], parity: Sequence[tuple[int, int]]
                 ) -> list[tuple[int, tuple[int, ...]]]:
    """Per feature that some mirror flips: (index of its linear term, indices of its
    products with every press feature); an empty tuple where ``terms`` lacks them (a
    degree-1 polynomial)."""
    exponents = np.asarray(terms, dtype=int)
    features = exponents.shape[1]
    press = [c for c in range(features) if tuple(parity[c]) == (0, 0)]
    index = {tuple(row): t for t, row in enumerate(exponents.tolist())}
    groups = []
    for j in range(features):
        if j in press:
            continue
        unit = [0] * features
        unit[j] = 1
        products = []
        for c in press:
            row = list(unit)
            row[c] += 1
            if tuple(row) in index:
                products.append(index[tuple(row)])
        groups.append((index[tuple(unit)], tuple(products)))
    return groups


def fit_press_scaled(basis: np.ndarray, values: np.ndarray, keep: np.ndarray,
                     groups: list[tuple[int, tuple[int, ...]]]) -> np.ndarray:
    """Coefficients over every term (``basis``'s columns): least squares on the kept
    terms plus, for each kept linear term of ``groups``, one shared coefficient on the sum
    of its press products."""
    scaled = [(lin, prods) for lin, prods in groups if keep[lin] and prods]
    columns = [basis[:, keep]] + [basis[:, list(prods)].sum(axis=1, keepdims=True)
                                  for _, prods in scaled]
    solution = np.linalg.lstsq(np.hstack(columns), values, rcond=None)[0]
    coef = np.zeros(basis.shape[1])
    coef[keep] = solution[:int(keep.sum())]
    for (_, prods), b in zip(scaled, solution[int(keep.sum()):], strict=True):
        coef[list(prods)] = b
    return coef
