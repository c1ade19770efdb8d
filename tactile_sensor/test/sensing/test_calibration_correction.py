"""A correction over the driver's calibration, and which of a base and a correction wins."""

from __future__ import annotations

import itertools
import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from tactile_sensor.sensing.calibration import Calibration
from tactile_sensor.sensing.calibration_correction import (
    CalibrationCorrection,
    CorrectedCalibration,
)
from tactile_sensor.sensing.errors import CalibrationError
from tactile_sensor.sensing.rate_calibration import Play, RateCalibration, RateTerm

FEM = Calibration([0.0, 0.1, 0.3, 0.45], [0.0, 1.0, 4.0, 6.77], "fem:abc")
SELF_CHECK = CalibrationCorrection("self_check:gain=0.8,stiffness=1.15", 0.8, 1.15, 100.0)


@given(st.floats(0.3, 3.0), st.floats(0.3, 3.0), st.floats(0.0, 0.45))
def test_the_corrected_curve_reads_the_force_of_the_skin_as_it_is(
        gain: float, stiffness: float, fem_output: float):
    """Where the FEM's skin gives ``fem_output``, the module now outputs gain x that and
    the skin pushes stiffness x the FEM's force."""
    corrected = CalibrationCorrection("c", gain, stiffness, 0.0).apply(FEM)
    assert corrected.force(gain * fem_output) == pytest.approx(
        stiffness * FEM.force(fem_output), rel=1e-9, abs=1e-12)
    assert corrected.full_scale_force_n == pytest.approx(stiffness * 6.77)
    assert corrected.source == "fem:abc corrected by c"


def test_a_rate_aware_base_keeps_its_terms_and_scales_its_play():
    play = Play((0.1, 0.1, 0.2, 0.2), 0.004, 20.0)
    rate = RateCalibration(FEM, [RateTerm(0.3, 0.5)], play)
    corrected = SELF_CHECK.apply(rate)
    assert isinstance(corrected, RateCalibration) and corrected.terms == rate.terms
    assert corrected.static.force_n == pytest.approx([1.15 * f for f in FEM.force_n])
    assert corrected.play.half_gap_n == pytest.approx((0.115, 0.115, 0.23, 0.23))
    assert corrected.play.band_v == pytest.approx(0.0032)


@pytest.mark.parametrize("factors", [(0.0, 1.0), (1.0, -1.0), (math.nan, 1.0),
                                     (1.0, math.inf)])
def test_factors_that_cannot_scale_a_curve_are_refused(factors):
    with pytest.raises(CalibrationError, match="must be finite and > 0"):
        CalibrationCorrection("self_check:x", *factors, 0.0)


def test_a_base_and_a_correction_heard_in_either_order_give_the_same_calibration():
    """The model latched its curve at 50 s, the gripper its correction at 100 s: a driver
    started after both hears them in no set order."""
    for first_base in (True, False):
        state = CorrectedCalibration()
        steps = [lambda s=state: s.set_base(FEM, 50.0),
                 lambda s=state: s.set_correction(SELF_CHECK)]
        for step in steps if first_base else steps[::-1]:
            step()
        assert state.effective.source == "fem:abc corrected by " + SELF_CHECK.source
        assert state.effective.force_n == pytest.approx([1.15 * f for f in FEM.force_n])


def test_a_file_calibration_is_corrected_and_hearing_things_twice_changes_nothing():
    state = CorrectedCalibration(FEM)
    assert state.set_correction(SELF_CHECK) == (True, "")
    corrected = state.effective
    assert state.set_correction(SELF_CHECK) == (False, "")
    same_base = Calibration(FEM.output_v, FEM.force_n, FEM.source)
    assert state.set_base(same_base, 200.0) == (False, "")  # the model's curve again
    assert state.effective is corrected


def test_a_newer_base_replaces_the_correction_unless_the_correction_says_keep():
    refit = Calibration([0.0, 0.2, 0.4], [0.0, 2.0, 6.0], "bench.json")
    state = CorrectedCalibration()
    state.set_base(FEM, 50.0)
    state.set_correction(SELF_CHECK)
    changed, note = state.set_base(refit, 150.0)
    assert changed and "was dropped; run the self-check again" in note
    assert state.effective is refit and state.correction is None
    kept = CalibrationCorrection("by hand", 0.9, 1.0, 200.0, keep_on_new_calibration=True)
    state.set_correction(kept)
    state.set_base(FEM, 300.0)
    assert state.effective.source == "fem:abc corrected by by hand"


def test_a_base_older_than_the_one_in_use_is_ignored():
    state = CorrectedCalibration()
    state.set_base(FEM, 150.0)
    changed, note = state.set_base(Calibration([0.0, 0.2], [0.0, 2.0], "old"), 100.0)
    assert not changed and "older than the one in use" in note and state.effective is FEM


def test_a_correction_older_than_the_base_or_the_correction_in_use_is_ignored():
    state = CorrectedCalibration()
    state.set_base(FEM, 150.0)
    changed, note = state.set_correction(SELF_CHECK)
    assert not changed and "older than the calibration in use" in note
    assert state.effective is FEM
    newer = CalibrationCorrection("self_check:newer", 0.9, 1.1, 200.0)
    assert state.set_correction(newer)[0]
    changed, note = state.set_correction(CalibrationCorrection("self_check:late", 0.7, 1.2,
                                                               180.0))
    assert not changed and "older than the one in use" in note


def test_a_correction_without_a_base_waits_for_one():
    state = CorrectedCalibration()
    assert state.set_correction(SELF_CHECK) == (False, "") and state.effective is None
    assert state.set_base(FEM, 50.0)[0]
    assert state.effective.full_scale_force_n == pytest.approx(1.15 * 6.77)


def test_every_order_of_two_bases_and_a_correction_ends_alike():
    """The stamps decide: the file base at 50 s, the correction at 100 s, a refit at 150 s."""
    refit = Calibration([0.0, 0.2, 0.4], [0.0, 2.0, 6.0], "refit")
    ends = set()
    for order in itertools.permutations(range(3)):
        state = CorrectedCalibration()
        steps = [lambda s=state: s.set_base(FEM, 50.0),
                 lambda s=state: s.set_correction(SELF_CHECK),
                 lambda s=state: s.set_base(refit, 150.0)]
        for k in order:
            steps[k]()
        ends.add(state.effective.source)
    assert ends == {"refit"}
