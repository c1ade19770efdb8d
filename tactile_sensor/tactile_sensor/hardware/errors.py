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


# -- Dynamixel servo (hardware/xm430.py) -------------------------------------------------


class DynamixelError(HardwareError):
    """Base of every fault talking to a Dynamixel servo."""


class PortOpenError(DynamixelError):
    """The servo's serial port cannot be opened (missing, busy, unsupported baud rate)."""


class PortLost(DynamixelError):
    """The servo's serial port failed while in use (adapter unplugged, device closed)."""


class CommunicationTimeout(DynamixelError):
    """No status packet came back in time (power, id, baud rate or cable)."""


class CorruptPacket(DynamixelError):
    """A status packet arrived damaged or incomplete (noise, baud mismatch, two masters)."""


class ServoRejected(DynamixelError):
    """The servo answered with an error code (instruction, CRC, range, length, limit, access).

    ``code`` is the low seven bits of the status packet's error byte.
    """

    def __init__(self, message: str, code: int) -> None:
        super().__init__(message)
        self.code = code


class ServoHardwareError(DynamixelError):
    """The servo latched a hardware error (the Alert bit); ``bits`` names the causes,
    e.g. ``frozenset({"overload"})``. Reboot clears it once the cause is gone."""

    def __init__(self, message: str, bits: frozenset[str]) -> None:
        super().__init__(message)
        self.bits = bits


class ModelMismatch(DynamixelError):
    """The servo at the configured id is not the expected model."""


class InvalidServoValue(DynamixelError):
    """A requested value cannot be represented in the servo's control table."""
