from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from tactile_sensor.sensing.conversion import AdcConversion
from tactile_sensor.sensing.errors import SensingError


def test_full_scale_reads_the_reference():
    adc = AdcConversion(12, 5.0)
    assert adc.volts(4095) == pytest.approx(5.0)
    assert adc.volts(0) == 0.0
    assert AdcConversion(10, 3.3).volts(1023) == pytest.approx(3.3)


@given(st.integers(1, 16), st.floats(0.5, 20.0), st.data())
def test_counts_and_volts_round_trip(bits, vref, data):
    adc = AdcConversion(bits, vref)
    code = data.draw(st.integers(0, adc.full_scale_counts))
    assert adc.counts(adc.volts(code)) == code


def test_counts_clip_at_the_rails():
    adc = AdcConversion()
    assert adc.counts(-1.0) == 0
    assert adc.counts(9.0) == 4095


@pytest.mark.parametrize(("bits", "vref", "match"), [(0, 5.0, "adc_bits"), (17, 5.0, "adc_bits"),
                                                     (12.0, 5.0, "adc_bits"),
                                                     (12, 0.0, "vref_v"), (12, -3.3, "vref_v")])
def test_bad_adc_settings_are_refused(bits, vref, match):
    with pytest.raises(SensingError, match=match):
        AdcConversion(bits, vref)
