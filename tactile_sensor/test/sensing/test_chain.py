from __future__ import annotations

import math
import threading

import numpy as np
import pytest

from tactile_sensor.hardware.adc_samples import Sample, SampleBatch
from tactile_sensor.sensing.calibration import Calibration
from tactile_sensor.sensing.chain import ChainConfig, SignalChain
from tactile_sensor.sensing.conversion import AdcConversion
from tactile_sensor.sensing.errors import SensingError, TareError

ADC = AdcConversion()
CAL = Calibration.from_curve([0.0, 0.49], [0.0, 7.0], "test:linear")


def samples(volts, rate_hz=1000.0, start=0):
    for k, v in enumerate(volts, start):
        yield Sample(k & 0xFFFF, round(k * 1e6 / rate_hz), 0, (ADC.counts(v),), 1)


def run(chain, volts, start=0):
    return [chain.process(s) for s in samples(volts, start=start)]


def test_press_gives_output_force_and_contact():
    chain = SignalChain(ChainConfig(filter_name="moving_average"), CAL)
    rest = run(chain, [2.0] * 600)
    assert math.isnan(rest[100].output_v)  # NaN until the window is full
    assert chain.tared and chain.baseline_v == pytest.approx(ADC.volts(ADC.counts(2.0)))
    pressed = run(chain, [2.0 - 0.245] * 100, start=600)  # half of full scale
    last = pressed[-1]
    assert last.output_v == pytest.approx(0.245, abs=2e-3)
    assert last.force_n == pytest.approx(3.5, abs=0.03)
    assert last.contact and not last.saturated
    assert chain.calibration_source == "test:linear"
    beyond = run(chain, [1.0] * 20, start=700)[-1]
    assert beyond.saturated and beyond.force_n == 7.0


def test_every_sample_goes_through_the_filter():
    chain = SignalChain(ChainConfig(filter_name="moving_average", filter_params={"window": 4}))
    chain.set_baseline(2.0)
    out = [r.output_v for r in run(chain, [2.0, 2.0, 2.0, 2.0, 1.6, 1.6])]
    assert out[4] == pytest.approx(0.1, abs=2e-3)  # 1 of 4 samples moved by 0.4 V
    assert out[5] == pytest.approx(0.2, abs=2e-3)
    assert math.isnan(chain.last.force_n)  # no calibration yet
    assert chain.calibration_source == "none"


def test_tare_on_demand_and_refusal_while_pressing():
    chain = SignalChain(ChainConfig(auto_tare=False), CAL)
    with pytest.raises(TareError, match="only 0"):
        chain.tare()
    run(chain, [1.9] * 500)
    assert not chain.tared
    assert chain.tare().baseline_v == pytest.approx(1.9, abs=1e-3)
    run(chain, list(1.9 - 0.0005 * np.arange(500)), start=500)
    with pytest.raises(TareError, match="not at rest"):
        chain.tare()
    assert chain.baseline_v == pytest.approx(1.9, abs=1e-3)  # unchanged


def test_auto_tare_waits_for_rest():
    chain = SignalChain(ChainConfig(), CAL)
    run(chain, list(2.0 - 0.0005 * np.arange(800)))  # pressing from the start
    assert not chain.tared
    run(chain, [1.6] * 600, start=800)
    # the window may still hold the end of the ramp, within the spread bound (50 mV)
    assert chain.tared and chain.baseline_v == pytest.approx(1.6, abs=0.01)


def test_tare_from_another_thread_while_streaming():
    chain = SignalChain(ChainConfig(auto_tare=False), CAL)
    run(chain, [2.0] * 500)
    errors = []

    def tare_many():
        for _ in range(50):
            try:
                chain.tare()
            except TareError as exc:  # pragma: no cover - would fail the test below
                errors.append(exc)

    thread = threading.Thread(target=tare_many)
    thread.start()
    run(chain, [2.0] * 5000, start=500)
    thread.join()
    assert not errors and chain.tared


def test_channel_mismatch_is_a_sensing_error():
    chain = SignalChain(ChainConfig(channel=1))
    with pytest.raises(SensingError, match="channel"):
        chain.process(Sample(0, 0, 0, (100,), 1))


@pytest.mark.parametrize(("values", "match"), [
    ({"filter": "savgol"}, "Unknown signal-chain setting"),
    ({"filter_name": "kalman"}, "Unknown filter"),
    ({"adc_bits": 40}, "adc_bits"),
    ({"contact_on_n": 0.1, "contact_off_n": 0.2}, "contact_off_n"),
    ({"tare_window_s": -1.0}, "tare_window_s"),
    ({"channel": 9}, "channel"),
    ({"auto_tare": "yes"}, "auto_tare"),
    ({"rate_hz": 0.0}, "sample rate"),
])
def test_bad_configuration_names_the_parameter(values, match):
    with pytest.raises(SensingError, match=match):
        ChainConfig.from_mapping(values)


def test_bad_baseline_is_refused():
    with pytest.raises(TareError, match="finite"):
        SignalChain().set_baseline(float("nan"))


# -- settings changed while running (the driver's 'ros2 param set') -----------------------

def test_reconfigure_changes_contact_thresholds_and_keeps_the_baseline():
    chain = SignalChain(ChainConfig(filter_name="none"), CAL)
    run(chain, [2.0] * 600)
    baseline = chain.baseline_v
    assert run(chain, [2.0 - 0.07] * 50, start=600)[-1].contact  # 1 N > 0.5 N
    chain.reconfigure(ChainConfig(filter_name="none", contact_on_n=2.0, contact_off_n=1.5))
    assert not run(chain, [2.0 - 0.07] * 50, start=650)[-1].contact  # 1 N < 1.5 N
    assert run(chain, [2.0 - 0.21] * 50, start=700)[-1].contact  # 3 N > 2 N
    assert chain.baseline_v == baseline and chain.config.contact_on_n == 2.0


def test_reconfigure_swaps_the_filter_and_the_tare_window():
    chain = SignalChain(ChainConfig(filter_name="moving_average", filter_params={"window": 4}))
    chain.set_baseline(2.0)
    chain.reconfigure(ChainConfig(filter_name="none", tare_window_s=0.2))
    out = run(chain, [2.0, 1.6])
    assert out[1].output_v == pytest.approx(0.4, abs=2e-3)  # unfiltered now
    run(chain, [1.9] * 200, start=2)
    assert chain.tare().samples == 200  # the new 0.2 s window at 1 kHz


@pytest.mark.parametrize(("change", "message"), [
    ({"adc_bits": 10}, "adc_bits cannot change while samples flow"),
    ({"channel": 1, "rate_hz": 500.0}, "rate_hz, channel cannot change"),
    ({"filter_name": "kalman"}, "kalman"),
    ({"contact_on_n": -1.0}, "contact"),
])
def test_reconfigure_refuses_what_cannot_change_or_is_invalid(change, message):
    chain = SignalChain(ChainConfig(), CAL)
    with pytest.raises(SensingError, match=message):
        chain.reconfigure(ChainConfig(**change))
    assert chain.config == ChainConfig()


@pytest.mark.parametrize("filter_name", ["savgol", "butterworth", "one_euro"])
def test_a_batch_gives_what_the_same_samples_give_one_by_one(filter_name):
    rng = np.random.default_rng(3)
    volts = np.concatenate([np.full(700, 2.0), 2.0 - np.linspace(0, 0.4, 300)])
    volts += rng.normal(0, 0.002, len(volts))
    one = SignalChain(ChainConfig(filter_name=filter_name), CAL)
    expected = run(one, volts)
    batched = SignalChain(ChainConfig(filter_name=filter_name), CAL)
    stream = list(samples(volts))
    got = [r for k in range(0, len(stream), 37)
           for r in batched.process_batch(SampleBatch.of(stream[k:k + 37]))]
    assert got == expected  # NaNs compare as the same object: the same Reading tuples
    assert batched.last == expected[-1] and batched.tared


def test_a_batch_without_our_channel_is_refused_naming_it():
    chain = SignalChain(ChainConfig(channel=1))
    with pytest.raises(SensingError, match="1 channel\\(s\\) but the chain reads channel 1"):
        chain.process_batch(SampleBatch.of(samples([2.0] * 3)))
