"""The gripper servo's health: a latched hardware error first, then the bus, else ready."""

from __future__ import annotations

from tactile_sensor.hardware.health import Health, Level
from tactile_sensor.hardware.xm430 import ServoState


def xm430_health(hardware_error: frozenset[str], comm_error: str,
                 state: ServoState | None) -> Health:
    """``hardware_error``: the latched bits; ``comm_error``: why the servo does not answer
    ("" when it does); ``state``: its latest sample (no key values before the first)."""
    if hardware_error:
        level, message = Level.ERROR, "hardware error: " + ", ".join(sorted(hardware_error))
    elif comm_error:
        level, message = Level.ERROR, comm_error
    else:
        level, message = Level.OK, "ready"
    values: dict[str, str] = {}
    if state is not None:
        values = {"position_rad": f"{state.position_rad:.4f}",
                  "current_a": f"{state.current_a:.3f}",
                  "input_voltage_v": f"{state.input_voltage_v:.1f}",
                  "temperature_c": f"{state.temperature_c:.0f}",
                  "hardware_error": ",".join(sorted(hardware_error)) or "none"}
    return Health(level, message, values)
