"""The XM430's control table as the servo holds it: its bytes, with the e-Manual's access
and range rules, so a write gets the error the real servo answers (Access, Data Length, Data
Range, Data Limit) and changes nothing, or the item values to apply."""

from __future__ import annotations

from tactile_sensor.hardware import xm430_table as table
from tactile_sensor.hardware.xm430_table import OperatingMode
from tactile_sensor.sim.dynamixel_packets import StatusError
from tactile_sensor.sim.errors import SimError

_VALID_MODES = frozenset(int(m) for m in OperatingMode)


def baud_item_value(baudrate: int) -> int:
    """Baud Rate (8) item value for a bit rate (SimError if the servo has no such rate)."""
    for value, bps in table.BAUD_RATES.items():
        if bps == baudrate:
            return value
    rates = ", ".join(str(b) for b in table.BAUD_RATES.values())
    raise SimError(f"The XM430 has no {baudrate} bps setting; choose --baud from {rates}.")



class ControlTable:
    """The servo's bytes, with the e-Manual's access and range rules."""

    def __init__(self) -> None:
        self.data = bytearray(table.TABLE_SIZE)
        for item in table.ITEMS:
            self.set(item.name, item.initial)

    def get(self, name: str) -> int:
        item = table.BY_NAME[name]
        return item.from_bytes(bytes(self.data[item.address: item.end]))

    def set(self, name: str, value: int) -> None:
        item = table.BY_NAME[name]
        self.data[item.address: item.end] = item.to_bytes(int(value))

    def reset_area(self, eeprom: bool, keep: tuple[str, ...] = ()) -> None:
        for item in table.ITEMS:
            if item.eeprom == eeprom and item.name not in keep and item.writable:
                self.set(item.name, item.initial)

    def read(self, address: int, length: int) -> tuple[StatusError, bytes]:
        if length < 0 or address < 0 or address + length > table.TABLE_SIZE:
            return StatusError.ACCESS, b""
        return StatusError.NONE, bytes(self.data[address: address + length])

    def check_write(self, address: int, data: bytes) -> tuple[StatusError, dict[str, int]]:
        """Validate a write; returns the error or the item values to apply."""
        end = address + len(data)
        if not data or address < 0 or end > table.TABLE_SIZE:
            return StatusError.ACCESS, {}
        values: dict[str, int] = {}
        covered = 0
        for item in table.ITEMS:
            if item.end <= address or item.address >= end:
                continue
            if item.address < address or item.end > end:
                return StatusError.DATA_LENGTH, {}
            if not item.writable or (item.eeprom and self.get("Torque Enable")):
                return StatusError.ACCESS, {}
            values[item.name] = item.from_bytes(
                data[item.address - address: item.end - address])
            covered += item.size
        if covered != len(data):  # bytes of undefined addresses
            return StatusError.ACCESS, {}
        for name, value in values.items():
            error = self._check_value(table.BY_NAME[name], value, values)
            if error:
                return error, {}
        return StatusError.NONE, values

    def _check_value(self, item: table.ControlItem, value: int,
                     values: dict[str, int]) -> StatusError:
        if not item.minimum <= value <= item.maximum:
            return StatusError.DATA_RANGE
        if item.name == "Operating Mode" and value not in _VALID_MODES:
            return StatusError.DATA_RANGE
        if item.limited_by is not None:
            limit = values.get(item.limited_by, self.get(item.limited_by))
            if abs(value) > limit:
                return StatusError.DATA_LIMIT
        if item.name == "Goal Position" and values.get(
                "Operating Mode", self.get("Operating Mode")) == OperatingMode.POSITION:
            low, high = self.get("Min Position Limit"), self.get("Max Position Limit")
            if not low <= value <= high:
                return StatusError.DATA_LIMIT
        return StatusError.NONE
