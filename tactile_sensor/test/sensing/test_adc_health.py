"""What the driver's diagnostics say about the ADC stream (sensing/adc_health.py): the
message's priority, the key values, the frame rate and the never-silent loss count."""

from __future__ import annotations

import dataclasses

import pytest
from hypothesis import given
from hypothesis import strategies as st

from tactile_sensor.hardware.adc_frame import DeviceInfo
from tactile_sensor.hardware.adc_reader import ConnectionState, ReaderStats
from tactile_sensor.hardware.health import Level
from tactile_sensor.sensing.adc_health import FrameRate, LossCounter, adc_health
from tactile_sensor.sensing.adc_settings import AdcSettings, Source
from tactile_sensor.sensing.array_chain import ArrayChain, Module
from tactile_sensor.sensing.calibration import Calibration
from tactile_sensor.sensing.chain import ChainConfig, SignalChain
from tactile_sensor.sensing.conversion import AdcConversion

USABLE = AdcSettings(AdcConversion(10, 3.3), Source.DEVICE)
CONTRADICTED = AdcSettings(None, Source.CONTRADICTED, "the device states 10 bits, not 12")
CALIBRATION = Calibration.from_curve([0.0, 0.5, 1.0], [0.0, 5.0, 10.0], "test")


def stats(state: ConnectionState = ConnectionState.CONNECTED, **changes: object) -> ReaderStats:
    base = ReaderStats(state=state, reason="opened /dev/ttyACM0", frames=1000, crc_errors=1,
                       header_errors=0, sequence_gaps=2, dropped_frames=3, sequence_resets=0,
                       resyncs=0, bytes_received=10_000, bytes_discarded=5, connections=1,
                       last_frame_age_s=0.001)
    return dataclasses.replace(base, **changes)


class Tared(SignalChain):
    """A chain in a given tare state (the tare itself is tested in test_tare.py)."""

    def __init__(self, baseline_v: float | None, calibration: Calibration | None) -> None:
        super().__init__(ChainConfig(), calibration)
        self._baseline = baseline_v

    @property
    def baseline_v(self) -> float | None:
        return self._baseline

    @property
    def tared(self) -> bool:
        return self._baseline is not None


READY = Tared(1.25, CALIBRATION)


@pytest.mark.parametrize(("reader", "adc", "chain", "lost", "level", "message"), [
    (stats(ConnectionState.DISCONNECTED, reason="unplugged"), USABLE, READY, 0, Level.ERROR,
     "unplugged"),
    (stats(ConnectionState.CONNECTING, reason="opening"), USABLE, READY, 0, Level.WARN,
     "opening"),
    (stats(awaiting_info=7), None, READY, 0, Level.WARN,
     "waiting for the device's info frame (7 sample(s) held)"),
    (stats(info_errors=1, last_info_error="0 channels"), None, READY, 0, Level.WARN,
     "waiting for the device's info frame (0 sample(s) held); its last was unusable: "
     "0 channels"),
    (stats(), CONTRADICTED, READY, 0, Level.ERROR, "the device states 10 bits, not 12"),
    (stats(), USABLE, Tared(None, CALIBRATION), 0, Level.WARN, "not tared yet"),
    (stats(), USABLE, Tared(1.25, None), 0, Level.WARN, "no calibration yet"),
    (stats(), USABLE, READY, 4, Level.WARN,
     "streaming; 4 ADC frame(s) lost since the last report"),
    (stats(), USABLE, READY, 0, Level.OK, "streaming"),
])
def test_the_message_names_the_first_problem(reader, adc, chain, lost, level, message):
    health = adc_health(reader, adc, chain, 1000.0, lost, 0)
    assert (health.level, health.message) == (level, message)


def test_key_values_of_a_ready_stream():
    info = DeviceInfo(2, 1, 10, 3.3, 1000, "uno")
    chain = Tared(1.25, CALIBRATION)
    chain.set_conversion(AdcConversion(10, 3.3))  # as the driver does on the info frame
    values = adc_health(stats(device_info=info), USABLE, chain, 998.04, 0, 997,
                        {"reading": 1, "wrench": 0}).values
    assert values["connection"] == "connected" and values["sample_rate_hz"] == "998.0"
    assert (values["frames"], values["frames_dropped"], values["crc_errors"]) == (
        "1000", "3", "1")
    assert values["baseline_v"] == "1.2500" and values["device"] == info.summary()
    assert (values["adc_settings"], values["adc_bits"], values["reference_voltage"]) == (
        "device", "10", "3.3")
    assert values["calibration_source"] == "test"
    assert values["full_scale_force_n"] == f"{CALIBRATION.full_scale_force_n:.4g}"
    assert values["readings_published"] == "997"
    assert values["ambient_ratio"].startswith("not measured")  # a stock module
    assert (values["reading_subscribers"], values["wrench_subscribers"]) == ("1", "0")
    assert all(isinstance(v, str) for v in values.values())


def test_key_values_before_the_device_spoke():
    values = adc_health(stats(), None, Tared(None, None), 0.0, 0, 0).values
    assert (values["device"], values["adc_settings"], values["adc_bits"],
            values["reference_voltage"], values["baseline_v"], values["full_scale_force_n"]
            ) == ("not stated yet", "not decided yet", "none", "none", "none", "none")


def test_an_array_reports_each_face_baseline():
    chain = ArrayChain(ChainConfig(), (Module(0, "front"), Module(1, "back")))
    values = adc_health(stats(), USABLE, chain, 1000.0, 0, 0).values
    assert (values["baseline_v.front"], values["baseline_v.back"]) == ("none", "none")


def test_the_frame_rate_is_measured_between_reports():
    now = [10.0]
    rate = FrameRate(lambda: now[0])
    now[0] = 10.5
    assert rate.update(500) == pytest.approx(1000.0)
    now[0] = 11.5
    assert rate.update(1500) == pytest.approx(1000.0)
    assert rate.update(100) == 0.0  # counters restarted: no negative rate, no division by 0


@given(st.lists(st.tuples(st.integers(0, 100), st.integers(0, 100)), max_size=20))
def test_every_lost_frame_is_reported_once(increments):
    loss = LossCounter()
    dropped = overflowed = reported = 0
    for d, o in increments:
        dropped, overflowed = dropped + d, overflowed + o
        new, warning = loss.update(stats(dropped_frames=dropped, backlog_dropped=overflowed))
        assert new == d + o
        assert (warning is None) == (new == 0)
        reported += new
    assert reported == dropped + overflowed


def test_the_loss_warning_says_where_frames_went():
    _, warning = LossCounter().update(stats(dropped_frames=3, backlog_dropped=2))
    assert warning is not None and warning.startswith(
        "5 ADC frame(s) lost (3 missing in the sequence, 2 dropped with a full backlog")
