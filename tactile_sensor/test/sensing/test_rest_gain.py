"""Following the module at rest (sensing/rest_gain.py): the baseline re-tared while nothing
touches, a modulated module's optical gain against its calibration's, and the warning
past its bound."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tactile_sensor.hardware.adc_frame import DeviceInfo
from tactile_sensor.hardware.adc_reader import ConnectionState, ReaderStats
from tactile_sensor.hardware.adc_samples import Sample
from tactile_sensor.hardware.health import Level
from tactile_sensor.sensing.adc_health import adc_health
from tactile_sensor.sensing.adc_settings import resolve_adc
from tactile_sensor.sensing.calibration import Calibration
from tactile_sensor.sensing.chain import ChainConfig, SignalChain
from tactile_sensor.sensing.errors import SensingError
from tactile_sensor.sensing.modulation import modulation_of
from tactile_sensor.sensing.rest_gain import RestGain, RestRetare

CAL = Calibration.from_curve([0.0, 0.49], [0.0, 7.0], "test:linear")
RATE_HZ = 100.0  # a coarse rate keeps the windows short: 0.5 s is 50 samples
MODULATED = DeviceInfo(3, 1, 12, 5.0, 2000, "mock", True, 900, 0)
SHARE = modulation_of(MODULATED, 0).share  # type: ignore[union-attr]


# -- the core ------------------------------------------------------------------------------

@settings(max_examples=60, deadline=None)
@given(st.floats(0.5, 4.5), st.floats(0.3, 1.5), st.floats(0.05, 0.5))
def test_the_gain_is_the_drop_at_rest_against_the_first_one(reference_v, ratio, bound):
    gain = RestGain(bound)
    assert gain.observe(reference_v) == 1.0 and gain.reference_drop_v == reference_v
    assert gain.observe(reference_v * ratio) == pytest.approx(ratio)
    beyond = abs(ratio - 1.0) > bound
    assert gain.beyond_bound is beyond
    warning = gain.warning()
    assert (warning is not None) is beyond
    if warning is not None:
        assert "recalibrate" in warning and f"{ratio:.2f}" in warning
    gain.forget()
    assert gain.gain == 1.0 and gain.reference_drop_v is None


@pytest.mark.parametrize("drop_v", [0.0, -0.5, math.nan])
def test_a_drop_without_emitter_light_leaves_the_gain(drop_v):
    gain = RestGain()
    assert gain.observe(drop_v) == 1.0 and gain.reference_drop_v is None
    gain.observe(3.0)
    gain.observe(2.4)
    assert gain.observe(drop_v) == pytest.approx(0.8)


@pytest.mark.parametrize("bound", [0.0, 1.0, -0.1, math.nan, math.inf, True, "0.1"])
def test_a_bad_gain_bound_is_refused_in_one_sentence(bound):
    with pytest.raises(SensingError, match=r"^gain_warn_bound must be a fraction in \(0, 1\)"):
        RestGain(bound)


@pytest.mark.parametrize("tau", [-1.0, math.nan, math.inf, 3601.0, True, "10"])
def test_a_bad_retare_time_constant_is_refused_in_one_sentence(tau):
    with pytest.raises(SensingError, match=r"^rest_retare_time_constant must be 0 \(off\)"):
        RestRetare(tau, 1000.0, 500)


@settings(max_examples=40, deadline=None)
@given(st.floats(0.5, 100.0), st.floats(0.01, 1.0), st.booleans())
def test_the_baseline_follows_the_rest_with_its_time_constant(tau_s, step_v, down):
    step_v = -step_v if down else step_v
    retare = RestRetare(tau_s, 1000.0, 500)  # one step per 0.5 s window
    baseline = 2.0
    windows = round(2 * tau_s)  # one time constant
    for _ in range(windows):
        baseline = retare.follow(baseline, 2.0 + step_v)
    followed = (baseline - 2.0) / step_v
    assert followed == pytest.approx(1 - math.exp(-windows * 0.5 / tau_s), rel=1e-9)
    assert retare.retares == windows and retare.enabled


def test_a_time_constant_of_zero_is_off():
    assert not RestRetare(0.0, 1000.0, 500).enabled


@settings(max_examples=60, deadline=None)
@given(st.floats(0.5, 100.0), st.floats(-1.0, 1.0), st.floats(0.0, 0.05))
def test_a_level_that_fell_past_the_windows_spread_is_taken_at_once(tau_s, change_v, spread_v):
    """Less light raises the voltage, which no press does: taken at once; more light (or a
    rise within the window's own spread) only with the time constant."""
    retare = RestRetare(tau_s, 1000.0, 500)
    rest_v = 2.0 + change_v
    got = retare.follow(2.0, rest_v, spread_v)
    if rest_v - 2.0 > spread_v:
        assert got == rest_v
    else:
        assert got == pytest.approx(2.0 + retare.alpha * (rest_v - 2.0), abs=1e-12)
    assert retare.retares == 1


# -- the chain re-tares at rest ------------------------------------------------------------

def stock_chain(tau_s: float = 1.0, **kw) -> SignalChain:
    config = ChainConfig(rate_hz=RATE_HZ, filter_name="none", rest_retare_time_constant_s=tau_s,
                         **kw)
    return SignalChain(config, CAL)


def feed(chain: SignalChain, volts, start: int = 0) -> list:
    step_us = round(1e6 / RATE_HZ)
    return [chain.process(Sample(k & 0xFFFF, k * step_us, 0, (round(v / 5.0 * 4095),), 1))
            for k, v in enumerate(volts, start)]


def test_slow_light_is_followed_at_rest_and_read_as_force_without_it():
    """Daylight that brightens by 0.1 V over 60 s: 1.4 N of force if the baseline stayed."""
    light = list(2.0 - 0.1 * np.clip((np.arange(7000) - 500) / 6000.0, 0.0, 1.0))
    following, fixed = stock_chain(), stock_chain(0.0)
    last = feed(following, light)[-1]
    assert last.force_n < 0.1 and not last.contact
    assert following.baseline_v == pytest.approx(1.9, abs=0.005)
    assert following.rest_retares > 100
    last = feed(fixed, light)[-1]
    assert last.force_n == pytest.approx(1.4, abs=0.05) and last.contact
    assert fixed.baseline_v == pytest.approx(2.0, abs=0.002) and fixed.rest_retares == 0


def test_a_lamp_switched_off_at_rest_is_taken_within_a_window():
    """0.3 V less light at rest (the default 10 s time constant): the level is the
    baseline once a window holds no step, so the next press reads from zero."""
    chain = stock_chain(10.0)
    feed(chain, [2.0] * 200)
    assert chain.baseline_v == pytest.approx(2.0, abs=0.002)
    after = feed(chain, [2.3] * 60, 200)  # a window (50) and a tenth of one (5) on
    assert after[0].force_n == 0.0 and not after[0].contact
    assert chain.baseline_v == pytest.approx(2.3, abs=0.002)
    press = feed(chain, [2.3 - 0.07] * 5, 260)
    assert press[-1].force_n == pytest.approx(1.0, abs=0.02)


def test_noise_at_rest_does_not_push_the_baseline_up():
    """Only a fall past the window's own spread is taken at once: noise at rest leaves the
    baseline where the time constant's average puts it."""
    chain = stock_chain(10.0)
    noise = np.random.default_rng(3).normal(0.0, 0.01, 6000)
    readings = feed(chain, list(2.0 + noise))
    assert chain.rest_retares > 100
    assert chain.baseline_v == pytest.approx(2.0, abs=0.001)
    assert not any(r.contact for r in readings)


def test_a_held_press_is_never_taken_for_light():
    chain = stock_chain()
    feed(chain, [2.0] * 100)
    baseline, retares = chain.baseline_v, chain.rest_retares
    held = feed(chain, [2.0 - 0.07] * 3000, 100)  # 1 N for 30 s, thirty time constants
    assert chain.baseline_v == baseline and chain.rest_retares == retares
    assert held[-1].force_n == pytest.approx(1.0, abs=0.02) and held[-1].contact


def test_a_press_under_the_release_threshold_is_taken_for_light():
    """The limit of re-taring a stock module at rest, as docs/ambient.md states it."""
    chain = stock_chain()
    feed(chain, [2.0] * 100)
    light_touch = feed(chain, [2.0 - 0.014] * 1000, 100)  # 0.2 N, under contact_off 0.3 N
    assert light_touch[2].force_n == pytest.approx(0.2, abs=0.02)
    assert light_touch[-1].force_n < 0.01


def test_blind_samples_and_an_unsteady_level_are_never_a_rest():
    chain = stock_chain(tare_max_spread_v=0.01)
    feed(chain, [2.0] * 100)
    baseline, retares = chain.baseline_v, chain.rest_retares
    feed(chain, [0.1] * 500, 100)  # the detector at its rail
    assert chain.rest_retares == retares
    wobble = 1.99 + 0.008 * np.sign(np.sin(np.arange(1000) * 2 * math.pi / 20))
    feed(chain, list(wobble), 600)  # under the release threshold but not steady
    assert chain.rest_retares == retares and chain.baseline_v == baseline


def test_a_stock_module_has_no_optical_gain():
    chain = stock_chain()
    feed(chain, [2.0] * 100 + [2.5] * 1000)
    assert chain.optical_gain() is None and chain.gain_warning() is None


# -- a modulated module's optical gain -----------------------------------------------------

def modulated_chain(tracking: bool = True) -> SignalChain:
    chain = SignalChain(ChainConfig(rate_hz=RATE_HZ, adc_bits=12, vref_v=5.0, filter_name="none",
                                    rest_retare_time_constant_s=1.0, gain_tracking=tracking),
                        CAL)
    chain.set_modulation(modulation_of(MODULATED, 0))
    return chain


def feed_pairs(chain: SignalChain, drops_v, start: int = 0, room_v: float = 0.4) -> list:
    """The emitter's drops [V] as on/off code pairs under steady room light."""
    def code(volts: float) -> int:
        return round(volts / 5.0 * 4095)
    step_us = round(1e6 / RATE_HZ)
    off = 5.0 - room_v
    return [chain.process(Sample(k & 0xFFFF, k * step_us, 0,
                                 (code(off - d * SHARE), code(off)), 0))
            for k, d in enumerate(drops_v, start)]


@settings(max_examples=8, deadline=None)
@given(st.floats(0.6, 1.1))
def test_the_force_holds_as_the_emitter_dims_and_the_gain_is_reported(ratio):
    """Calibrated at a 3 V drop at rest; over 40 s the emitter comes to give ``ratio`` of its
    light: a press that gave 0.35 V of output (5 N) gives ``ratio`` x 0.35 V."""
    readings = {}
    drift = list(3.0 * (1 + (ratio - 1) * np.clip(np.arange(5000) / 4000, 0.0, 1.0)))
    for tracking in (True, False):
        chain = modulated_chain(tracking)
        feed_pairs(chain, [3.0] * 100)
        assert chain.optical_gain() == (1.0, pytest.approx(3.0, abs=0.01))
        feed_pairs(chain, drift, 100)  # 10 s at rest after it: 10 time constants
        press = feed_pairs(chain, [(3.0 + 0.35) * ratio] * 5, 5100)
        readings[tracking] = press[-1].force_n
        gain, reference = chain.optical_gain()  # type: ignore[misc]
        assert gain == pytest.approx(ratio, abs=0.01) and reference == pytest.approx(3.0, abs=0.01)
        assert (chain.gain_warning() is not None) is (abs(gain - 1) > 0.15)
    assert readings[True] == pytest.approx(5.0, abs=0.08)
    assert readings[False] == pytest.approx(5.0 * ratio, abs=0.08)


def test_a_modulated_modules_fall_keeps_the_time_constant():
    """Its level falls only as the emitter dims (it rejects the room): followed with the
    time constant, which averages its noisier signal into the gain, never taken at once."""
    chain = modulated_chain()
    feed_pairs(chain, [3.0] * 100)
    feed_pairs(chain, [2.1] * 60, 100)  # a window and a tenth after the emitter's fall
    gain, _ = chain.optical_gain()  # type: ignore[misc]
    assert 0.75 < gain < 0.99  # a step of the follow (alpha 0.39), not the fall's 0.70


def test_a_new_calibration_takes_the_optics_as_they_are():
    chain = modulated_chain()
    feed_pairs(chain, [3.0] * 100 + [2.1] * 1500)
    assert chain.optical_gain()[0] == pytest.approx(0.7, abs=0.01)  # type: ignore[index]
    assert "recalibrate" in (chain.gain_warning() or "")
    chain.set_calibration(CAL)  # e.g. the gripper's self-check publishes a corrected one
    assert chain.optical_gain() == (1.0, pytest.approx(2.1, abs=0.01))
    assert chain.gain_warning() is None
    press = feed_pairs(chain, [2.1 + 0.35] * 5, 1600)
    assert press[-1].force_n == pytest.approx(5.0, abs=0.08)


def diagnostics(chain: SignalChain, info: DeviceInfo = MODULATED):
    stats = ReaderStats(state=ConnectionState.CONNECTED, reason="", frames=1, crc_errors=0,
                        header_errors=0, sequence_gaps=0, dropped_frames=0, sequence_resets=0,
                        resyncs=0, bytes_received=0, bytes_discarded=0, connections=1,
                        last_frame_age_s=0.0, device_info=info)
    return adc_health(stats, resolve_adc(info), chain, RATE_HZ, 0, 0)


def test_the_diagnostics_warn_recalibrate_past_the_bound_and_report_the_gain():
    chain = modulated_chain()
    feed_pairs(chain, [3.0] * 100)
    health = diagnostics(chain)
    assert health.level == Level.OK and health.values["optical_gain"] == "1.000"
    assert health.values["optical_gain_reference_drop_v"] == "3.000"
    feed_pairs(chain, [2.1] * 1500, 100)
    health = diagnostics(chain)
    assert health.level == Level.WARN and "recalibrate" in health.message
    assert not health.message.endswith(".") and "; " not in health.message  # one sentence
    assert health.values["optical_gain"] == "0.700"
    assert int(health.values["rest_retares"]) > 10
    stock = stock_chain(0.0)
    feed(stock, [2.0] * 100)
    values = diagnostics(stock, DeviceInfo(2, 1, 12, 5.0, 1000, "avr")).values
    assert values["optical_gain"].startswith("not measured")
    assert values["rest_retares"].startswith("off")


@pytest.mark.parametrize(("values", "match"), [
    ({"rest_retare_time_constant_s": -1.0}, "rest_retare_time_constant"),
    ({"gain_warn_bound": 1.5}, "gain_warn_bound"),
    ({"gain_tracking": "yes"}, "gain_tracking must be true or false"),
])
def test_bad_rest_settings_are_refused_naming_them(values, match):
    with pytest.raises(SensingError, match=match):
        ChainConfig.from_mapping(values)


def test_the_rest_settings_change_while_samples_flow():
    chain = modulated_chain()
    feed_pairs(chain, [3.0] * 100 + [2.1] * 1500)
    chain.reconfigure(ChainConfig(rate_hz=RATE_HZ, adc_bits=12, vref_v=5.0, filter_name="none",
                                  rest_retare_time_constant_s=0.0, gain_tracking=False,
                                  gain_warn_bound=0.5))
    assert chain.gain_warning() is None  # 0.70 is inside +-50 %
    press = feed_pairs(chain, [2.1 + 0.35 * 0.7] * 5, 1600)
    assert press[-1].force_n == pytest.approx(3.5, abs=0.08)  # the gain no longer applied
    assert chain.rest_retares == 0
