"""A device's Health (hardware/health.py) as the /diagnostics message the nodes publish."""

from __future__ import annotations

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue

from tactile_sensor.hardware.health import Health


def diagnostic_array(name: str, hardware_id: str, health: Health,
                     stamp: Time) -> DiagnosticArray:
    status = DiagnosticStatus(name=name, hardware_id=hardware_id, level=bytes([health.level]),
                              message=health.message,
                              values=[KeyValue(key=k, value=v)
                                      for k, v in health.values.items()])
    array = DiagnosticArray(status=[status])
    array.header.stamp = stamp
    return array
