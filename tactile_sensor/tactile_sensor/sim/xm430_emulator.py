"""A Dynamixel XM430-W210 on a pseudo-terminal, answering Protocol 2.0 as the real servo does.

Clients (dynamixel-sdk, the project's Xm430Client, DYNAMIXEL Wizard-like tools) open the
symlink like /dev/ttyUSB0. The emulator answers ping, read, write, reg write/action, factory
reset, reboot, clear, sync read/write and bulk read/write; unknown instructions get an
Instruction error and damaged packets addressed to it a CRC error, with the Alert bit (0x80)
set in every status while Hardware Error Status is non-zero. Replies are delayed by the
Return Delay Time plus the wire time of both packets at the configured baud rate, so a
faster link really is faster; a host whose port is set to another baud rate gets no reply.

A :class:`MotorModel` (through the drivetrain of sim/drivetrain.py) moves the output toward
Goal Position under the profile and the current
limit; an optional :class:`GripperWorld` loads it (fingers, skin, rod). Faults can be injected
through methods or, from another process, through a line-based control FIFO
(``--control PATH``, ``sim/control_fifo.py``; see :data:`CONTROL_HELP`). The control table's
bytes and write rules are ``sim/xm430_control_table.py``.
"""

from __future__ import annotations

import argparse
import math
import signal
import sys
import termios
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from types import TracebackType

from tactile_sensor.hardware import xm430_table as table
from tactile_sensor.hardware.xm430_table import OperatingMode
from tactile_sensor.sim.control_fifo import ControlFifo
from tactile_sensor.sim.drivetrain import DEFAULT_DRIVETRAIN, Drivetrain
from tactile_sensor.sim.dynamixel_packets import (
    ALERT_BIT,
    BROADCAST_ID,
    BadCrc,
    Instruction,
    Packet,
    PacketParser,
    StatusError,
    build_status,
)
from tactile_sensor.sim.errors import SimError
from tactile_sensor.sim.gripper_world import GripperWorld
from tactile_sensor.sim.motor_model import MotorCommand, MotorModel
from tactile_sensor.sim.pty_link import PtyLink
from tactile_sensor.sim.xm430_control_table import ControlTable, baud_item_value

CONTROL_HELP = """\
control FIFO commands (one per line, e.g. `echo "fault overload" > CONTROL`):
  fault NAME          latch a hardware error bit: input_voltage, overheating,
                      motor_encoder, electrical_shock, overload (reboot clears it)
  voltage VOLTS       set the supply voltage (outside Min/Max Voltage Limit sets the
                      input_voltage bit while it lasts)
  no-response on|off  stop / resume answering (a pulled cable or dead servo)
  delay SECONDS       extra delay before every reply (slow response; 0 to clear)
  rod DIAMETER_M [OFFSET_M] | rod none   place or remove the object between the fingers
  object lift|down    take the object with mass off its support (gravity and the
                      scripted pull act from then on) or put it back
  clear               undo voltage, no-response and delay (latched bits stay)"""

#: Parser gives up a partial packet after this much silence (a real servo's own timeout).
_INTERBYTE_TIMEOUT_S = 0.01
#: The loop's step while the servo is at rest [s]: the world still follows the skin's slow
#: relaxation, and a thousand wake-ups a second of a servo that stands still cost the
#: in-process bringup about a tenth of a core.
_REST_STEP_S = 0.01
_POSITION_MODES = (OperatingMode.POSITION, OperatingMode.EXTENDED_POSITION,
                   OperatingMode.CURRENT_BASED_POSITION)
#: pty default speed (openpty): the host has not set a baud rate, so accept any.
_UNSET_SPEED = termios.B38400
_BAUD_TO_TERMIOS = {bps: getattr(termios, f"B{bps}", None) for bps in table.BAUD_RATES.values()}
_OVERLOAD_AFTER_S = 1.0


@dataclass
class Faults:
    """Injected conditions (cleared by :meth:`Xm430Emulator.clear_faults`)."""

    no_response: bool = False
    extra_delay_s: float = 0.0
    input_voltage_v: float = 12.0


@dataclass
class _Pending:
    due_s: float
    data: bytes
    after: Callable[[], None] | None = field(default=None)


class Xm430Emulator:
    """One emulated servo behind a :class:`PtyLink`; ``start()`` runs it in a thread."""

    def __init__(self, link_path: Path | str, servo_id: int = 1, baudrate: int = 57_600,
                 world: GripperWorld | None = None, control_path: Path | str | None = None,
                 reboot_s: float = 0.05, clock: Callable[[], float] = time.monotonic,
                 drivetrain: Drivetrain | None = DEFAULT_DRIVETRAIN) -> None:
        if not 0 <= servo_id <= table.BY_NAME["ID"].maximum:
            raise SimError(f"Servo id {servo_id} is outside 0..252; choose another --id.")
        self.link = PtyLink(link_path)
        self.world = world
        self.table = ControlTable()
        self.table.set("ID", servo_id)
        self.table.set("Baud Rate", baud_item_value(baudrate))
        self.faults = Faults()
        self.reboot_s = reboot_s
        self._clock = clock
        self._control = ControlFifo(Path(control_path), "xm430") if control_path else None
        self._lock = threading.RLock()
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._parser = PacketParser()
        self._pending: list[_Pending] = []
        self._last_byte_s = 0.0
        self._last_step_s: float | None = None
        self._rebooting_until = 0.0
        self._registered: tuple[int, bytes] | None = None
        self._latched_errors = 0
        self._shutdown = False
        self._t0 = clock()
        start = world.initial_position_rad if world else math.pi
        self.motor = MotorModel(start, world.load_torque_nm if world else None,
                                drivetrain=drivetrain,
                                pitch_radius_m=world.geometry.pitch_radius_m if world else 0.014)
        self._publish_motor()
        #: Every (instruction, error) answered, for tests and the log.
        self.counters: dict[str, int] = {"packets": 0, "replies": 0, "crc_errors": 0}

    # -- lifecycle -------------------------------------------------------------------------

    @property
    def servo_id(self) -> int:
        return self.table.get("ID")

    @property
    def baudrate(self) -> int:
        return table.BAUD_RATES[self.table.get("Baud Rate")]

    def start(self) -> Xm430Emulator:
        self.link.open()
        if self._control is not None:
            self._control.open()
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name="xm430-emulator", daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
            self._thread = None
        self.link.close()
        if self._control is not None:
            self._control.close()

    def __enter__(self) -> Xm430Emulator:
        return self.start()

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.stop()

    # -- fault injection -------------------------------------------------------------------

    def inject_hardware_error(self, name: str) -> None:
        """Latch a hardware error bit by name (see xm430_table.HARDWARE_ERROR_NAMES)."""
        bits = table.encode_hardware_error({name})
        with self._lock:
            self._latch(bits)

    def set_input_voltage(self, volts: float) -> None:
        with self._lock:
            self.faults.input_voltage_v = float(volts)
            self._update_hardware_status()

    def set_no_response(self, on: bool) -> None:
        with self._lock:
            self.faults.no_response = bool(on)

    def set_extra_delay(self, seconds: float) -> None:
        if seconds < 0:
            raise SimError("A reply delay cannot be negative; give 0 or more seconds.")
        with self._lock:
            self.faults.extra_delay_s = float(seconds)

    def clear_faults(self) -> None:
        with self._lock:
            self.faults = Faults()
            self._update_hardware_status()

    def control(self, line: str) -> str:
        """Apply one control command (the FIFO's syntax); returns what was done."""
        words = line.split()
        if not words:
            return ""
        cmd, args = words[0].lower(), words[1:]
        try:
            if cmd == "fault" and len(args) == 1:
                self.inject_hardware_error(args[0])
                return f"latched {args[0]}"
            if cmd == "voltage" and len(args) == 1:
                self.set_input_voltage(float(args[0]))
                return f"input voltage {float(args[0]):.2f} V"
            if cmd == "no-response" and len(args) == 1 and args[0] in ("on", "off"):
                self.set_no_response(args[0] == "on")
                return f"no-response {args[0]}"
            if cmd == "delay" and len(args) == 1:
                self.set_extra_delay(float(args[0]))
                return f"reply delay {float(args[0]):.3f} s"
            if cmd == "rod" and self.world is not None and args:
                if args[0] == "none":
                    self.world.set_rod(None)
                    return "rod removed"
                offset = float(args[1]) if len(args) > 1 else 0.0
                self.world.set_rod(float(args[0]), offset)
                return f"rod {float(args[0]):.4f} m at {offset:.4f} m"
            if cmd == "object" and args in (["lift"], ["down"]) and self.world is not None:
                done = self.world.lift() if args[0] == "lift" else self.world.set_down()
                if not done:
                    raise SimError("There is no object to lift or set down; give the world "
                                   "one (object.mass_kg > 0).")
                return "object lifted" if args[0] == "lift" else "object set down"
            if cmd == "clear" and not args:
                self.clear_faults()
                return "faults cleared"
        except ValueError as exc:
            raise SimError(f"Bad control command '{line.strip()}': {exc}; see --help.") from None
        raise SimError(f"Unknown control command '{line.strip()}'; see --help for the list.")

    # -- state exposed for tests and worlds -------------------------------------------------

    def item(self, name: str) -> int:
        with self._lock:
            return self.table.get(name)

    @property
    def hardware_error(self) -> frozenset[str]:
        return table.decode_hardware_error(self.item("Hardware Error Status"))

    # -- main loop -------------------------------------------------------------------------

    def _run(self) -> None:
        while not self._stop.is_set():
            now = self._clock()
            with self._lock:
                step = _REST_STEP_S if not self._pending and self._at_rest() else 1e-3
                next_due = min((p.due_s for p in self._pending), default=now + step)
            timeout = max(0.0, min(step, next_due - now))
            try:
                data = self.link.read(4096, timeout)
            except OSError:
                data = b""
            now = self._clock()
            with self._lock:
                if data:
                    self._receive(data, now)
                elif self._parser.pending and now - self._last_byte_s > _INTERBYTE_TIMEOUT_S:
                    self._parser.reset()
                self._advance(now)
                self._flush(now)
            if self._control is not None:
                self._control.poll(self.control)

    def _at_rest(self) -> bool:
        """Nothing would change between steps: the output and its profile still at the goal,
        and no object that could slip in the fingers (call with the lock held). A packet
        from the host still wakes the loop at once."""
        s = self.motor.state
        held = getattr(self.world, "held", None) if self.world is not None else None
        if held is not None or s.velocity_rad_s != 0.0 or s.trajectory_velocity_rad_s != 0.0:
            return False
        command = self._motor_command()
        return not command.torque_on or abs(command.goal_position_rad
                                            - s.trajectory_position_rad) < table.RAD_PER_PULSE

    def _host_baud_matches(self) -> bool:
        try:
            speed = termios.tcgetattr(self.link.fileno())[4]
        except (termios.error, SimError, OSError):
            return True
        return speed in (_UNSET_SPEED, _BAUD_TO_TERMIOS.get(self.baudrate))

    def _receive(self, data: bytes, now: float) -> None:
        self._last_byte_s = now
        if now < self._rebooting_until or not self._host_baud_matches():
            self._parser.reset()
            return
        for packet in self._parser.feed(data):
            self.counters["packets"] += 1
            if isinstance(packet, BadCrc):
                self.counters["crc_errors"] += 1
                if packet.servo_id == self.servo_id:
                    self._reply(now, packet.wire_length, StatusError.CRC)
                continue
            if packet.error is None:
                self._handle(packet, now)

    def _wire_s(self, n_bytes: int) -> float:
        return n_bytes * 10.0 / self.baudrate

    def _reply(self, now: float, rx_length: int, error: int, params: bytes = b"",
               after: Callable[[], None] | None = None, servo_id: int | None = None) -> None:
        if self.faults.no_response:
            if after is not None:
                after()
            return
        alert = ALERT_BIT if self.table.get("Hardware Error Status") else 0
        packet = build_status(self.servo_id if servo_id is None else servo_id,
                              int(error) | alert, params)
        due = (now + self._wire_s(rx_length + len(packet)) + self.faults.extra_delay_s
               + self.table.get("Return Delay Time") * table.RETURN_DELAY_S_PER_UNIT)
        self._pending.append(_Pending(due, packet, after))

    def _flush(self, now: float) -> None:
        due = [p for p in self._pending if p.due_s <= now]
        if not due:
            return
        self._pending = [p for p in self._pending if p.due_s > now]
        for p in sorted(due, key=lambda p: p.due_s):
            if not self.faults.no_response:
                self.link.write_all(p.data, timeout_s=0.05)
                self.counters["replies"] += 1
            if p.after is not None:
                p.after()

    def _answers(self, instruction: int) -> bool:
        level = self.table.get("Status Return Level")
        if instruction == Instruction.PING:
            return True
        if instruction in (Instruction.READ, Instruction.SYNC_READ, Instruction.BULK_READ):
            return level >= 1
        return level >= 2

    # -- instructions ----------------------------------------------------------------------

    def _handle(self, packet: Packet, now: float) -> None:
        me = self.servo_id
        inst, params, n = packet.instruction, packet.params, packet.wire_length
        broadcast = packet.servo_id == BROADCAST_ID
        if packet.servo_id != me and not broadcast:
            return
        if inst == Instruction.SYNC_READ and broadcast:
            self._sync_read(params, now, n)
        elif inst == Instruction.SYNC_WRITE and broadcast:
            self._sync_write(params)
        elif inst == Instruction.BULK_READ and broadcast:
            self._bulk_read(params, now, n)
        elif inst == Instruction.BULK_WRITE and broadcast:
            self._bulk_write(params)
        elif inst == Instruction.PING:
            model = self.table.get("Model Number").to_bytes(2, "little")
            self._reply(now, n, StatusError.NONE,
                        model + bytes([self.table.get("Firmware Version")]))
        elif inst == Instruction.ACTION:
            self._action(now, n, reply=not broadcast)
        elif broadcast:
            # Write, reboot etc. to everyone act silently; anything else is ignored.
            if inst in (Instruction.WRITE, Instruction.REBOOT, Instruction.REG_WRITE):
                self._unicast(inst, params, now, n, reply=False)
        else:
            self._unicast(inst, params, now, n, reply=True)

    def _unicast(self, inst: int, params: bytes, now: float, n: int, reply: bool) -> None:
        # decided before the instruction runs: a write that lowers Status Return Level is
        # still answered under the old level
        respond = reply and self._answers(inst)

        def answer(error: int, data: bytes = b"", after: Callable[[], None] | None = None
                   ) -> None:
            if respond:
                self._reply(now, n, error, data, after)
            elif after is not None:
                after()

        if inst == Instruction.READ:
            if len(params) != 4:
                return answer(StatusError.INSTRUCTION)
            address = int.from_bytes(params[:2], "little")
            length = int.from_bytes(params[2:4], "little")
            error, data = self.table.read(address, length)
            return answer(error, data)
        if inst in (Instruction.WRITE, Instruction.REG_WRITE):
            if len(params) < 3:
                return answer(StatusError.INSTRUCTION)
            address = int.from_bytes(params[:2], "little")
            error, values = self.table.check_write(address, params[2:])
            if error:
                return answer(error)
            if inst == Instruction.REG_WRITE:
                self._registered = (address, params[2:])
                self.table.set("Registered Instruction", 1)
                return answer(StatusError.NONE)
            error, after = self._apply(values, now)
            return answer(error, b"", after)
        if inst == Instruction.REBOOT:
            if params:
                return answer(StatusError.INSTRUCTION)
            return answer(StatusError.NONE, b"", lambda: self._begin_reboot(self._clock()))
        if inst == Instruction.FACTORY_RESET:
            if len(params) != 1 or params[0] not in (0x01, 0x02, 0xFF):
                return answer(StatusError.INSTRUCTION)
            if self.table.get("Torque Enable"):
                return answer(StatusError.ACCESS)
            keep = {0xFF: (), 0x01: ("ID",), 0x02: ("ID", "Baud Rate")}[params[0]]
            return answer(StatusError.NONE, b"",
                          lambda: self._factory_reset(keep, self._clock()))
        if inst == Instruction.CLEAR:
            if params != b"\x01DXL\x22":
                return answer(StatusError.INSTRUCTION)
            if abs(self.motor.state.velocity_rad_s) > 1e-3:
                return answer(StatusError.RESULT_FAIL)
            turn = 2.0 * math.pi
            self.motor.state.position_rad %= turn
            self.motor.reset_trajectory()
            self._publish_motor()
            return answer(StatusError.NONE)
        return answer(StatusError.INSTRUCTION)

    def _action(self, now: float, n: int, reply: bool) -> None:
        if self._registered is None:
            if reply:
                self._reply(now, n, StatusError.INSTRUCTION)
            return
        address, data = self._registered
        self._registered = None
        self.table.set("Registered Instruction", 0)
        error, values = self.table.check_write(address, data)
        after = None
        if not error:
            error, after = self._apply(values, now)
        if reply:
            self._reply(now, n, error, b"", after)
        elif after is not None:
            after()

    def _sync_read(self, params: bytes, now: float, n: int) -> None:
        if len(params) < 5 or self.servo_id not in params[4:] or not self._answers(
                Instruction.SYNC_READ):
            return
        address = int.from_bytes(params[:2], "little")
        length = int.from_bytes(params[2:4], "little")
        error, data = self.table.read(address, length)
        # A single servo on the bus answers as soon as its turn comes; with no other servo
        # answering first, that is at once.
        self._reply(now, n, error, data)

    def _sync_write(self, params: bytes) -> None:
        if len(params) < 4:
            return
        address = int.from_bytes(params[:2], "little")
        length = int.from_bytes(params[2:4], "little")
        chunk = 1 + length
        body = params[4:]
        for i in range(0, len(body) - chunk + 1, chunk):
            if body[i] == self.servo_id:
                error, values = self.table.check_write(address, body[i + 1: i + chunk])
                if not error:
                    _, after = self._apply(values, self._clock())
                    if after is not None:
                        after()

    def _bulk_read(self, params: bytes, now: float, n: int) -> None:
        for i in range(0, len(params) - 4, 5):
            if params[i] == self.servo_id and self._answers(Instruction.BULK_READ):
                address = int.from_bytes(params[i + 1: i + 3], "little")
                length = int.from_bytes(params[i + 3: i + 5], "little")
                error, data = self.table.read(address, length)
                self._reply(now, n, error, data)
                return

    def _bulk_write(self, params: bytes) -> None:
        i = 0
        while i + 5 <= len(params):
            servo_id = params[i]
            address = int.from_bytes(params[i + 1: i + 3], "little")
            length = int.from_bytes(params[i + 3: i + 5], "little")
            data = params[i + 5: i + 5 + length]
            i += 5 + length
            if servo_id == self.servo_id and len(data) == length:
                error, values = self.table.check_write(address, data)
                if not error:
                    _, after = self._apply(values, self._clock())
                    if after is not None:
                        after()

    # -- applying writes -------------------------------------------------------------------

    def _apply(self, values: dict[str, int], now: float
               ) -> tuple[StatusError, Callable[[], None] | None]:
        """Write validated values; ID and baud changes wait until the reply has gone."""
        self._advance(now)
        if values.get("Torque Enable") == 1 and self._shutdown:
            return StatusError.RESULT_FAIL, None
        deferred = {k: values.pop(k) for k in ("ID", "Baud Rate") if k in values}
        if values.get("Torque Enable") == 1 and not self.table.get("Torque Enable"):
            # the servo holds where it is when torque comes on
            self.motor.reset_trajectory()
            self.table.set("Goal Position", round(self.motor.state.position_rad
                                                  / table.RAD_PER_PULSE))
        mode = values.get("Operating Mode")
        if mode is not None and mode != self.table.get("Operating Mode") and mode in (
                OperatingMode.CURRENT, OperatingMode.CURRENT_BASED_POSITION):
            values.setdefault("Goal Current", self.table.get("Current Limit"))
        if "Current Limit" in values and "Goal Current" not in values:
            limit = values["Current Limit"]
            goal = self.table.get("Goal Current")
            if abs(goal) > limit:
                values["Goal Current"] = int(math.copysign(limit, goal))
        for name, value in values.items():
            self.table.set(name, value)
        self._update_hardware_status()
        if not deferred:
            return StatusError.NONE, None

        def later() -> None:
            for name, value in deferred.items():
                self.table.set(name, value)
        return StatusError.NONE, later

    def _begin_reboot(self, now: float) -> None:
        self._rebooting_until = now + self.reboot_s
        self._parser.reset()
        self.table.reset_area(eeprom=False)
        self.table.set("Hardware Error Status", 0)
        self._latched_errors = 0
        self._shutdown = False
        self._registered = None
        self.motor.overload_time_s = 0.0
        self.motor.reset_trajectory()
        self._update_hardware_status()

    def _factory_reset(self, keep: tuple[str, ...], now: float) -> None:
        self.table.reset_area(eeprom=True, keep=keep)
        self._begin_reboot(now)

    # -- physics ---------------------------------------------------------------------------

    def _latch(self, bits: int) -> None:
        self._latched_errors |= bits
        self._update_hardware_status()

    def _update_hardware_status(self) -> None:
        status = self._latched_errors
        volts = self.faults.input_voltage_v
        low = self.table.get("Min Voltage Limit") * table.V_PER_VOLTAGE_UNIT
        high = self.table.get("Max Voltage Limit") * table.V_PER_VOLTAGE_UNIT
        if not low <= volts <= high:
            status |= 1 << table.HardwareErrorBit.INPUT_VOLTAGE
        self.table.set("Hardware Error Status", status)
        if status & self.table.get("Shutdown"):
            self._shutdown = True
            self._latched_errors |= status & self.table.get("Shutdown")
            self.table.set("Torque Enable", 0)

    def _motor_command(self) -> MotorCommand:
        t = self.table
        mode = t.get("Operating Mode")
        torque = bool(t.get("Torque Enable"))
        current_limit = t.get("Current Limit")
        if mode == OperatingMode.CURRENT_BASED_POSITION:
            current_limit = min(abs(t.get("Goal Current")), current_limit)
        if mode in _POSITION_MODES:
            goal = t.get("Goal Position") * table.RAD_PER_PULSE
        else:
            # velocity, current and PWM modes are not modelled: the output holds still
            goal = self.motor.state.position_rad
        velocity_limit = t.get("Velocity Limit") * table.RAD_S_PER_VELOCITY_UNIT
        profile_v = t.get("Profile Velocity") * table.RAD_S_PER_VELOCITY_UNIT
        profile_v = min(profile_v, velocity_limit) if profile_v else velocity_limit
        return MotorCommand(
            torque_on=torque,
            goal_position_rad=goal,
            profile_velocity_rad_s=profile_v,
            profile_acceleration_rad_s2=t.get("Profile Acceleration")
            * table.RAD_S2_PER_ACCELERATION_UNIT,
            current_limit_a=current_limit * table.A_PER_CURRENT_UNIT,
            input_voltage_v=self.faults.input_voltage_v,
            position_p_gain=t.get("Position P Gain"),
        )

    def _advance(self, now: float) -> None:
        if self._last_step_s is None:
            self._last_step_s = now
        dt = now - self._last_step_s
        if dt <= 0:
            return
        self._last_step_s = now
        self.motor.step(min(dt, 0.1), self._motor_command())
        if self.motor.overload_time_s > _OVERLOAD_AFTER_S:
            self._latch(1 << table.HardwareErrorBit.OVERLOAD)
        if self.motor.temperature_c > self.table.get("Temperature Limit"):
            self._latch(1 << table.HardwareErrorBit.OVERHEATING)
        self._publish_motor()
        if self.world is not None:
            self.world.update(now - self._t0, self.motor.state.rack_position_rad)

    def _publish_motor(self) -> None:
        s, t = self.motor.state, self.table
        t.set("Present Position", round(s.position_rad / table.RAD_PER_PULSE))
        t.set("Present Velocity", round(s.velocity_rad_s / table.RAD_S_PER_VELOCITY_UNIT))
        current = round(s.current_a / table.A_PER_CURRENT_UNIT)
        t.set("Present Current", max(-32768, min(32767, current)))
        t.set("Position Trajectory", round(s.trajectory_position_rad / table.RAD_PER_PULSE))
        t.set("Velocity Trajectory",
              round(s.trajectory_velocity_rad_s / table.RAD_S_PER_VELOCITY_UNIT))
        threshold = t.get("Moving Threshold") * table.RAD_S_PER_VELOCITY_UNIT
        moving = abs(s.velocity_rad_s) > threshold
        t.set("Moving", int(moving))
        profiling = s.trajectory_velocity_rad_s != 0.0
        arrived = abs(t.get("Goal Position") - t.get("Present Position")) <= 20
        t.set("Moving Status", (0x01 if arrived else 0) | (0x02 if profiling else 0)
              | (0x30 if profiling else 0))
        t.set("Present Input Voltage", round(self.faults.input_voltage_v
                                             / table.V_PER_VOLTAGE_UNIT))
        t.set("Present Temperature", max(0, min(255, round(self.motor.temperature_c))))
        t.set("Realtime Tick", int((self._clock() - self._t0) * 1000) % 32768)

# -- command line --------------------------------------------------------------------------


def _build_world(args: argparse.Namespace) -> GripperWorld | None:
    if args.no_world:
        return None
    from tactile_sensor.control.geometry import GripperGeometry
    from tactile_sensor.sim.skin_response import TabulatedSkin

    try:
        from tactile_sensor.physics.params import PhysicsParams
        from tactile_sensor.physics.prediction import load_or_compute_curve
    except ImportError as exc:
        raise SimError(f"The gripper world needs the physics layer ({exc}); install the "
                       "package fully or run with --no-world.") from None

    def progress(fraction: float, message: str) -> None:
        print(f"xm430: skin model {fraction:4.0%} {message}", file=sys.stderr, flush=True)

    curve = load_or_compute_curve(PhysicsParams(), progress=progress)
    geometry = GripperGeometry(pitch_radius_m=args.pitch_radius, open_opening_m=args.open,
                               closed_opening_m=args.closed)
    rod = None if args.rod_diameter <= 0 else args.rod_diameter
    return GripperWorld(TabulatedSkin.from_prediction_curve(curve), geometry, rod, args.rod_offset)


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="tactile-sensor mock xm430",
        description="Emulate a Dynamixel XM430-W210 (Protocol 2.0) on a pseudo-terminal, "
                    "driving the gripper world of the paper's section III-E.",
        epilog=CONTROL_HELP, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--link", required=True, type=Path,
                   help="symlink to create for the servo's serial port (e.g. /tmp/ttyXM430)")
    p.add_argument("--id", type=int, default=1, help="servo id (default 1)")
    p.add_argument("--baud", type=int, default=57_600,
                   help="bit rate the servo listens at; the host must match (default 57600)")
    p.add_argument("--control", type=Path, default=None,
                   help="create a FIFO here that accepts fault-injection commands")
    p.add_argument("--no-world", action="store_true",
                   help="servo alone: no fingers, skin or rod load")
    p.add_argument("--rod-diameter", type=float, default=0.020,
                   help="diameter of the rod between the fingers [m]; 0 for none")
    p.add_argument("--rod-offset", type=float, default=0.0,
                   help="rod centre offset from the gripper centre towards finger B [m]")
    p.add_argument("--pitch-radius", type=float, default=0.014, help="pinion pitch radius [m]")
    p.add_argument("--open", type=float, default=0.060, help="fully open opening [m]")
    p.add_argument("--closed", type=float, default=0.002, help="closed-limit opening [m]")
    p.add_argument("--adc-link", type=Path, default=None,
                   help="also run the mock photoreflector ADC, fed by this world, here")
    return p


def _raise_interrupt(signum: int, frame: object) -> None:
    raise KeyboardInterrupt


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    adc = None
    try:
        world = _build_world(args)
        emulator = Xm430Emulator(args.link, args.id, args.baud, world, args.control)
        emulator.start()
        if args.adc_link is not None:
            if world is None:
                raise SimError("--adc-link needs the gripper world; drop --no-world.")
            from tactile_sensor.sim.adc_device import MockAdcDevice

            adc = MockAdcDevice(args.adc_link, world.module_voltages)
            adc.start()
    except (SimError, ValueError) as exc:
        print(f"tactile-sensor mock xm430: {exc}", file=sys.stderr)
        return 1
    signal.signal(signal.SIGTERM, _raise_interrupt)
    print(f"xm430: id {args.id} at {args.baud} bps on {args.link}"
          + (f", control FIFO {args.control}" if args.control else ""), file=sys.stderr,
          flush=True)
    try:
        while True:
            time.sleep(0.5)
    except KeyboardInterrupt:
        pass
    finally:
        if adc is not None:
            adc.stop()
        emulator.stop()
    return 0


if __name__ == "__main__":
    sys.exit(main())
