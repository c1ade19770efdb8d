"""The default prediction against reference values of an earlier solver (default mesh).

Making the solver faster (ordering, factorisation, Krylov tuning) changes where Newton stops
inside its tolerance, never the equilibrium: the curve must match the reference within what
that tolerance allows. CPU-heavy (the product's full default sweep, a few seconds of CPU).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from tactile_sensor.physics.fem.sweep import _RESIDUAL_TOL
from tactile_sensor.physics.params import PhysicsParams
from tactile_sensor.physics.prediction import PredictionCurve, compute_curve

REFERENCE = Path(__file__).parent / "data" / "default_sweep_reference.json"


@pytest.fixture(scope="module")
def reference() -> dict:
    return json.loads(REFERENCE.read_text())


@pytest.fixture(scope="module")
def curve() -> PredictionCurve:
    return compute_curve(PhysicsParams())


def tolerances(params: PhysicsParams) -> tuple[float, float]:
    """(force [N], relative bulge) two converged solutions may differ by.

    Each sweep stops once the out-of-balance force is below tol_n; the extrapolation
    f + (f - f_half) / (2^p - 1) amplifies a difference by up to 1 + 2 / (2^0.8 - 1) = 3.7.
    The bulge is a displacement: 1e-4 of it is far above where two converged solves differ
    (~1e-8 measured) and far below the mesh's error (~1 %).
    """
    tol_n = _RESIDUAL_TOL * params.shear_modulus * params.height**2
    return 4.0 * 2 * tol_n, 1e-4


def test_reference_is_for_the_default_parameters(reference):
    assert reference["digest"] == PhysicsParams().digest(), (
        "the default parameters changed: recompute the reference with the solver it names")


def test_default_sweep_matches_the_reference_within_the_solver_tolerance(curve, reference):
    force_tol, bulge_rtol = tolerances(PhysicsParams())
    assert curve.nodes == reference["nodes"]
    np.testing.assert_array_equal(curve.indentation_m, reference["indentation_m"])
    np.testing.assert_allclose(curve.force_n, reference["force_n"], rtol=0, atol=force_tol)
    np.testing.assert_allclose(curve.bulge_m, reference["bulge_m"], rtol=bulge_rtol,
                               atol=1e-12)
    np.testing.assert_allclose(curve.output_v, reference["output_v"], rtol=bulge_rtol,
                               atol=1e-9)

