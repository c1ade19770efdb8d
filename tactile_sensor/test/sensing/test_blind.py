"""A detector blinded by light: NaN force and no contact at the rail, back by itself once the
light goes and the filter holds no rail sample, no tare meanwhile, and the diagnostics'
ERROR and headroom."""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from tactile_sensor.hardware.adc_samples import Sample
from tactile_sensor.hardware.health import Level
from tactile_sensor.sensing.adc_health import adc_health
from tactile_sensor.sensing.adc_settings import AdcSettings, Source
from tactile_sensor.sensing.blind import (
    BLIND_MESSAGE,
    HYSTERESIS_V,
    SATURATION_V,
    BlindDetector,
    headroom,
)
from tactile_sensor.sensing.calibration import Calibration
from tactile_sensor.sensing.chain import ChainConfig, SignalChain
from tactile_sensor.sensing.conversion import AdcConversion
from tactile_sensor.sensing.errors import SensingError, TareError

from .test_adc_health import stats

ADC = AdcConversion()
CAL = Calibration.from_curve([0.0, 0.49], [0.0, 7.0], "test:linear")
WINDOW = 50  # the default filter's: savgol's 40 and the notch's longest flicker period (10)


def run(chain, volts, start=0):
    return [chain.process(Sample(k & 0xFFFF, k * 1000, 0, (ADC.counts(v),), 1))
            for k, v in enumerate(volts, start)]


def tared_chain() -> SignalChain:
    chain = SignalChain(ChainConfig(), CAL)
    run(chain, [2.0] * 600)
    assert chain.tared
    return chain


def test_a_sample_at_the_rail_is_blind_and_it_sees_again_after_the_settle_samples():
    detector = BlindDetector(settle_samples=3)
    assert not detector.update(1.0)
    assert detector.update(SATURATION_V)
    assert detector.update(SATURATION_V + HYSTERESIS_V / 2)  # inside the hysteresis
    assert [detector.update(1.0) for _ in range(3)] == [True, True, False]
    assert detector.blind_samples == 4


@given(st.lists(st.floats(0.0, 5.0), min_size=1, max_size=200))
def test_no_sample_at_the_rail_is_ever_read_as_seeing(volts):
    detector = BlindDetector(settle_samples=5)
    for v in volts:
        blind = detector.update(v)
        assert blind or v > SATURATION_V


def test_the_settle_samples_must_be_a_positive_integer():
    with pytest.raises(SensingError, match="settle_samples"):
        BlindDetector(settle_samples=0)


def test_a_blind_chain_gives_nan_force_no_contact_and_recovers_by_itself():
    chain = tared_chain()
    pressed = run(chain, [1.8] * 100, start=600)[-1]
    assert pressed.contact and not pressed.blind
    blind = run(chain, [0.0] * 50, start=700)
    assert all(r.blind and math.isnan(r.force_n) and not r.contact for r in blind)
    assert chain.blind and blind[0].blind  # blind from the first sample at the rail
    back = run(chain, [1.8] * 100, start=750)
    first_seeing = next(i for i, r in enumerate(back) if not r.blind)
    assert first_seeing == WINDOW - 1  # once the filter's window holds no rail sample
    assert back[first_seeing].force_n == pytest.approx(pressed.force_n, abs=0.05)
    assert not chain.blind


def test_a_blind_chain_refuses_to_tare_in_one_sentence():
    chain = tared_chain()
    run(chain, [0.1] * 600, start=600)
    with pytest.raises(TareError) as error:
        chain.tare()
    assert str(error.value) == f"Cannot tare: {BLIND_MESSAGE}."


def test_light_at_the_rail_before_the_first_tare_never_becomes_the_baseline():
    chain = SignalChain(ChainConfig(), CAL)
    run(chain, [0.0] * 2000)
    assert not chain.tared


def test_the_headroom_is_the_room_above_saturation_in_the_emitters_rest_drop():
    assert headroom(2.0, None, 5.0) == (pytest.approx(1.7), None)
    left, ratio = headroom(2.0, 2.0, 5.0)
    assert (left, ratio) == (pytest.approx(1.7), pytest.approx(1.7 / 3.0))
    assert headroom(0.1, 2.0, 5.0) == (0.0, 0.0)
    assert math.isnan(headroom(math.nan, 2.0, 5.0)[0])
    chain = tared_chain()
    left, ratio = chain.headroom()
    assert left == pytest.approx(2.0 - SATURATION_V, abs=2e-3)
    assert ratio == pytest.approx((2.0 - SATURATION_V) / 3.0, abs=2e-3)


def test_the_diagnostics_say_why_the_sensor_is_blind_and_how_much_room_is_left():
    usable = AdcSettings(ADC, Source.DEVICE)
    chain = tared_chain()
    ok = adc_health(stats(), usable, chain, 1000.0, 0, 0)
    assert ok.level is Level.OK and ok.values["blind"] == "no"
    assert float(ok.values["detector_headroom_ratio"]) == pytest.approx(0.567, abs=2e-3)
    run(chain, [0.0] * 10, start=600)
    blind = adc_health(stats(), usable, chain, 1000.0, 0, 0)
    assert (blind.level, blind.message) == (Level.ERROR, BLIND_MESSAGE)
    assert blind.message.startswith("ambient light saturates the detector")
    assert blind.values["blind"] == "yes" and blind.values["blind_samples"] == "10"
    assert blind.values["detector_headroom_v"] == "0.000"
