"""The XM430-W210 control table (Protocol 2.0, model number 1030) as data, with unit scales.

One source for the client (hardware/xm430.py) and the emulator (sim/xm430_emulator.py), so
both agree on addresses, sizes, access, initial values and ranges by construction. Values are
from the ROBOTIS e-Manual for the XM430-W210 (firmware 4x). Units: position 4096 pulses/rev
(0.088 deg), velocity 0.229 rpm, profile acceleration 214.577 rev/min^2, current 2.69 mA,
input voltage 0.1 V, temperature 1 degC.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import IntEnum

MODEL_NUMBER = 1030
MODEL_NAME = "XM430-W210"

RAD_PER_PULSE = 2.0 * math.pi / 4096.0
RAD_S_PER_VELOCITY_UNIT = 0.229 * 2.0 * math.pi / 60.0
RAD_S2_PER_ACCELERATION_UNIT = 214.577 * 2.0 * math.pi / 3600.0
A_PER_CURRENT_UNIT = 2.69e-3
V_PER_VOLTAGE_UNIT = 0.1
RETURN_DELAY_S_PER_UNIT = 2e-6

#: Baud Rate (8) item value -> bits per second.
BAUD_RATES: dict[int, int] = {
    0: 9_600, 1: 57_600, 2: 115_200, 3: 1_000_000, 4: 2_000_000,
    5: 3_000_000, 6: 4_000_000, 7: 4_500_000,
}


class OperatingMode(IntEnum):
    """Operating Mode (11) values."""

    CURRENT = 0
    VELOCITY = 1
    POSITION = 3
    EXTENDED_POSITION = 4
    CURRENT_BASED_POSITION = 5
    PWM = 16


class HardwareErrorBit(IntEnum):
    """Hardware Error Status (70) bits and the names the project uses for them."""

    INPUT_VOLTAGE = 0
    OVERHEATING = 2
    MOTOR_ENCODER = 3
    ELECTRICAL_SHOCK = 4
    OVERLOAD = 5


HARDWARE_ERROR_NAMES: dict[int, str] = {
    HardwareErrorBit.INPUT_VOLTAGE: "input_voltage",
    HardwareErrorBit.OVERHEATING: "overheating",
    HardwareErrorBit.MOTOR_ENCODER: "motor_encoder",
    HardwareErrorBit.ELECTRICAL_SHOCK: "electrical_shock",
    HardwareErrorBit.OVERLOAD: "overload",
}


def decode_hardware_error(value: int) -> frozenset[str]:
    """Names of the set bits of Hardware Error Status; unknown bits read as ``bitN``."""
    names = set()
    for bit in range(8):
        if value & (1 << bit):
            names.add(HARDWARE_ERROR_NAMES.get(bit, f"bit{bit}"))
    return frozenset(names)


def encode_hardware_error(names: frozenset[str] | set[str]) -> int:
    """Inverse of :func:`decode_hardware_error` (ValueError on an unknown name)."""
    lookup = {name: bit for bit, name in HARDWARE_ERROR_NAMES.items()}
    value = 0
    for name in names:
        if name in lookup:
            value |= 1 << lookup[name]
        elif name.startswith("bit") and name[3:].isdigit() and int(name[3:]) < 8:
            value |= 1 << int(name[3:])
        else:
            raise ValueError(f"unknown hardware error '{name}'; use one of "
                             f"{', '.join(sorted(lookup))}")
    return value


@dataclass(frozen=True)
class ControlItem:
    """One control-table item.

    ``minimum``/``maximum`` are the fixed range (violations are Data Range errors);
    ``limited_by`` names an item whose value bounds this one (violations are Data Limit
    errors), as Goal Current is bounded by Current Limit.
    """

    name: str
    address: int
    size: int
    writable: bool
    eeprom: bool
    initial: int
    minimum: int
    maximum: int
    signed: bool = False
    limited_by: str | None = None

    @property
    def end(self) -> int:
        return self.address + self.size

    def to_bytes(self, value: int) -> bytes:
        return (value & ((1 << (8 * self.size)) - 1)).to_bytes(self.size, "little")

    def from_bytes(self, data: bytes) -> int:
        return int.from_bytes(data, "little", signed=self.signed)


def _item(name: str, address: int, size: int, access: str, initial: int, minimum: int,
          maximum: int, *, signed: bool = False, limited_by: str | None = None) -> ControlItem:
    return ControlItem(name, address, size, access == "RW", address < 64, initial, minimum,
                       maximum, signed, limited_by)


_I32 = 2**31 - 1
ITEMS: tuple[ControlItem, ...] = (
    # EEPROM area (writable only while Torque Enable is 0)
    _item("Model Number", 0, 2, "R", MODEL_NUMBER, 0, 65535),
    _item("Model Information", 2, 4, "R", 0, 0, _I32),
    _item("Firmware Version", 6, 1, "R", 46, 0, 255),
    _item("ID", 7, 1, "RW", 1, 0, 252),
    _item("Baud Rate", 8, 1, "RW", 1, 0, 7),
    _item("Return Delay Time", 9, 1, "RW", 250, 0, 254),
    _item("Drive Mode", 10, 1, "RW", 0, 0, 13),
    _item("Operating Mode", 11, 1, "RW", 3, 0, 16),
    _item("Secondary(Shadow) ID", 12, 1, "RW", 255, 0, 255),
    _item("Protocol Type", 13, 1, "RW", 2, 1, 2),
    _item("Homing Offset", 20, 4, "RW", 0, -1_044_479, 1_044_479, signed=True),
    _item("Moving Threshold", 24, 4, "RW", 10, 0, 1023),
    _item("Temperature Limit", 31, 1, "RW", 80, 0, 100),
    _item("Max Voltage Limit", 32, 2, "RW", 160, 95, 160),
    _item("Min Voltage Limit", 34, 2, "RW", 95, 95, 160),
    _item("PWM Limit", 36, 2, "RW", 885, 0, 885),
    _item("Current Limit", 38, 2, "RW", 1193, 0, 1193),
    _item("Velocity Limit", 44, 4, "RW", 330, 0, 1023),
    _item("Max Position Limit", 48, 4, "RW", 4095, 0, 4095),
    _item("Min Position Limit", 52, 4, "RW", 0, 0, 4095),
    _item("Shutdown", 63, 1, "RW", 52, 0, 255),
    # RAM area
    _item("Torque Enable", 64, 1, "RW", 0, 0, 1),
    _item("LED", 65, 1, "RW", 0, 0, 1),
    _item("Status Return Level", 68, 1, "RW", 2, 0, 2),
    _item("Registered Instruction", 69, 1, "R", 0, 0, 1),
    _item("Hardware Error Status", 70, 1, "R", 0, 0, 255),
    _item("Velocity I Gain", 76, 2, "RW", 1920, 0, 16383),
    _item("Velocity P Gain", 78, 2, "RW", 100, 0, 16383),
    _item("Position D Gain", 80, 2, "RW", 0, 0, 16383),
    _item("Position I Gain", 82, 2, "RW", 0, 0, 16383),
    _item("Position P Gain", 84, 2, "RW", 800, 0, 16383),
    _item("Feedforward 2nd Gain", 88, 2, "RW", 0, 0, 16383),
    _item("Feedforward 1st Gain", 90, 2, "RW", 0, 0, 16383),
    _item("Bus Watchdog", 98, 1, "RW", 0, 0, 127),
    _item("Goal PWM", 100, 2, "RW", 0, -885, 885, signed=True, limited_by="PWM Limit"),
    _item("Goal Current", 102, 2, "RW", 0, -1193, 1193, signed=True,
          limited_by="Current Limit"),
    _item("Goal Velocity", 104, 4, "RW", 0, -1023, 1023, signed=True,
          limited_by="Velocity Limit"),
    _item("Profile Acceleration", 108, 4, "RW", 0, 0, 32767),
    _item("Profile Velocity", 112, 4, "RW", 0, 0, 32767),
    _item("Goal Position", 116, 4, "RW", 0, -1_048_575, 1_048_575, signed=True),
    _item("Realtime Tick", 120, 2, "R", 0, 0, 32767),
    _item("Moving", 122, 1, "R", 0, 0, 1),
    _item("Moving Status", 123, 1, "R", 0, 0, 255),
    _item("Present PWM", 124, 2, "R", 0, -885, 885, signed=True),
    _item("Present Current", 126, 2, "R", 0, -32768, 32767, signed=True),
    _item("Present Velocity", 128, 4, "R", 0, -_I32, _I32, signed=True),
    _item("Present Position", 132, 4, "R", 0, -_I32, _I32, signed=True),
    _item("Velocity Trajectory", 136, 4, "R", 0, -_I32, _I32, signed=True),
    _item("Position Trajectory", 140, 4, "R", 0, -_I32, _I32, signed=True),
    _item("Present Input Voltage", 144, 2, "R", 120, 0, 65535),
    _item("Present Temperature", 146, 1, "R", 30, 0, 255),
)

BY_NAME: dict[str, ControlItem] = {item.name: item for item in ITEMS}
BY_ADDRESS: dict[int, ControlItem] = {item.address: item for item in ITEMS}
#: Bytes a read may cover (the indirect area beyond the last item reads as zeros).
TABLE_SIZE = 662

#: The block ``read_state`` fetches in one sync read: Moving (122) .. Present Temperature (146).
STATE_BLOCK_START = BY_NAME["Moving"].address
STATE_BLOCK_END = BY_NAME["Present Temperature"].end


def item(name: str) -> ControlItem:
    """Look an item up by its e-Manual name (KeyError lists close names)."""
    try:
        return BY_NAME[name]
    except KeyError:
        raise KeyError(f"no control-table item '{name}' on the {MODEL_NAME}") from None


def decode_block(start: int, data: bytes) -> dict[str, int]:
    """Values of every item wholly inside ``data`` read from address ``start``."""
    out = {}
    for it in ITEMS:
        if it.address >= start and it.end <= start + len(data):
            out[it.name] = it.from_bytes(data[it.address - start: it.end - start])
    return out
