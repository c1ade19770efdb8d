"""The modulated module's on/off pair: the detector's levels, the chain's signal, blindness."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tactile_sensor.hardware.adc_frame import DeviceInfo
from tactile_sensor.hardware.adc_reader import ConnectionState, ReaderStats
from tactile_sensor.hardware.adc_samples import Sample
from tactile_sensor.physics.detector import response_tau_s
from tactile_sensor.sensing.adc_health import adc_health
from tactile_sensor.sensing.adc_settings import resolve_adc
from tactile_sensor.sensing.chain import ChainConfig, SignalChain
from tactile_sensor.sensing.errors import SensingError
from tactile_sensor.sensing.modulation import (
    DETECTOR_TAU_S,
    Modulation,
    PairSignal,
    emitter_levels,
    modulation_of,
)

MODULATED = DeviceInfo(3, 1, 12, 5.0, 2000, "mock", True, 900, 0)


def test_the_chain_and_the_physics_take_the_same_detector():
    assert pytest.approx(response_tau_s(), rel=1e-12) == DETECTOR_TAU_S


def simulated_levels(settle_s: float, period_s: float, tau_s: float) -> tuple[float, float]:
    """The detector's first-order response to the emitter switched on for the first half
    of every period, stepped exactly over many periods, sampled ``settle_s`` after each
    switch."""
    x, on, off = 0.0, 0.0, -1.0
    half = period_s / 2
    for _ in range(100_000):
        last = off
        x = 1.0 - (1.0 - x) * math.exp(-settle_s / tau_s)
        on = x
        x = 1.0 - (1.0 - x) * math.exp(-(half - settle_s) / tau_s)
        x *= math.exp(-settle_s / tau_s)
        off = x
        x *= math.exp(-(half - settle_s) / tau_s)
        if abs(off - last) < 1e-14:
            break
    return on, off


@settings(max_examples=60, deadline=None)
@given(st.floats(0.2e-3, 20e-3), st.floats(0.05, 1.0), st.floats(0.05e-3, 2e-3))
def test_the_levels_are_the_periodic_steady_state_of_the_detectors_response(period_s, part,
                                                                             tau_s):
    settle_s = part * period_s / 2
    on, off = emitter_levels(settle_s, period_s, tau_s)
    assert (on, off) == pytest.approx(simulated_levels(settle_s, period_s, tau_s), abs=1e-9)
    assert 0.0 <= off <= 1.0 and on + off == pytest.approx(1.0)


def test_a_long_settle_reads_the_emitter_fully_and_a_short_one_loses_it():
    assert emitter_levels(5e-3, 10e-3) == pytest.approx((1.0, 0.0), abs=1e-5)
    # the reference firmware's Uno: 500 Hz, 788 us after each switch
    assert Modulation(2000, 788, 112, 0, 1).share == pytest.approx(0.711, abs=1e-3)
    # each later channel is sampled later, so it keeps more
    shares = [Modulation(2000, 676, 28, c, 8).share for c in range(8)]
    assert shares == sorted(shares) and shares[0] == pytest.approx(0.624, abs=1e-3)


@pytest.mark.parametrize(("settle_s", "period_s", "tau_s"), [
    (0.0, 2e-3, DETECTOR_TAU_S), (1.1e-3, 2e-3, DETECTOR_TAU_S), (0.5e-3, 2e-3, 0.0)])
def test_a_timing_that_is_not_half_on_half_off_is_refused(settle_s, period_s, tau_s):
    with pytest.raises(SensingError, match="within half the period"):
        emitter_levels(settle_s, period_s, tau_s)


def test_the_device_says_whether_and_how_it_modulates():
    assert modulation_of(DeviceInfo(2, 1, 10, 5.0, 1000, "avr"), 0) is None
    assert modulation_of(MODULATED, 0) == Modulation(2000, 900, 0, 0, 1)
    with pytest.raises(SensingError, match="within half the period"):
        modulation_of(MODULATED._replace(settle_us=1500), 0)
    with pytest.raises(SensingError, match="keeps -14 % of the emitter's light"):
        modulation_of(MODULATED._replace(settle_us=200), 0)


def test_the_pair_signal_is_the_emitters_drop_scaled_back_and_averages_the_off_samples():
    modulation = Modulation(2000, 900, 0, 0, 1)
    pair = PairSignal(modulation, 5.0)
    share = modulation.share
    assert pair.signal(2.0, 2.0 + 1.5 * share) == pytest.approx(3.5)
    # the off sample half a period before and after the on sample, averaged
    assert pair.signal(2.0, 2.0 + 2.5 * share) == pytest.approx(5.0 - 2.0)
    pair.reset()
    assert pair.signal(2.0, 2.0 + 2.5 * share) == pytest.approx(2.5)


def counts_of(volts: float) -> int:
    return round(volts / 5.0 * 4095)


def feed(chain: SignalChain, pairs: list[tuple[float, float]], start: int = 0) -> list:
    return [chain.process(Sample(k, (start + k) * 2000, 0, (counts_of(on), counts_of(off)), 0))
            for k, (on, off) in enumerate(pairs)]


def modulated_chain() -> SignalChain:
    chain = SignalChain(ChainConfig(rate_hz=500.0, adc_bits=12, vref_v=5.0, filter_name="none",
                                    tare_window_s=0.1))
    chain.set_modulation(modulation_of(MODULATED, 0))
    return chain


def test_a_modulated_chain_reads_the_same_output_whatever_the_steady_light():
    share = modulation_of(MODULATED, 0).share  # type: ignore[union-attr]
    outputs = []
    for ambient_v in (0.0, 0.5, 1.0):  # the room's light lowers both samples alike
        chain = modulated_chain()
        rest = [(4.5 - ambient_v - 3.0 * share, 4.5 - ambient_v)] * 120
        press = [(4.5 - ambient_v - 3.5 * share, 4.5 - ambient_v)] * 5
        readings = feed(chain, rest + press)
        assert chain.tared and not readings[-1].blind
        outputs.append(readings[-1].output_v)
    assert outputs == pytest.approx([0.5] * 3, abs=3e-3)


def test_a_plain_chain_reads_the_on_code_and_a_modulated_one_ignores_a_light_step():
    share = modulation_of(MODULATED, 0).share  # type: ignore[union-attr]
    rest = [(4.5 - 3.0 * share, 4.5)] * 120
    step = [(4.5 - 3.0 * share - 1.0, 3.5)] * 5  # a lamp switched on: both samples fall 1 V
    plain = SignalChain(ChainConfig(rate_hz=500.0, adc_bits=12, vref_v=5.0, filter_name="none",
                                    tare_window_s=0.1))
    modulated = modulated_chain()
    assert feed(plain, rest + step)[-1].output_v == pytest.approx(1.0, abs=3e-3)
    assert feed(modulated, rest + step)[-1].output_v == pytest.approx(0.0, abs=3e-3)


def test_an_on_or_off_sample_at_the_rail_is_blind_and_sight_returns_with_the_light():
    chain = modulated_chain()
    share = modulation_of(MODULATED, 0).share  # type: ignore[union-attr]
    rest = [(4.5 - 3.0 * share, 4.5)] * 120
    feed(chain, rest)
    assert chain.tared
    blind = feed(chain, [(0.1, 2.0)] * 3, 120)  # sunlight: the on sample at the rail
    assert all(r.blind and math.isnan(r.force_n) for r in blind) and chain.blind
    assert chain.headroom()[0] == 0.0
    after = feed(chain, rest[:8], 123)
    assert not after[-1].blind and after[-1].output_v == pytest.approx(0.0, abs=3e-3)
    assert chain.headroom()[0] == pytest.approx(4.5 - 3.0 * share - 0.3, abs=3e-3)


def test_switching_modulation_forgets_the_filter_and_tare_window_and_off_restores_one_code():
    chain = modulated_chain()
    feed(chain, [(2.0, 4.5)] * 10)
    chain.set_modulation(modulation_of(MODULATED, 0))  # the same: nothing forgotten
    assert chain.modulation == Modulation(2000, 900, 0, 0, 1)
    chain.set_modulation(None)
    assert chain.modulation is None
    reading = chain.process(Sample(0, 0, 0, (counts_of(1.5),), 0))
    assert reading.voltage_v == pytest.approx(1.5, abs=2e-3)


def test_a_modulated_frame_without_its_off_codes_names_the_channel():
    chain = modulated_chain()
    with pytest.raises(SensingError, match="channel"):
        chain.process(Sample(0, 0, 0, (counts_of(1.5),), 0))


@settings(max_examples=30, deadline=None)
@given(st.floats(0.0, 1.5), st.floats(0.3, 1.2))
def test_steady_light_never_reaches_the_signal(ambient_v, drop_v):
    modulation = modulation_of(MODULATED, 0)
    assert modulation is not None
    pair = PairSignal(modulation, 5.0)
    off = 4.9 - ambient_v
    on = off - drop_v * modulation.share
    values = [pair.signal(on, off) for _ in range(3)]
    assert np.allclose(values, 5.0 - drop_v)


def test_the_room_light_is_measured_from_the_emitter_off_sample():
    """The off sample still shows some emitter light (the detector's response); what is
    left is the room's, reported in the ratio the light scenes use."""
    chain = modulated_chain()
    on_share, off_share = modulation_of(MODULATED, 0).levels  # type: ignore[union-attr]
    assert chain.ambient() is not None and math.isnan(chain.ambient()[0])  # no sample yet
    room_v, emitter_v = 0.6, 3.0
    feed(chain, [(5.0 - room_v - emitter_v * on_share, 5.0 - room_v - emitter_v * off_share)]
         * 120)
    drop, ratio = chain.ambient()  # type: ignore[misc]
    assert (drop, ratio) == (pytest.approx(room_v, abs=3e-3), pytest.approx(0.2, abs=2e-3))
    assert SignalChain().ambient() is None  # a stock module has no emitter-off sample


def test_the_diagnostics_report_the_room_light_of_a_modulated_module():
    chain = modulated_chain()
    on_share, off_share = modulation_of(MODULATED, 0).levels  # type: ignore[union-attr]
    feed(chain, [(4.4 - 3.0 * on_share, 4.4 - 3.0 * off_share)] * 120)
    reader = ReaderStats(state=ConnectionState.CONNECTED, reason="", frames=120, crc_errors=0,
                         header_errors=0, sequence_gaps=0, dropped_frames=0,
                         sequence_resets=0, resyncs=0, bytes_received=0, bytes_discarded=0,
                         connections=1, last_frame_age_s=0.0, device_info=MODULATED)
    values = adc_health(reader, resolve_adc(MODULATED), chain, 500.0, 0, 0).values
    assert (values["ambient_v"], values["ambient_ratio"]) == ("0.600", "0.200")


def test_an_array_chain_reads_every_modules_emitter_light_from_its_own_pair():
    from tactile_sensor.sensing.array_chain import ArrayChain, parse_modules

    info = MODULATED._replace(channels=2, read_us=50)
    chain = ArrayChain(ChainConfig(rate_hz=500.0, adc_bits=12, vref_v=5.0,
                                   filter_name="none"), parse_modules("0:front,1:back"))
    chain.set_modulation(modulation_of(info, 0))
    shares = [Modulation(2000, 900, 50, c, 2).share for c in (0, 1)]
    assert chain.modulation == Modulation(2000, 900, 50, 0, 2) and shares[0] < shares[1]
    emitter = (3.0, 2.0)  # each module's emitter drop; the room's light 0.5 V on both
    on = [4.5 - d * s for d, s in zip(emitter, shares, strict=True)]
    counts = (*map(counts_of, on), counts_of(4.5), counts_of(4.5))
    reading = chain.process(Sample(0, 0, 0, counts, 0))
    assert reading.voltages_v == pytest.approx((2.0, 3.0), abs=3e-3)
    chain.set_modulation(None)
    assert chain.modulation is None
    assert chain.process(Sample(1, 2000, 0, counts, 0)).voltages_v == pytest.approx(
        tuple(on), abs=2e-3)
