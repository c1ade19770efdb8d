"""A typed client for one Dynamixel XM430-W210 over dynamixel-sdk (Protocol 2.0).

The ROBOTIS SDK reports every call as ``(value, comm_result, error)``; this module wraps
that once (:meth:`Xm430Client._check`) and raises the hardware layer's typed exceptions
instead, with messages that name the cause and the fix. Values cross the API in SI units
(rad, rad/s, rad/s^2, A, V, degC); the raw control-table units stay inside.

Two deliberate departures from the stock SDK usage, both for the control loop:

* ``read_state`` issues one Sync Read of Moving..Present Temperature (122..146) through the
  packet handler directly, because ``GroupSyncRead`` discards the status error byte; the
  Alert bit in that byte tells us when to fetch Hardware Error Status (a second
  transaction only while a fault is latched).
* The port's pyserial timeout is set to 2 ms instead of 0, so the SDK's receive loop blocks
  in ``select`` instead of spinning a CPU core; the SDK's own packet timeout still applies
  and is set from ``timeout_s``.
"""

from __future__ import annotations

import contextlib
import itertools
import math
import termios
import threading
import time
from dataclasses import dataclass
from types import TracebackType

import serial
from dynamixel_sdk import PacketHandler, PortHandler
from dynamixel_sdk.robotis_def import (
    COMM_PORT_BUSY,
    COMM_RX_CORRUPT,
    COMM_RX_TIMEOUT,
    COMM_SUCCESS,
)

from tactile_sensor.hardware import xm430_table as table
from tactile_sensor.hardware.errors import (
    CommunicationTimeout,
    CorruptPacket,
    DynamixelError,
    InvalidServoValue,
    ModelMismatch,
    PortLost,
    PortOpenError,
    ServoHardwareError,
    ServoRejected,
)
from tactile_sensor.hardware.xm430_table import OperatingMode

_STATUS_MEANING = {
    1: ("could not process the instruction", "check the instruction's preconditions"),
    2: ("does not know the instruction or its form", "check the instruction and its length"),
    3: ("received a damaged packet (CRC error)", "check the cable and the baud rate"),
    4: ("was given a value outside the item's range", "use a value inside the range"),
    5: ("was given data of the wrong length for the item", "write the whole item"),
    6: ("was given a value beyond a limit item (e.g. Current Limit)",
        "lower the value or raise the limit"),
    7: ("refused access (read-only item, or EEPROM while torque is on)",
        "turn torque off before writing EEPROM items"),
}


@dataclass(frozen=True)
class ServoState:
    """Present state from one Sync Read (SI units)."""

    position_rad: float
    velocity_rad_s: float
    current_a: float
    input_voltage_v: float
    temperature_c: float
    moving: bool
    hardware_error: frozenset[str]
    #: Position Trajectory (where the profile generator currently is) [rad].
    trajectory_position_rad: float = 0.0


#: What pyserial raises when the device goes away mid-call (termios.error from a flush).
PORT_FAILURES = (serial.SerialException, OSError, termios.error)


class _QuietPortHandler(PortHandler):
    """PortHandler whose reads block briefly instead of spinning, with our packet timeout."""

    def __init__(self, port_name: str, timeout_s: float) -> None:
        super().__init__(port_name)
        self.timeout_ms = timeout_s * 1000.0

    def setupPort(self, cflag_baud: int) -> bool:
        ok = super().setupPort(cflag_baud)
        if ok:
            self.ser.timeout = 0.002
        return ok

    def setPacketTimeout(self, packet_length: int) -> None:
        self.packet_start_time = self.getCurrentTime()
        self.packet_timeout = self.tx_time_per_byte * packet_length + self.timeout_ms

    # pyserial raises when the device goes away (a pulled U2D2, a mock that exited): the SDK
    # would let that escape from every call, so it becomes the typed PortLost here, and
    # the SDK's busy flag is cleared so the next call can report the same again.
    def readPort(self, length: int) -> bytes:
        try:
            return super().readPort(length)
        except PORT_FAILURES as exc:
            raise self._lost(exc) from None

    def writePort(self, packet: list[int]) -> int:
        try:
            return super().writePort(packet)
        except PORT_FAILURES as exc:
            raise self._lost(exc) from None

    def clearPort(self) -> None:
        try:
            super().clearPort()
        except PORT_FAILURES as exc:
            raise self._lost(exc) from None

    def _lost(self, exc: BaseException) -> PortLost:
        self.is_using = False
        return PortLost(f"The serial port {self.port_name} failed ({exc}): the adapter was "
                        "unplugged or the device closed; reconnect it, then reconfigure.")


def _raw(name: str, value_si: float, scale: float) -> int:
    item = table.item(name)
    if not math.isfinite(value_si):
        raise InvalidServoValue(f"{name} must be a finite number, not {value_si}; "
                                "give a real value.")
    raw = round(value_si / scale)
    if not item.minimum <= raw <= item.maximum:
        low, high = item.minimum * scale, item.maximum * scale
        raise InvalidServoValue(f"{name} {value_si:g} is outside the XM430's range "
                                f"{low:g}..{high:g} (SI units); choose a value inside it.")
    return raw


class Xm430Client:
    """One XM430-W210 on a serial port; use as a context manager or call connect/close."""

    def __init__(self, port: str, baudrate: int = 57_600, servo_id: int = 1,
                 timeout_s: float = 0.034) -> None:
        if not 0 <= servo_id <= 252:
            raise InvalidServoValue(f"Servo id {servo_id} is outside 0..252; "
                                    "configure the id the servo really has.")
        if timeout_s <= 0:
            raise InvalidServoValue(f"timeout_s must be positive, not {timeout_s}; "
                                    "use e.g. 0.034 s (two USB latency periods).")
        self.port = port
        self.baudrate = baudrate
        self.servo_id = servo_id
        self.timeout_s = timeout_s
        self.firmware_version: int | None = None
        self._port: _QuietPortHandler | None = None
        self._ph = PacketHandler(2.0)
        self._lock = threading.Lock()

    # -- connection ------------------------------------------------------------------------

    def connect(self) -> None:
        """Open the port, ping the servo and check it is an XM430-W210."""
        if self._port is not None:
            return
        if baudrate_item(self.baudrate) is None:
            rates = ", ".join(str(b) for b in table.BAUD_RATES.values())
            raise PortOpenError(f"{self.baudrate} bps is not an XM430 baud rate; choose "
                                f"one of {rates}.")
        port = _QuietPortHandler(self.port, self.timeout_s)
        try:
            if not port.setBaudRate(self.baudrate):
                raise PortOpenError(f"The serial port {self.port} rejects {self.baudrate} bps;"
                                    " choose a standard Dynamixel baud rate.")
        except (serial.SerialException, OSError) as exc:
            raise PortOpenError(f"Cannot open {self.port} ({exc}): check the device path, "
                                "that the adapter is plugged in and no other program holds "
                                "it.") from None
        self._port = port
        try:
            model, firmware = self.ping()
            if model != table.MODEL_NUMBER:
                raise ModelMismatch(
                    f"Servo id {self.servo_id} on {self.port} is model {model}, not the "
                    f"{table.MODEL_NAME} ({table.MODEL_NUMBER}); check the id or the "
                    "configured model.")
            self.firmware_version = firmware
        except DynamixelError:
            self.close()
            raise

    def close(self) -> None:
        if self._port is not None:
            with contextlib.suppress(OSError, serial.SerialException):
                self._port.closePort()
            self._port = None

    @property
    def is_connected(self) -> bool:
        return self._port is not None

    def __enter__(self) -> Xm430Client:
        self.connect()
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()

    # -- the one place SDK results become exceptions ----------------------------------------

    def _where(self) -> str:
        return f"servo id {self.servo_id} on {self.port} at {self.baudrate} bps"

    def _check(self, what: str, comm_result: int, error: int, *,
               alert_raises: bool = True) -> None:
        if comm_result == COMM_RX_TIMEOUT:
            raise CommunicationTimeout(f"No reply from {self._where()} to {what}: check "
                                       "power, id and baud rate.")
        if comm_result == COMM_RX_CORRUPT:
            raise CorruptPacket(f"Damaged reply from {self._where()} to {what}: check the "
                                "baud rate, the cable and that no other program uses the "
                                "port.")
        if comm_result == COMM_PORT_BUSY:
            raise DynamixelError(f"The port {self.port} was busy during {what}: use one "
                                 "client per port from one thread at a time.")
        if comm_result != COMM_SUCCESS:
            raise DynamixelError(f"Could not exchange {what} with {self._where()} "
                                 f"({self._ph.getTxRxResult(comm_result)}): check the "
                                 "adapter and cable.")
        code = error & 0x7F
        if code:
            meaning, fix = _STATUS_MEANING.get(code, ("reported an unknown error", "check"))
            raise ServoRejected(f"Servo id {self.servo_id} {meaning} for {what}: {fix}.", code)
        if error & 0x80 and alert_raises:
            bits = self._read_hardware_error_unlocked()
            raise ServoHardwareError(
                f"Servo id {self.servo_id} reports a hardware error ({', '.join(sorted(bits))})"
                f" during {what}: remove the cause, then reboot the servo to clear it.", bits)

    def _require_port(self) -> _QuietPortHandler:
        if self._port is None:
            raise DynamixelError(f"The client for {self._where()} is not connected; call "
                                 "connect() first.")
        return self._port

    # -- raw access ------------------------------------------------------------------------

    def ping(self) -> tuple[int, int]:
        """(model number, firmware version) of the servo."""
        with self._lock:
            port = self._require_port()
            # ping's status carries the firmware version after the model; read it via txRx
            txpacket = [0] * 10
            txpacket[4], txpacket[5], txpacket[6], txpacket[7] = self.servo_id, 3, 0, 1
            rx, result, error = self._ph.txRxPacket(port, txpacket)
            self._check("ping", result, error, alert_raises=False)
            return rx[9] | (rx[10] << 8), rx[11]

    def read_item(self, name: str) -> int:
        """Raw value of one control-table item (signed where the item is)."""
        it = table.item(name)
        with self._lock:
            port = self._require_port()
            data, result, error = self._ph.readTxRx(port, self.servo_id, it.address, it.size)
            self._check(f"reading {name}", result, error, alert_raises=False)
            return it.from_bytes(bytes(data))

    def write_items(self, values: dict[str, int], *, alert_raises: bool = True) -> None:
        """Write raw values of adjacent items in one Write instruction."""
        items = sorted((table.item(n) for n in values), key=lambda i: i.address)
        for a, b in itertools.pairwise(items):
            if a.end != b.address:
                raise InvalidServoValue(f"{a.name} and {b.name} are not adjacent; write them "
                                        "in separate calls.")
        payload = b"".join(it.to_bytes(values[it.name]) for it in items)
        what = "writing " + ", ".join(f"{it.name}={values[it.name]}" for it in items)
        with self._lock:
            port = self._require_port()
            result, error = self._ph.writeTxRx(port, self.servo_id, items[0].address,
                                               len(payload), list(payload))
            self._check(what, result, error, alert_raises=alert_raises)

    def write_item(self, name: str, value: int) -> None:
        self.write_items({name: value})

    # -- typed commands ----------------------------------------------------------------------

    def set_torque(self, enabled: bool) -> None:
        # turning torque off must work even while a hardware error is latched
        self.write_items({"Torque Enable": int(enabled)}, alert_raises=enabled)

    def torque_enabled(self) -> bool:
        return bool(self.read_item("Torque Enable"))

    def set_operating_mode(self, mode: OperatingMode) -> None:
        """Needs torque off (EEPROM item)."""
        self.write_item("Operating Mode", int(OperatingMode(mode)))

    def set_current_limit_a(self, amps: float) -> None:
        """Needs torque off (EEPROM item)."""
        self.write_item("Current Limit", _raw("Current Limit", amps, table.A_PER_CURRENT_UNIT))

    def set_goal_current_a(self, amps: float) -> None:
        self.write_item("Goal Current", _raw("Goal Current", amps, table.A_PER_CURRENT_UNIT))

    def set_profile(self, velocity_rad_s: float, acceleration_rad_s2: float = math.inf
                    ) -> None:
        """Profile velocity and acceleration; ``math.inf`` means unlimited (raw 0)."""
        self.write_items(_profile_raw(velocity_rad_s, acceleration_rad_s2))

    def set_goal_position_rad(self, position_rad: float) -> None:
        self.write_item("Goal Position",
                        _raw("Goal Position", position_rad, table.RAD_PER_PULSE))

    def command_position(self, position_rad: float, velocity_rad_s: float,
                         acceleration_rad_s2: float = math.inf,
                         goal_current_a: float | None = None) -> None:
        """Goal current (optional), profile and goal position in ONE Write (102..119 or
        108..119), so a control loop changes all of them in one transaction."""
        values = _profile_raw(velocity_rad_s, acceleration_rad_s2)
        values["Goal Position"] = _raw("Goal Position", position_rad, table.RAD_PER_PULSE)
        if goal_current_a is not None:
            values["Goal Current"] = _raw("Goal Current", goal_current_a,
                                          table.A_PER_CURRENT_UNIT)
            values["Goal Velocity"] = 0
        self.write_items(values)

    def _read_hardware_error_unlocked(self) -> frozenset[str]:
        it = table.item("Hardware Error Status")
        data, result, error = self._ph.readTxRx(self._require_port(), self.servo_id,
                                                it.address, 1)
        self._check("reading Hardware Error Status", result, error, alert_raises=False)
        return table.decode_hardware_error(data[0])

    def read_hardware_error(self) -> frozenset[str]:
        with self._lock:
            return self._read_hardware_error_unlocked()

    def read_state(self) -> ServoState:
        """Present state in one Sync Read; hardware errors are reported, not raised."""
        start, end = table.STATE_BLOCK_START, table.STATE_BLOCK_END
        with self._lock:
            port = self._require_port()
            result = self._ph.syncReadTx(port, start, end - start, [self.servo_id], 1, False)
            self._check("sync read of the present state", result, 0)
            data, result, error = self._ph.readRx(port, self.servo_id, end - start)
            self._check("sync read of the present state", result, error, alert_raises=False)
            if len(data) != end - start:
                raise CorruptPacket(f"Short sync-read reply from {self._where()}: check the "
                                    "baud rate and the cable.")
            bits = self._read_hardware_error_unlocked() if error & 0x80 else frozenset()
        v = table.decode_block(start, bytes(data))
        return ServoState(
            position_rad=v["Present Position"] * table.RAD_PER_PULSE,
            velocity_rad_s=v["Present Velocity"] * table.RAD_S_PER_VELOCITY_UNIT,
            current_a=v["Present Current"] * table.A_PER_CURRENT_UNIT,
            input_voltage_v=v["Present Input Voltage"] * table.V_PER_VOLTAGE_UNIT,
            temperature_c=float(v["Present Temperature"]),
            moving=bool(v["Moving"]),
            hardware_error=bits,
            trajectory_position_rad=v["Position Trajectory"] * table.RAD_PER_PULSE,
        )

    def reboot(self, wait_s: float = 2.0) -> None:
        """Reboot (clears a latched hardware error; RAM items return to their initial
        values, torque off) and wait until the servo answers pings again."""
        with self._lock:
            port = self._require_port()
            result, error = self._ph.reboot(port, self.servo_id)
            self._check("reboot", result, error, alert_raises=False)
        deadline = time.monotonic() + wait_s
        while True:
            time.sleep(0.02)
            try:
                self.ping()
                return
            except (CommunicationTimeout, CorruptPacket):
                if time.monotonic() > deadline:
                    raise CommunicationTimeout(
                        f"{self._where().capitalize()} did not come back within {wait_s} s "
                        "after reboot: check power and wiring.") from None


def baudrate_item(baudrate: int) -> int | None:
    """Baud Rate (8) item value for a bit rate, or None if the XM430 has no such rate."""
    for value, bps in table.BAUD_RATES.items():
        if bps == baudrate:
            return value
    return None


def _profile_raw(velocity_rad_s: float, acceleration_rad_s2: float) -> dict[str, int]:
    values = {}
    for name, si, scale in (
            ("Profile Velocity", velocity_rad_s, table.RAD_S_PER_VELOCITY_UNIT),
            ("Profile Acceleration", acceleration_rad_s2, table.RAD_S2_PER_ACCELERATION_UNIT)):
        if si == math.inf:
            values[name] = 0
        elif not si > 0:
            raise InvalidServoValue(f"{name} must be positive (or math.inf for unlimited), "
                                    f"not {si}; give a positive value.")
        else:
            # never round a small request down to 0, which the servo reads as unlimited
            values[name] = max(1, _raw(name, si, scale))
    return values
