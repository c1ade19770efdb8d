"""Array chain: tare of all modules together, forces from the array calibration, contact on
|F|, blindness when any module's detector is at its rail, the modules string and every
refusal."""

from __future__ import annotations

import dataclasses
import math
import re

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tactile_sensor.hardware.adc_samples import Sample, SampleBatch
from tactile_sensor.hardware.health import Level
from tactile_sensor.sensing.adc_health import adc_health
from tactile_sensor.sensing.adc_settings import AdcSettings, Source
from tactile_sensor.sensing.array_calibration import ArrayCalibration
from tactile_sensor.sensing.array_chain import ArrayChain, Module, parse_modules
from tactile_sensor.sensing.blind import BLIND_MESSAGE
from tactile_sensor.sensing.chain import ChainConfig
from tactile_sensor.sensing.conversion import AdcConversion
from tactile_sensor.sensing.errors import CalibrationError, SensingError, TareError
from tactile_sensor.sensing.modulation import Modulation

from .test_adc_health import stats

ADC = AdcConversion()
FACES = ("front", "back", "left", "right")
MODULES = tuple(Module(c, f) for c, f in enumerate(FACES))


def linear_calibration(faces=FACES, degree: int = 3) -> ArrayCalibration:
    """Fx = 10 (right - left), Fy = 10 (front - back), Fz = 5 sum, fitted on a grid."""
    rng = np.random.default_rng(0)
    o = rng.uniform(-0.1, 0.5, size=(300, len(faces)))
    col = {f: o[:, i] for i, f in enumerate(faces)}
    fx = 10.0 * (col["right"] - col["left"])
    fy = 10.0 * (col["front"] - col["back"])
    fz = 5.0 * o.sum(axis=1)
    return ArrayCalibration.fit(faces, o, np.stack([fx, fy, fz], axis=1), degree, "test:lin")


CAL = linear_calibration()


def samples(rows, start=0, channels=4):
    for k, volts in enumerate(rows, start):
        counts = tuple(ADC.counts(v) for v in volts) + (0,) * (channels - len(volts))
        yield Sample(k & 0xFFFF, k * 1000, 0, counts, 1)


def run(chain, rows, start=0, channels=4):
    return [chain.process(s) for s in samples(rows, start, channels)]


def quantised(v: float) -> float:
    return ADC.volts(ADC.counts(v))


@settings(max_examples=25, deadline=None)
@given(rest=st.lists(st.floats(1.0, 4.0), min_size=4, max_size=4),
       press=st.lists(st.floats(-0.1, 0.4), min_size=4, max_size=4))
def test_outputs_after_tare_and_forces_are_the_calibration_of_the_outputs(rest, press):
    chain = ArrayChain(ChainConfig(filter_name="moving_average"), MODULES, CAL)
    before = run(chain, [rest] * 600)
    assert math.isnan(before[0].force_n) and all(math.isnan(o) for o in before[0].outputs_v)
    assert chain.tared
    assert chain.baselines_v == pytest.approx([quantised(v) for v in rest], abs=1e-9)
    pressed = run(chain, [[r - p for r, p in zip(rest, press, strict=True)]] * 20, start=600)
    last = pressed[-1]
    expected = [quantised(r) - quantised(r - p) for r, p in zip(rest, press, strict=True)]
    assert last.outputs_v == pytest.approx(expected, abs=1e-9)
    assert last.voltages_v == pytest.approx([quantised(r - p) for r, p in
                                             zip(rest, press, strict=True)], abs=1e-12)
    fx, fy, fz = CAL.force(last.outputs_v)
    assert (last.force_x_n, last.force_y_n, last.force_n) == (fx, fy, fz)
    assert (last.voltage_v, last.output_v) == (last.voltages_v[0], last.outputs_v[0])
    assert last.saturated == (not CAL.in_range(last.outputs_v))


def test_forces_are_nan_until_calibrated_and_saturated_beyond_the_fit():
    chain = ArrayChain(ChainConfig(), MODULES)
    run(chain, [[2.0] * 4] * 600)
    assert chain.tared and chain.calibration_source == "none"
    assert math.isnan(chain.last.force_n) and math.isnan(chain.last.force_x_n)
    assert not math.isnan(chain.last.output_v)
    chain.set_calibration(CAL)
    assert run(chain, [[2.0] * 4] * 50, start=600)[-1].force_n == pytest.approx(0, abs=0.02)
    far = run(chain, [[1.0, 2.0, 2.0, 2.0]] * 50, start=650)[-1]  # front output 1 V
    assert far.saturated and far.outputs_v[0] == pytest.approx(1.0, abs=0.01)


def test_contact_is_decided_on_the_force_magnitude():
    chain = ArrayChain(ChainConfig(filter_name="none", contact_on_n=1.0, contact_off_n=0.5,
                                   contact_debounce_s=0.0), MODULES, CAL)
    run(chain, [[2.0] * 4] * 600)
    # pure shear toward +x: right bulges out (+0.1 V output), left draws in: Fz stays 0
    shear = run(chain, [[2.0, 2.0, 2.1, 1.9]] * 5, start=600)[-1]
    assert shear.force_x_n == pytest.approx(2.0, abs=0.05)
    assert abs(shear.force_n) < 0.05 and shear.contact
    released = run(chain, [[2.0] * 4] * 5, start=605)[-1]
    assert not released.contact


@settings(max_examples=12, deadline=None)
@given(moving=st.integers(0, 3), auto=st.booleans())
def test_tare_is_refused_when_one_module_moves_and_names_it(moving, auto):
    chain = ArrayChain(ChainConfig(auto_tare=auto), MODULES, CAL)
    ramp = 2.0 - 0.0005 * np.arange(600)
    rows = [[float(ramp[k]) if i == moving else 2.0 for i in range(4)] for k in range(600)]
    run(chain, rows)
    assert not chain.tared  # auto-tare never took the moving module
    with pytest.raises(TareError, match=f"Module {FACES[moving]} \\(channel {moving}\\): "
                                        "Tare refused: the signal is not at rest"):
        chain.tare()
    assert chain.baselines_v is None  # all or none
    run(chain, [[2.0] * 4] * 600, start=600)
    result = chain.tare()
    assert result.baselines_v == pytest.approx([quantised(2.0)] * 4)
    assert result.samples == 500


def test_tare_needs_a_full_window():
    chain = ArrayChain(ChainConfig(auto_tare=False), MODULES, CAL)
    run(chain, [[2.0] * 4] * 10)
    with pytest.raises(TareError, match=r"Module front \(channel 0\): Tare needs 0.5 s"):
        chain.tare()


def test_channels_follow_the_modules_and_a_short_sample_is_refused():
    modules = (Module(5, "left"), Module(2, "right"))
    chain = ArrayChain(ChainConfig(filter_name="none"), modules)
    chain.process(next(samples([[0, 0, 1.0, 0, 0, 3.0]], channels=6)))
    assert chain.last.voltages_v == pytest.approx([quantised(3.0), quantised(1.0)])
    with pytest.raises(SensingError, match="has 4 channel\\(s\\) but the modules use "
                                           "channel 5"):
        chain.process(next(samples([[2.0] * 4])))


def test_a_calibration_for_other_modules_is_refused_with_both_named():
    chain = ArrayChain(ChainConfig(), MODULES)
    other = ArrayCalibration(("front", "back", "left@0.002", "right@-0.002"),
                             CAL.feature_matrix, CAL.terms, CAL.coefficients,
                             CAL.output_scale_v, CAL.output_max_v, "test:other")
    with pytest.raises(CalibrationError, match=re.escape(
            "is for modules front, back, left@0.002, right@-0.002 but the driver's modules "
            "are front, back, left, right")):
        chain.set_calibration(other)
    with pytest.raises(CalibrationError, match="modules are front, back"):
        ArrayChain(ChainConfig(), MODULES[:2], CAL)
    assert chain.calibration is None


def test_a_calibration_in_another_module_order_is_put_in_the_channels_order():
    chain = ArrayChain(ChainConfig(), MODULES)
    swapped = linear_calibration(("front", "back", "right", "left"))
    chain.set_calibration(swapped)
    assert chain.calibration.faces == FACES
    outputs = (0.1, 0.05, 0.02, 0.3)
    assert chain.calibration.force(outputs) == pytest.approx(
        swapped.force((0.1, 0.05, 0.3, 0.02)), abs=1e-12)


def test_reconfigure_keeps_baselines_and_refuses_the_adc_settings():
    chain = ArrayChain(ChainConfig(filter_name="moving_average"), MODULES, CAL)
    run(chain, [[2.0] * 4] * 600)
    baselines = chain.baselines_v
    chain.reconfigure(ChainConfig(filter_name="none", contact_on_n=2.0, contact_off_n=1.0))
    assert chain.baselines_v == baselines and chain.calibration is CAL
    step = run(chain, [[1.9, 2.0, 2.0, 2.0]], start=600)[0]
    assert step.outputs_v[0] == pytest.approx(0.1, abs=2e-3)  # no filter: at once
    with pytest.raises(SensingError, match="rate_hz cannot change"):
        chain.reconfigure(ChainConfig(rate_hz=500.0))
    chain.reconfigure(ChainConfig(tare_window_s=0.1, auto_tare=False))
    with pytest.raises(TareError, match="only 0"):
        chain.tare()


def test_reset_and_a_new_conversion_forget_filters_and_windows_but_keep_baselines():
    chain = ArrayChain(ChainConfig(auto_tare=False), MODULES, CAL)
    run(chain, [[2.0] * 4] * 600)
    chain.tare()
    chain.reset()
    assert chain.tared
    with pytest.raises(TareError, match="only 0"):
        chain.tare()
    run(chain, [[2.0] * 4] * 600)
    chain.set_conversion(AdcConversion(10, 5.0))
    assert chain.conversion.bits == 10
    with pytest.raises(TareError, match="only 0"):
        chain.tare()


def test_parse_modules():
    assert parse_modules("") == () and parse_modules("  ") == ()
    assert parse_modules("0:front, 1:back,2 : left,3:right") == MODULES
    assert parse_modules("7:left,0:right") == (Module(7, "left"), Module(0, "right"))


@pytest.mark.parametrize(("text", "sentence"), [
    ("0:front,1", "Module '1' in modules is not CHANNEL:FACE; write it like "
                  "'0:front,1:back,2:left,3:right'."),
    ("0:front,x:back", "Module 'x:back' in modules has channel 'x', which is not a whole "
                       "number 0..7."),
    ("0:front,8:back", "Module '8:back' in modules has channel 8; ADC channels are 0..7."),
    ("0:front,-1:back", "Module '-1:back' in modules has channel -1; ADC channels are 0..7."),
    ("0:front,1:top", "Module '1:top' in modules has face 'top'; faces are front, back, "
                      "left, right, optionally FACE@OFFSET"),
    ("0:front,0:back", "Channel 0 appears twice in modules (front and back); give each "
                       "module its own channel."),
    ("0:front,1:front", "Module front appears twice in modules (channels 0 and 1); a "
                        "window carries one module"),
    ("0:front@0.001,1:front@1e-3", "Module front@0.001 appears twice in modules"),
    ("0:front@,1:back", "Module '0:front@' in modules has face 'front@'"),
    ("2:front", "modules names one module (2:front); leave modules empty and set channel "
                "for a single module, or name two or more."),
    ("0:front,,1:back", "Module '' in modules is not CHANNEL:FACE"),
])
def test_a_bad_modules_string_gets_one_sentence(text, sentence):
    with pytest.raises(SensingError) as info:
        parse_modules(text)
    assert str(info.value).startswith(sentence)
    assert str(info.value).endswith(".") and str(info.value).count(". ") == 0


def test_an_array_chain_needs_two_modules():
    with pytest.raises(SensingError, match="two or more modules"):
        ArrayChain(ChainConfig(), MODULES[:1])


def test_a_batch_gives_what_the_same_samples_give_one_by_one():
    rng = np.random.default_rng(4)
    rows = [[2.0, 2.1, 1.9, 2.2]] * 600 + [[2.0 - d, 2.1, 1.9 - d / 2, 2.2] for d in
                                          np.linspace(0, 0.3, 200)]
    rows = (np.array(rows) + rng.normal(0, 0.002, (len(rows), 4))).tolist()
    expected = run(ArrayChain(ChainConfig(), MODULES, CAL), rows)
    batched = ArrayChain(ChainConfig(), MODULES, CAL)
    stream = list(samples(rows))
    got = [r for k in range(0, len(stream), 50)
           for r in batched.process_batch(SampleBatch.of(stream[k:k + 50]))]
    assert [r.outputs_v for r in got] == [r.outputs_v for r in expected]
    assert [(r.force_x_n, r.force_y_n, r.force_n, r.contact) for r in got] == [
        (r.force_x_n, r.force_y_n, r.force_n, r.contact) for r in expected]
    assert batched.last == expected[-1]


def test_a_batch_with_too_few_channels_is_refused_naming_the_top_one():
    chain = ArrayChain(ChainConfig(), MODULES, CAL)
    with pytest.raises(SensingError, match="3 channel\\(s\\) but the modules use channel 3"):
        chain.process_batch(SampleBatch.of(samples([[2.0, 2.0, 2.0]] * 2, channels=3)))


def torque_calibration(observed=("fx", "fy", "fz", "tx")) -> ArrayCalibration:
    """CAL with a torque column by hand: Tx = 0.1 N m per scaled front - back feature."""
    torque = np.zeros((3, CAL.terms.shape[0]))
    torque[0, CAL.terms.tolist().index([0, 0, 0, 1])] = 0.1
    return ArrayCalibration(CAL.faces, CAL.feature_matrix, CAL.terms, CAL.coefficients,
                            CAL.output_scale_v, CAL.output_max_v, "test:torque", torque,
                            observed)


def step_rise_s(cutoff_hz: float) -> tuple[float, float, float]:
    """(10-90 % rise time [s] of Tx after a step in the front output, its final value, the
    calibration's Tx of the final outputs)."""
    cal = torque_calibration()
    chain = ArrayChain(ChainConfig(filter_name="none"), MODULES, cal, cutoff_hz)
    run(chain, [[2.0] * 4] * 600)
    after = run(chain, [[1.9, 2.0, 2.0, 2.0]] * 400, start=600)
    tx = np.array([r.torque_x_nm for r in after])
    final = cal.wrench(after[-1].outputs_v)[3]
    t10, t90 = (int(np.argmax(tx >= q * final)) for q in (0.1, 0.9))
    return (t90 - t10) * 1e-3, float(tx[-1]), final


def test_a_torque_step_rises_in_the_cutoffs_time_and_settles_on_the_calibration():
    rise_10, last_10, final = step_rise_s(10.0)
    rise_20, last_20, _ = step_rise_s(20.0)
    assert final > 0.01
    assert last_10 == pytest.approx(final, rel=1e-3) and last_20 == pytest.approx(final, rel=1e-3)
    assert rise_10 / rise_20 == pytest.approx(2.0, rel=0.1)        # time scales as 1 / cutoff
    assert rise_10 == pytest.approx(0.34 / 10.0, rel=0.25)        # 2nd-order: ~0.34 / f_c


def test_torque_noise_falls_with_the_square_root_of_the_cutoff():
    rng = np.random.default_rng(4)
    rows = 2.0 + rng.normal(0.0, 0.05, (3000, 4))
    spread = {}
    for cutoff in (5.0, 40.0):
        chain = ArrayChain(ChainConfig(filter_name="none", tare_max_spread_v=1.0), MODULES,
                           torque_calibration(), cutoff)
        run(chain, [[2.0] * 4] * 600)
        chain.tare()
        tx = [r.torque_x_nm for r in run(chain, rows, start=600)][200:]
        spread[cutoff] = float(np.std(tx))
    assert spread[40.0] / spread[5.0] == pytest.approx(math.sqrt(8.0), rel=0.25)


def test_unobserved_components_are_nan_and_a_force_only_calibration_has_no_torque():
    chain = ArrayChain(ChainConfig(), MODULES, torque_calibration(("fx", "fz", "tx")))
    last = run(chain, [[2.0] * 4] * 650)[-1]
    assert math.isnan(last.force_y_n) and math.isnan(last.torque_y_nm)
    assert math.isnan(last.torque_z_nm) and not math.isnan(last.torque_x_nm)
    assert not math.isnan(last.force_x_n) and not math.isnan(last.force_n)
    chain.set_calibration(CAL)                                  # forces only
    last = run(chain, [[2.0] * 4] * 5, start=650)[-1]
    assert all(math.isnan(t) for t in (last.torque_x_nm, last.torque_y_nm, last.torque_z_nm))
    assert last.force_n == pytest.approx(0.0, abs=0.02)


def test_a_torque_cutoff_beyond_half_the_rate_is_one_sentence():
    with pytest.raises(SensingError, match="torque_cutoff_hz = 600 Hz does not fit the 1000 "
                                           "Hz sample rate") as info:
        ArrayChain(ChainConfig(), MODULES, CAL, 600.0)
    assert str(info.value).endswith("below half the sample rate.")


def test_modules_at_offsets_parse_to_canonical_labels():
    assert parse_modules("0:front@-5.5e-3, 1:front@0.0055,2:back@0") == (
        Module(0, "front@-0.0055"), Module(1, "front@0.0055"), Module(2, "back"))


def test_the_forces_slow_part_is_low_passed_with_the_torque_and_added_to_the_force():
    """A slow Fy of 0.5 N per scaled front - back feature: the force steps at once by its
    fast part, the slow part follows in the torque's rise time, and the sum settles on the
    calibration's static wrench."""
    slow = np.zeros((3, CAL.terms.shape[0]))
    slow[1, CAL.terms.tolist().index([0, 0, 0, 1])] = 0.5
    base = torque_calibration(("fx", "fy", "fz", "tx"))
    cal = ArrayCalibration(base.faces, base.feature_matrix, base.terms, base.coefficients,
                           base.output_scale_v, base.output_max_v, "test:slow",
                           base.torque_coefficients, base.observed, slow)
    assert cal.has_slow
    chain = ArrayChain(ChainConfig(filter_name="none"), MODULES, cal, 10.0)
    run(chain, [[2.0] * 4] * 600)
    after = run(chain, [[1.9, 2.0, 2.0, 2.0]] * 400, start=600)
    fast = base.wrench(after[-1].outputs_v)[1]
    total = cal.wrench(after[-1].outputs_v)[1]
    assert abs(total - fast) > 0.01                            # the slow part is there
    fy = np.array([r.force_y_n for r in after])
    assert fy[0] == pytest.approx(fast, abs=0.2 * abs(total - fast))   # not yet added
    assert fy[-1] == pytest.approx(total, rel=1e-3)
    parts = cal.wrench_parts_unchecked(after[-1].outputs_v)
    assert parts[1] + parts[7] == pytest.approx(total, rel=1e-12)
    assert parts[3] == pytest.approx(cal.wrench(after[-1].outputs_v)[3], rel=1e-12)


def tared_array() -> ArrayChain:
    chain = ArrayChain(ChainConfig(), MODULES, CAL)
    run(chain, [(2.0, 2.0, 2.0, 2.0)] * 600)
    assert chain.tared and not chain.blind
    return chain


def test_one_module_at_the_rail_blinds_the_array_until_the_light_goes():
    chain = tared_array()
    lit = run(chain, [(2.0, 0.1, 2.0, 2.0)] * 20, start=600)
    assert all(r.blind and not r.contact for r in lit)
    assert all(math.isnan(v) for r in lit for v in (r.force_x_n, r.force_y_n, r.force_n))
    assert chain.blind and chain.blind_samples == 20
    assert chain.headroom()[0] == 0.0
    with pytest.raises(TareError) as refused:
        chain.tare()
    assert str(refused.value) == f"Cannot tare: {BLIND_MESSAGE}."
    back = run(chain, [(2.0, 2.0, 2.0, 2.0)] * 60, start=620)
    seeing = [k for k, r in enumerate(back) if not r.blind]
    assert seeing and seeing[0] >= 1 and all(not back[k].blind for k in range(seeing[0], 60))
    assert back[-1].force_n == pytest.approx(0.0, abs=1e-6) and not chain.blind


def test_light_at_the_rail_before_the_first_tare_never_becomes_an_arrays_baseline():
    chain = ArrayChain(ChainConfig(), MODULES, CAL)
    run(chain, [(2.0, 2.0, 0.0, 2.0)] * 2000)
    assert not chain.tared and chain.blind


def test_a_modulated_array_is_blind_when_the_room_saturates_the_emitter_off_sample():
    modulation = Modulation(2000, 900, 0, 0, 4)
    chain = ArrayChain(ChainConfig(rate_hz=500.0, filter_name="none", tare_window_s=0.1),
                       MODULES, CAL)
    chain.set_modulation(modulation)
    share = modulation.share

    def pair_rows(on: float, off: float, n: int, start: int) -> list:
        counts = tuple(ADC.counts(on) for _ in FACES) + tuple(ADC.counts(off) for _ in FACES)
        return [chain.process(Sample(k & 0xFFFF, k * 2000, 0, counts, 1))
                for k in range(start, start + n)]

    rest = pair_rows(3.0 - 1.5 * share, 3.0, 120, 0)
    assert chain.tared and not rest[-1].blind
    assert chain.headroom()[0] == pytest.approx(3.0 - 1.5 * share - 0.3, abs=3e-3)
    lit = pair_rows(0.05, 0.2, 5, 120)  # the room's light takes both samples to the rail
    assert all(r.blind for r in lit) and math.isnan(lit[-1].force_n)


def test_the_diagnostics_say_an_array_is_blind_in_one_sentence():
    usable = AdcSettings(ADC, Source.DEVICE)
    chain = tared_array()
    ok = adc_health(stats(), usable, chain, 1000.0, 0, 0)
    assert ok.values["blind"] == "no" and ok.values["detector_headroom_v"] == "1.700"
    run(chain, [(2.0, 2.0, 2.0, 0.2)] * 5, start=600)
    blind = adc_health(stats(), usable, chain, 1000.0, 0, 0)
    assert (blind.level, blind.message) == (Level.ERROR, BLIND_MESSAGE)
    assert blind.values["blind"] == "yes" and blind.values["blind_samples"] == "5"


# -- the array re-tares at rest (sensing/rest_gain.py) --------------------------------------

def resting_array(tau_s: float = 1.0, **kw) -> ArrayChain:
    config = ChainConfig(rate_hz=100.0, filter_name="none", rest_retare_time_constant_s=tau_s,
                         **kw)
    return ArrayChain(config, MODULES, CAL)


def feed_array(chain: ArrayChain, rows, start: int = 0) -> list:
    return [chain.process(Sample(k & 0xFFFF, k * 10_000, 0,
                                 tuple(ADC.counts(v) for v in row), 1))
            for k, row in enumerate(rows, start)]


def test_slow_light_on_every_module_is_followed_at_rest_and_read_as_force_without_it():
    """Each module 20 mV brighter over 60 s: Fz = 5 x 4 x 0.02 = 0.4 N if the baselines
    stayed (over the release threshold, under the contact's), about 0 N followed."""
    drift = 2.0 - 0.02 * np.clip((np.arange(7000) - 500) / 6000.0, 0.0, 1.0)
    rows = [(v, v, v, v) for v in drift]
    following, fixed = resting_array(), resting_array(0.0)
    last = feed_array(following, rows)[-1]
    assert abs(last.force_n) < 0.05 and following.rest_retares > 100
    assert following.baselines_v == pytest.approx((1.98,) * 4, abs=0.003)
    last = feed_array(fixed, rows)[-1]
    assert last.force_n == pytest.approx(0.4, abs=0.02)
    assert fixed.baselines_v == pytest.approx((2.0,) * 4, abs=0.002)
    assert fixed.rest_retares == 0


def test_a_held_press_on_the_array_is_never_taken_for_light():
    chain = resting_array()
    feed_array(chain, [(2.0,) * 4] * 100)
    baselines, retares = chain.baselines_v, chain.rest_retares
    held = feed_array(chain, [(1.94, 1.94, 2.0, 2.0)] * 3000, 100)  # Fz 0.6 N, Fy 0: 30 s
    assert chain.baselines_v == baselines and chain.rest_retares == retares
    assert held[-1].force_n == pytest.approx(0.6, abs=0.02) and held[-1].contact


def test_an_unsteady_module_or_a_blind_one_is_never_a_rest():
    chain = resting_array(tare_max_spread_v=0.01)
    feed_array(chain, [(2.0,) * 4] * 100)
    baselines, retares = chain.baselines_v, chain.rest_retares
    feed_array(chain, [(2.0, 2.0, 0.1, 2.0)] * 500, 100)  # one detector at its rail
    wobble = 1.999 + 0.008 * np.sign(np.sin(np.arange(1000) * 2 * math.pi / 20))
    feed_array(chain, [(2.0, 2.0, 2.0, w) for w in wobble], 600)  # one module not steady
    assert chain.rest_retares == retares and chain.baselines_v == baselines


def test_switching_the_arrays_rest_follow_off_stops_it_and_the_diagnostics_say_so():
    chain = resting_array()
    feed_array(chain, [(2.0,) * 4] * 300)
    assert chain.rest_retares > 0
    usable = AdcSettings(ADC, Source.DEVICE)
    assert adc_health(stats(), usable, chain, 100.0, 0, 0).values["rest_retares"] == str(
        chain.rest_retares)
    chain.reconfigure(dataclasses.replace(chain.config, rest_retare_time_constant_s=0.0))
    feed_array(chain, [(1.99,) * 4] * 300, 300)
    assert chain.baselines_v == pytest.approx((2.0,) * 4, abs=0.002)
    assert adc_health(stats(), usable, chain, 100.0, 0, 0).values["rest_retares"] == (
        "off (rest_retare_time_constant 0)")
