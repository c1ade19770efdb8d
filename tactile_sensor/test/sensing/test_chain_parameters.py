"""The driver's parameters as the signal chain reads them (sensing/chain_parameters.py):
the mapping onto ChainConfig, the conflicts between values, and run-time changes."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from tactile_sensor.sensing.chain import ChainConfig
from tactile_sensor.sensing.chain_parameters import (
    FILTER_KEYS,
    RUNTIME_PARAMETERS,
    chain_config,
    configure_only_refusal,
    publish_period_ns,
    with_runtime_changes,
)
from tactile_sensor.sensing.errors import ParameterConflict, SensingError

#: The driver's parameters at their defaults (nodes/driver.py).
VALUES = {
    "port": "/dev/ttyACM0", "channel": 0, "adc_bits": 0, "reference_voltage": 0.0,
    "sample_rate": 1000.0, "filter_type": "savgol_mains", "filter.window": 0,
    "filter.cutoff_hz": 50.0, "filter.order": 2, "filter.min_cutoff_hz": 10.0,
    "filter.beta": 0.5, "filter.d_cutoff_hz": 1.0, "publish_rate": 0.0,
    "frame_id": "tactile_sensor", "calibration_source": "model", "calibration_file": "",
    "contact_on_force": 0.5, "contact_off_force": 0.3, "contact_debounce": 0.01,
    "tare_window": 0.5, "tare_max_spread": 0.05, "auto_tare": True,
    "rest_retare_time_constant": 10.0, "gain_tracking": True, "gain_warn_bound": 0.15}


def test_defaults_map_onto_the_chain_defaults():
    assert chain_config(VALUES) == ChainConfig()


@pytest.mark.parametrize("name", sorted(FILTER_KEYS))
def test_each_filter_gets_only_its_own_settings(name):
    config = chain_config({**VALUES, "filter_type": name, "filter.window": 11})
    assert set(config.filter_params) == set(FILTER_KEYS[name])
    config.validate()


def test_zero_device_settings_mean_the_chain_defaults():
    config = chain_config({**VALUES, "adc_bits": 10, "reference_voltage": 3.3})
    assert (config.adc_bits, config.vref_v) == (10, 3.3)


def test_contact_needs_hysteresis():
    with pytest.raises(ParameterConflict, match=r"'contact_off_force' = 0\.5 must be below"):
        chain_config({**VALUES, "contact_off_force": 0.5})


def test_a_file_calibration_needs_a_file():
    with pytest.raises(ParameterConflict, match="'calibration_file' is empty"):
        chain_config({**VALUES, "calibration_source": "file"})


@given(st.floats(1e-3, 100_000.0))
def test_the_publish_period_is_the_rate_inverted(rate):
    assert publish_period_ns({"publish_rate": rate}) == pytest.approx(1e9 / rate, abs=1.0)


@pytest.mark.parametrize(("rate", "period"), [(0.0, 0), (5e-324, 2**63 - 1)])
def test_no_rate_publishes_every_sample_and_a_vanishing_one_almost_never(rate, period):
    assert publish_period_ns({"publish_rate": rate}) == period


def test_device_parameters_cannot_change_while_configured():
    declared = set(VALUES)
    assert configure_only_refusal(["frame_id", "publish_rate"], declared, "/driver") is None
    assert configure_only_refusal(["not_declared"], declared, "/driver") is None
    reason = configure_only_refusal(["frame_id", "port", "channel"], declared, "/driver")
    assert reason is not None and reason.startswith(
        "Parameter 'port' is read on configure") and "ros2 lifecycle set /driver" in reason


def test_runtime_changes_pass_through_validation():
    seen = []

    def validate(name: str, value: object) -> object:
        seen.append(name)
        return float(value)  # type: ignore[arg-type]

    values = with_runtime_changes(VALUES, {"contact_on_force": "2", "port": "/dev/x"},
                                  validate)
    assert values["contact_on_force"] == 2.0 and values["port"] == "/dev/ttyACM0"
    assert seen == ["contact_on_force"] and VALUES["contact_on_force"] == 0.5
    assert "port" not in RUNTIME_PARAMETERS


def test_a_runtime_change_that_breaks_the_combination_is_refused():
    with pytest.raises(SensingError, match="hysteresis"):
        with_runtime_changes(VALUES, {"contact_off_force": 0.9}, lambda n, v: v)
    with pytest.raises(SensingError):
        with_runtime_changes(VALUES, {"filter.window": 1}, lambda n, v: v)
