"""The driver's parameters as the signal chain reads them, and which may change at run time.

Parameter names are the driver node's (nodes/driver.py declares them); values arrive here
already checked one by one, so what is left is their combination and the mapping onto
``ChainConfig``. Filter, tare, contact and publishing settings take effect at once; the rest
describe the device and its wiring and are read on configure, so changing one then is
refused with how to apply it (never silently ignored).
"""

from __future__ import annotations

from collections.abc import Callable, Collection, Iterable, Mapping
from typing import Any

from tactile_sensor.sensing.chain import ChainConfig
from tactile_sensor.sensing.errors import ParameterConflict

#: What 'ros2 param set' may change while the driver is configured.
RUNTIME_PARAMETERS = frozenset({
    "filter_type", "filter.window", "filter.cutoff_hz", "filter.order", "filter.min_cutoff_hz",
    "filter.beta", "filter.d_cutoff_hz", "contact_on_force", "contact_off_force",
    "contact_debounce", "tare_window", "tare_max_spread", "auto_tare", "publish_rate",
    "frame_id", "rest_retare_time_constant", "gain_tracking", "gain_warn_bound"})

#: The ``filter.*`` parameters each filter reads.
FILTER_KEYS = {"savgol": ("window",), "savgol_mains": ("window",), "moving_average": ("window",),
               "savgol_quadratic": ("window",), "savgol_quadratic_mains": ("window",),
               "butterworth": ("order", "cutoff_hz"),
               "one_euro": ("min_cutoff_hz", "beta", "d_cutoff_hz"), "none": ()}


def chain_config(values: Mapping[str, Any]) -> ChainConfig:
    """Parameter values -> the signal chain's configuration (validated there too)."""
    name = values["filter_type"]
    params = {key: values[f"filter.{key}"] for key in FILTER_KEYS[name]}
    if params.get("window") == 0:
        del params["window"]
    if values["contact_off_force"] >= values["contact_on_force"]:
        raise ParameterConflict(
            f"Parameter 'contact_off_force' = {values['contact_off_force']} must be below "
            f"'contact_on_force' = {values['contact_on_force']} (hysteresis).")
    if values["calibration_source"] == "file" and not values["calibration_file"]:
        raise ParameterConflict("Parameter 'calibration_file' is empty but calibration_source "
                                "is 'file'; give the calibration JSON's path.")
    return ChainConfig(
        rate_hz=values["sample_rate"], adc_bits=values["adc_bits"] or ChainConfig.adc_bits,
        vref_v=values["reference_voltage"] or ChainConfig.vref_v, channel=values["channel"],
        filter_name=name,
        filter_params=params, tare_window_s=values["tare_window"],
        tare_max_spread_v=values["tare_max_spread"], auto_tare=values["auto_tare"],
        contact_on_n=values["contact_on_force"], contact_off_n=values["contact_off_force"],
        contact_debounce_s=values["contact_debounce"],
        rest_retare_time_constant_s=values["rest_retare_time_constant"],
        gain_tracking=values["gain_tracking"], gain_warn_bound=values["gain_warn_bound"])


def publish_period_ns(values: Mapping[str, Any]) -> int:
    """Time between published readings [ns]; 0 publishes every sample. A rate so small
    that its period overflows publishes (almost) never rather than failing."""
    rate = values["publish_rate"]
    return int(min(1e9 / rate, 2**63 - 1)) if rate > 0 else 0


def configure_only_refusal(names: Iterable[str], declared: Collection[str],
                           node: str) -> str | None:
    """Why setting ``names`` now is refused (the first declared one read on configure only),
    or None when every one may change at run time."""
    fixed = [n for n in names if n in declared and n not in RUNTIME_PARAMETERS]
    if not fixed:
        return None
    return (f"Parameter '{fixed[0]}' is read on configure and cannot change while the "
            f"driver is configured; run 'ros2 lifecycle set {node} deactivate' and "
            f"'... cleanup', set it, then configure and activate again.")


def with_runtime_changes(values: Mapping[str, Any], changes: Mapping[str, Any],
                         validate: Callable[[str, Any], Any]) -> dict[str, Any]:
    """``values`` with the run-time ``changes`` applied, each through ``validate(name,
    value)``; raises what ``validate`` raises, or a SensingError when the combination does
    not hold (contact hysteresis, filter settings)."""
    updated = dict(values)
    for name, value in changes.items():
        if name in RUNTIME_PARAMETERS:
            updated[name] = validate(name, value)
    chain_config(updated).validate()
    return updated
