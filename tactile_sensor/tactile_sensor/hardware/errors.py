"""Device faults as typed exceptions, so callers can react without parsing strings.

Every message is one sentence naming the cause and the fix; nodes show it as is.
"""

from __future__ import annotations


class HardwareError(Exception):
    """Base of every device fault raised by the hardware layer."""


class SerialPortError(HardwareError):
    """The serial port cannot be used as configured (bad port name, baud rate, option)."""


class FrameError(HardwareError):
    """A byte string is not one valid ADC frame (bad sync, header, length or CRC)."""
