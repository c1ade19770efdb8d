"""The rate-aware calibration: exact against physics' Prony series, file version 2, and
the signal chain's force with rate terms that start from rest at every tare."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tactile_sensor.hardware.adc_samples import Sample
from tactile_sensor.physics.viscoelastic import RateDependentForce
from tactile_sensor.sensing.array_chain import build_chain
from tactile_sensor.sensing.calibration import Calibration
from tactile_sensor.sensing.chain import ChainConfig, SignalChain
from tactile_sensor.sensing.conversion import AdcConversion
from tactile_sensor.sensing.errors import CalibrationError
from tactile_sensor.sensing.rate_calibration import (
    RateCalibration,
    RateTerm,
    load_file,
)

STATIC = Calibration.from_curve([0.0, 0.1, 0.3, 0.5], [0.0, 1.0, 3.5, 7.0], "test:curve")
TERMS = (RateTerm(0.05, 0.1), RateTerm(0.04, 1.5))
RATE = RateCalibration(STATIC, TERMS)
ADC = AdcConversion()


def estimate(cal: RateCalibration, t: np.ndarray, output: np.ndarray) -> np.ndarray:
    est = cal.estimator()
    return np.array([est.update(float(o), float(s))[0]
                     for o, s in zip(output, t, strict=True)])


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), knots=st.integers(2, 12),
       terms=st.lists(st.tuples(st.floats(0.0, 0.5), st.floats(0.005, 20.0)),
                      min_size=1, max_size=3))
def test_exact_on_piecewise_linear_inputs_as_physics(seed, knots, terms):
    """A piecewise-linear output inside one segment of the curve gives a piecewise-linear
    static force; sampled at random times (knots among them), the estimator equals
    physics' RateDependentForce on the same static force to rounding."""
    rng = np.random.default_rng(seed)
    knot_t = np.concatenate(([0.0], np.cumsum(rng.uniform(0.01, 2.0, knots - 1))))
    knot_out = rng.uniform(0.1, 0.3, knots)  # one segment of STATIC: linear in output
    t = np.unique(np.concatenate((knot_t, rng.uniform(0.0, knot_t[-1], 40))))
    output = np.interp(t, knot_t, knot_out)
    cal = RateCalibration(STATIC, [RateTerm(g, tau) for g, tau in terms])
    static = np.array([STATIC.force(float(o)) for o in output])
    truth = RateDependentForce(cal.g, cal.tau_s).force_history(t, static)
    assert np.allclose(estimate(cal, t, output), truth, rtol=1e-12, atol=1e-12)


def test_ramp_and_hold_match_the_closed_form_and_relax():
    """F_s = k t on a ramp: each term is g k tau (1 − e^(−t/tau)); in a hold it decays."""
    t = np.arange(0.0, 3.0 + 1e-9, 1e-3)  # ramp 1 s, hold 2 s
    output = 0.1 + 0.2 * np.minimum(t, 1.0)  # static force 1 -> 3.5 N at 2.5 N/s
    force = estimate(RATE, t, output)
    end = 1000
    extra = sum(g * 2.5 * tau * (1 - math.exp(-1.0 / tau)) for g, tau in zip(
        RATE.g, RATE.tau_s, strict=True))
    assert force[end] == pytest.approx(3.5 + extra, rel=1e-9)
    assert np.all(np.diff(force[end:]) < 0)  # relaxes during the hold
    hold = 2.0
    left = sum(g * 2.5 * tau * (1 - math.exp(-1.0 / tau)) * math.exp(-hold / tau)
               for g, tau in zip(RATE.g, RATE.tau_s, strict=True))
    assert force[-1] == pytest.approx(3.5 + left, rel=1e-9)


def test_a_step_adds_the_instant_moduli_and_saturation_is_reported():
    est = RATE.estimator()
    assert est.update(0.1, 0.0) == (1.0, False)
    force, saturated = est.update(0.3, 0.0)  # dt 0: a step
    assert force == pytest.approx(1.0 + 2.5 * RATE.instant_gain)
    assert not saturated
    assert est.update(0.6, 0.001)[1]  # beyond the curve's end


def test_the_full_scale_is_the_static_curves_relaxed_maximum():
    assert RATE.full_scale_force_n == STATIC.full_scale_force_n == 7.0


def test_nan_output_and_a_clock_going_back_restart_from_rest():
    est = RATE.estimator()
    est.update(0.1, 0.0)
    est.update(0.3, 0.1)
    force, _ = est.update(float("nan"), 0.2)
    assert math.isnan(force)
    assert est.update(0.3, 0.3)[0] == pytest.approx(3.5)  # from rest again
    est.update(0.4, 0.4)
    assert est.update(0.2, 0.1)[0] == pytest.approx(STATIC.force(0.2))  # time went back


def test_reset_forgets_the_history():
    est = RATE.estimator()
    est.update(0.1, 0.0)
    assert est.update(0.3, 0.01)[0] > 3.5
    est.reset()
    assert est.update(0.3, 0.02)[0] == 3.5


@pytest.mark.parametrize(("terms", "match"), [
    ((), "1 to 3 rate terms"),
    ((RateTerm(0.1, 1.0),) * 4, "1 to 3 rate terms"),
    ((RateTerm(-0.1, 1.0),), "g=-0.1"),
    ((RateTerm(float("nan"), 1.0),), "g=nan"),
    ((RateTerm(0.1, 0.0),), "tau_s=0.0"),
    ((RateTerm(0.1, float("inf")),), "tau_s=inf"),
])
def test_bad_terms_are_refused(terms, match):
    with pytest.raises(CalibrationError, match=match):
        RateCalibration(STATIC, terms)


# -- file format ----------------------------------------------------------------------------

def test_version_2_round_trip(tmp_path):
    path = tmp_path / "cal.json"
    RATE.to_file(path, fit={"folds": {"10.0": 0.05}})
    data = json.loads(path.read_text())
    assert data["version"] == 2
    assert data["rate_terms"] == [{"g": 0.05, "tau_s": 0.1}, {"g": 0.04, "tau_s": 1.5}]
    loaded = load_file(path)
    assert isinstance(loaded, RateCalibration)
    assert loaded.terms == TERMS and loaded.static.output_v == STATIC.output_v
    assert loaded.source == f"file:{path} (test:curve)"


def test_static_files_stay_version_1_and_load_as_static(tmp_path):
    path = tmp_path / "cal.json"
    STATIC.to_file(path)
    assert json.loads(path.read_text())["version"] == 1
    assert isinstance(load_file(path), Calibration)
    data = {**json.loads(path.read_text()), "version": 2, "rate_terms": []}
    path.write_text(json.dumps(data))
    assert isinstance(load_file(path), Calibration)  # version 2 without terms: static


def _write(tmp_path, data):
    path = tmp_path / "cal.json"
    path.write_text(json.dumps(data))
    return path


V2 = {**RATE.to_dict(), "source": "x"}


@pytest.mark.parametrize(("data", "match"), [
    ({**V2, "version": 4}, "version 4 is newer than this tactile_sensor reads \\(up to 3\\); "
                           "update tactile_sensor"),
    ({**V2, "version": 0}, "not a version"),
    ({**V2, "version": "2"}, "not a version"),
    ({**V2, "version": 1}, "version-1 calibration file cannot hold rate_terms"),
    ({**V2, "rate_terms": [{"g": 0.1}]}, "rate_terms\\[0\\] must be an object"),
    ({**V2, "rate_terms": [{"g": -1.0, "tau_s": 1.0}]}, "g=-1.0"),
    ({**V2, "rate_terms": [{"g": 0.1, "tau_s": 1.0}] * 4}, "1 to 3 rate terms"),
    ({**V2, "output_v": [0.0, 0.0, 1.0, 2.0]}, "strictly increasing"),
    ({**V2, "format": "other"}, "not a calibration file"),
])
def test_bad_version_2_files_are_refused_with_a_reason(tmp_path, data, match):
    with pytest.raises(CalibrationError, match=match):
        load_file(_write(tmp_path, data))


def test_the_static_reader_refuses_rate_terms_rather_than_dropping_them(tmp_path):
    with pytest.raises(CalibrationError, match="holds rate terms"):
        Calibration.from_file(_write(tmp_path, V2))


# -- in the signal chain --------------------------------------------------------------------

def samples(volts, start=0):
    for k, v in enumerate(volts, start):
        yield Sample(k & 0xFFFF, k * 1000, 0, (ADC.counts(v),), 1)


def run(chain, volts, start=0):
    return [chain.process(s) for s in samples(volts, start=start)]


def press_volts(rest=600, ramp=300, hold=1000):
    """Rest at 2.0 V, then the voltage falls 0.3 V in ``ramp`` ms and holds."""
    return ([2.0] * rest + list(2.0 - 0.3 * np.arange(1, ramp + 1) / ramp)
            + [1.7] * hold)


def test_chain_with_a_rate_calibration_overshoots_then_relaxes():
    config = ChainConfig(filter_name="none")
    static_chain = SignalChain(config, STATIC)
    rate_chain = SignalChain(config, RATE)
    assert rate_chain.rate_aware and not static_chain.rate_aware
    volts = press_volts(hold=5000)  # 3.3 times the slower term's 1.5 s
    static = np.array([r.force_n for r in run(static_chain, volts)])
    rate = np.array([r.force_n for r in run(rate_chain, volts)])
    peak = 600 + 299
    assert static[peak] == pytest.approx(STATIC.force(0.3), abs=0.01)
    assert rate[peak] > static[peak] * 1.02  # faster than the terms relax: more force
    assert rate[-1] - static[-1] < 0.1 * (rate[peak] - static[peak])  # relaxed in the hold
    assert rate_chain.calibration is RATE and rate_chain.calibration_source == "test:curve"


def test_chain_restarts_the_rate_terms_at_a_tare():
    chain = SignalChain(ChainConfig(filter_name="none", auto_tare=False), RATE)
    chain.set_baseline(2.0)
    run(chain, press_volts(rest=10, ramp=100, hold=5))
    assert chain.last.force_n > STATIC.force(0.3) * 1.02
    run(chain, [1.7] * 600, start=200)  # at rest under load: a tare window
    chain.tare()
    first = run(chain, [1.7] * 2, start=800)
    assert first[-1].force_n == pytest.approx(STATIC.force(0.0), abs=0.01)  # no carry-over


@pytest.mark.parametrize("restart", ["set_baseline", "reset", "set_calibration"])
def test_chain_restarts_the_rate_terms_when_its_history_is_lost(restart):
    chain = SignalChain(ChainConfig(filter_name="none", auto_tare=False), RATE)
    chain.set_baseline(2.0)
    run(chain, press_volts(rest=10, ramp=100, hold=5))
    {"set_baseline": lambda: chain.set_baseline(2.0), "reset": chain.reset,
     "set_calibration": lambda: chain.set_calibration(RATE)}[restart]()
    assert run(chain, [1.7], start=200)[0].force_n == pytest.approx(STATIC.force(0.3),
                                                                    abs=0.01)


def test_chain_with_a_static_calibration_is_unchanged():
    chain = SignalChain(ChainConfig(filter_name="none"), STATIC)
    readings = run(chain, press_volts())
    expected = [STATIC.evaluate(r.output_v) for r in readings[600:]]
    assert [(r.force_n, r.saturated) for r in readings[600:]] == expected
    chain.set_calibration(RATE)
    chain.set_calibration(STATIC)
    assert not chain.rate_aware


def test_build_chain_loads_the_rate_terms_from_a_version_2_file(tmp_path):
    path = tmp_path / "cal.json"
    RATE.to_file(path)
    chain = build_chain(ChainConfig(), (), str(path))
    assert isinstance(chain.calibration, RateCalibration) and chain.rate_aware
    STATIC.to_file(path)
    assert not build_chain(ChainConfig(), (), str(path)).rate_aware
