"""Counts -> volts from the device's word or the configuration: every rule and sentence."""

from __future__ import annotations

import pytest

from tactile_sensor.hardware.adc_frame import DeviceInfo
from tactile_sensor.sensing.adc_settings import Source, resolve_adc
from tactile_sensor.sensing.conversion import AdcConversion

UNO = DeviceInfo(2, 1, 10, 5.0, 1000, "avr")
PICO = DeviceInfo(2, 3, 12, 3.3, 1000, "rp2040")
V1 = DeviceInfo(1, 1)


@pytest.mark.parametrize("info", [UNO, PICO])
def test_nothing_configured_takes_the_device_s_word(info):
    adc = resolve_adc(info)
    assert adc.source is Source.DEVICE and adc.problem == ""
    assert adc.conversion == AdcConversion(info.adc_bits, info.vref_v)


def test_configured_values_that_agree_are_fine():
    adc = resolve_adc(PICO, 12, 3.3, channel=2, rate_hz=1000.0)
    assert adc.usable and adc.source is Source.DEVICE and adc.problem == ""


def test_a_contradicted_resolution_is_an_error_naming_both_values():
    adc = resolve_adc(UNO, configured_bits=12)
    assert not adc.usable and adc.source is Source.CONTRADICTED
    assert adc.problem == (
        "adc_bits is configured as 12 bit but the device sends 10-bit codes: no force is "
        "published; remove adc_bits from the configuration (default: from the device) or fix "
        "the firmware.")


def test_both_contradictions_are_named_in_one_sentence():
    adc = resolve_adc(PICO, 10, 5.0)
    assert adc.conversion is None
    assert "configured as 10 bit but the device sends 12-bit" in adc.problem
    assert "configured as 5 V but the device reports 3.3 V" in adc.problem
    assert "remove adc_bits and reference_voltage" in adc.problem
    assert adc.problem.endswith("fix the firmware.") and ". " not in adc.problem


def test_a_channel_the_device_does_not_send_is_an_error():
    adc = resolve_adc(UNO, channel=1)
    assert adc.conversion is None
    assert "reads channel 1 but the device sends 1 channel(s)" in adc.problem


def test_a_rate_mismatch_is_a_warning_with_the_fix():
    adc = resolve_adc(DeviceInfo(2, 1, 10, 5.0, 2000, "avr"), rate_hz=1000.0)
    assert adc.usable
    assert "samples at 500 Hz but sample_rate is 1000 Hz" in adc.problem
    assert "set sample_rate to 500" in adc.problem


def test_version_1_uses_the_configuration_with_a_warning():
    adc = resolve_adc(V1, 12, 5.0)
    assert adc.conversion == AdcConversion(12, 5.0) and adc.source is Source.CONFIGURED
    assert "does not state its resolution: using the configured 12 bit and 5 V" in adc.problem


def test_version_1_unconfigured_assumes_what_the_v1_sketch_sent():
    adc = resolve_adc(V1)
    assert adc.conversion == AdcConversion(10, 5.0) and adc.source is Source.ASSUMED
    assert "using the assumed 10 bit and 5 V" in adc.problem
