"""Conformance of the emulator, driven by dynamixel-sdk itself (classic API and easy SDK)."""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import dynamixel_easy_sdk.connector
import pytest
import serial
from dynamixel_easy_sdk import Connector, OperatingMode, ProfileConfiguration
from dynamixel_sdk import (
    COMM_RX_TIMEOUT,
    COMM_SUCCESS,
    GroupBulkRead,
    GroupSyncRead,
    GroupSyncWrite,
    PacketHandler,
    PortHandler,
)

# share_the_gil_fairly: an autouse fixture, in force for every test here
from emulated_xm430 import linear_skin, share_the_gil_fairly  # noqa: F401
from waiting import wait_until

from tactile_sensor.sim.dynamixel_packets import Instruction, build_instruction, parse_one
from tactile_sensor.sim.errors import SimError
from tactile_sensor.sim.gripper_world import GripperWorld
from tactile_sensor.sim.held_object import HeldObject, ObjectSpec
from tactile_sensor.sim.skin_shear import TangentialStiffness
from tactile_sensor.sim.xm430_emulator import Xm430Emulator

BAUD = 1_000_000
PH = PacketHandler(2.0)
ADDR_TORQUE, ADDR_LED, ADDR_HW_ERROR = 64, 65, 70
ADDR_GOAL_CURRENT, ADDR_GOAL_POSITION, ADDR_PRESENT_POSITION = 102, 116, 132
# Upper bound of every wait on a condition, and the SDK's packet timeout where an answer is
# expected: generous, because a wait ends as soon as the answer (or the condition) is
# there, and on a busy machine the emulator (a thread or a process) may answer late.
PATIENCE_S = 30.0
# How long a call that must get no answer listens. Silence cannot be faked by a busy
# machine (it only makes answers later, never makes them appear); on an idle machine the
# emulator answers within a millisecond, so a wrong answer would show up well inside it.
SILENCE_S = 0.5


class PatientPortHandler(PortHandler):
    """The stock PortHandler (its spinning read loop included) with a packet timeout of
    ``timeout_s`` plus the wire time, instead of the stock ~34 ms a busy scheduler exceeds."""

    timeout_s = PATIENCE_S

    def setPacketTimeout(self, packet_length: int) -> None:
        self.packet_start_time = self.getCurrentTime()
        self.packet_timeout = self.tx_time_per_byte * packet_length + self.timeout_s * 1000.0


@contextlib.contextmanager
def listening_for_silence(handler: PatientPortHandler) -> Iterator[None]:
    """The calls inside expect no answer: they listen for SILENCE_S, not PATIENCE_S."""
    handler.timeout_s = SILENCE_S
    try:
        yield
    finally:
        del handler.timeout_s  # back to the class's PATIENCE_S


def open_port(path: Path | str, baud: int = BAUD) -> PatientPortHandler:
    handler = PatientPortHandler(str(path))
    assert handler.openPort() and handler.setBaudRate(baud)
    return handler


@pytest.fixture
def emulator(tmp_path):
    world = GripperWorld(linear_skin())
    # the protocol's tests on the ideal servo: positions land on the goal
    with Xm430Emulator(tmp_path / "xm430", baudrate=BAUD, world=world,
                       drivetrain=None) as emu:
        yield emu


@pytest.fixture
def port(emulator):
    handler = open_port(emulator.link.link_path)
    yield handler
    handler.closePort()


def test_ping_returns_model_1030(port):
    assert PH.ping(port, 1) == (1030, COMM_SUCCESS, 0)


def test_other_ids_do_not_answer(port):
    with listening_for_silence(port):
        assert PH.ping(port, 2)[1] == COMM_RX_TIMEOUT
    assert PH.ping(port, 1)[1] == COMM_SUCCESS  # while id 1 does


def test_read_write_round_trip_and_signed_position(port, emulator):
    assert PH.write1ByteTxRx(port, 1, ADDR_LED, 1) == (COMM_SUCCESS, 0)
    assert PH.read1ByteTxRx(port, 1, ADDR_LED) == (1, COMM_SUCCESS, 0)
    assert PH.read4ByteTxRx(port, 1, ADDR_PRESENT_POSITION)[0] == 2048
    assert emulator.item("LED") == 1


@pytest.mark.parametrize(("address", "size", "value", "code"), [
    (0, 2, 1020, 7),          # Model Number is read-only: access error
    (11, 1, 2, 4),            # Operating Mode 2 does not exist: data range error
    (38, 2, 1194, 4),         # Current Limit above 1193: data range error
    (116, 2, 100, 5),         # half of the 4-byte Goal Position: data length error
    (14, 1, 0, 7),            # undefined address: access error
])
def test_bad_writes_get_the_servos_error_codes(port, address, size, value, code):
    write = {1: PH.write1ByteTxRx, 2: PH.write2ByteTxRx}[size]
    assert write(port, 1, address, value) == (COMM_SUCCESS, code)


def test_limits_and_eeprom_lock(port):
    assert PH.write2ByteTxRx(port, 1, 38, 100) == (COMM_SUCCESS, 0)     # Current Limit 100
    assert PH.write1ByteTxRx(port, 1, 11, 5) == (COMM_SUCCESS, 0)       # current-based pos.
    assert PH.write2ByteTxRx(port, 1, ADDR_GOAL_CURRENT, 101) == (COMM_SUCCESS, 6)
    assert PH.write1ByteTxRx(port, 1, ADDR_TORQUE, 1) == (COMM_SUCCESS, 0)
    assert PH.write1ByteTxRx(port, 1, 11, 3) == (COMM_SUCCESS, 7)       # EEPROM locked


def test_unknown_instruction_gets_instruction_error(port):
    _rx, result, error = PH.txRxPacket(port, [0, 0, 0, 0, 1, 3, 0, 0x30, 0, 0])
    assert (result, error) == (COMM_SUCCESS, 2)


def test_damaged_packet_gets_crc_error(emulator):
    frame = bytearray(build_instruction(1, Instruction.PING))
    frame[-1] ^= 0xFF
    with serial.Serial(str(emulator.link.link_path), BAUD, timeout=PATIENCE_S) as ser:
        ser.write(bytes(frame))
        status = parse_one(ser.read(11))
    assert status.error == 3 and status.servo_id == 1


def test_sync_read_sync_write_bulk_read(port, emulator):
    PH.write1ByteTxRx(port, 1, ADDR_TORQUE, 1)
    group = GroupSyncRead(port, PH, 122, 25)
    assert group.addParam(1)
    assert group.txRxPacket() == COMM_SUCCESS
    assert group.getData(1, ADDR_PRESENT_POSITION, 4) == 2048
    writer = GroupSyncWrite(port, PH, ADDR_GOAL_POSITION, 4)
    writer.addParam(1, (2100).to_bytes(4, "little"))
    assert writer.txPacket() == COMM_SUCCESS
    # a sync write gets no status packet: wait until the emulator has applied it
    assert wait_until(lambda: emulator.item("Goal Position") == 2100)
    bulk = GroupBulkRead(port, PH)
    bulk.addParam(1, ADDR_GOAL_POSITION, 4)
    assert bulk.txRxPacket() == COMM_SUCCESS
    assert bulk.getData(1, ADDR_GOAL_POSITION, 4) == 2100


def test_motor_follows_profile_to_goal(port, emulator):
    # 20 x 0.229 rev/min: the 300 ticks (0.46 rad) take about 1 s, so the motion outlasts
    # any scheduler delay between the goal and the reads that must see it moving
    PH.write4ByteTxRx(port, 1, 112, 20)                       # Profile Velocity
    PH.write1ByteTxRx(port, 1, ADDR_TORQUE, 1)
    PH.write4ByteTxRx(port, 1, ADDR_GOAL_POSITION, 2048 + 300)  # closing, short of the rod
    # Moving is updated on the emulator's next step, not with the write's status packet
    assert wait_until(lambda: PH.read1ByteTxRx(port, 1, 122)[0] == 1)   # Moving
    assert wait_until(
        lambda: PH.read4ByteTxRx(port, 1, ADDR_PRESENT_POSITION)[0] == 2048 + 300)
    assert wait_until(lambda: PH.read1ByteTxRx(port, 1, 122)[0] == 0)   # and stopped


def test_hardware_error_sets_alert_shuts_down_and_reboot_clears(port, emulator):
    PH.write1ByteTxRx(port, 1, ADDR_TORQUE, 1)
    emulator.inject_hardware_error("overload")
    value, result, error = PH.read1ByteTxRx(port, 1, ADDR_HW_ERROR)
    assert (value, result, error) == (0x20, COMM_SUCCESS, 0x80)
    assert PH.read1ByteTxRx(port, 1, ADDR_TORQUE)[0] == 0      # shutdown: torque off
    assert PH.write1ByteTxRx(port, 1, ADDR_TORQUE, 1) == (COMM_SUCCESS, 0x81)
    # a boot long enough that the ping below is surely sent while it lasts
    emulator.reboot_s = 10 * SILENCE_S
    assert PH.reboot(port, 1) == (COMM_SUCCESS, 0x80)
    with listening_for_silence(port):
        assert PH.ping(port, 1)[1] == COMM_RX_TIMEOUT           # still booting
        assert wait_until(lambda: PH.ping(port, 1)[1] == COMM_SUCCESS)  # booted
    assert PH.read1ByteTxRx(port, 1, ADDR_HW_ERROR) == (0, COMM_SUCCESS, 0)
    assert PH.write1ByteTxRx(port, 1, ADDR_TORQUE, 1) == (COMM_SUCCESS, 0)


def test_input_voltage_error_is_live_and_keeps_torque(port, emulator):
    PH.write1ByteTxRx(port, 1, ADDR_TORQUE, 1)
    emulator.set_input_voltage(8.0)
    assert PH.read1ByteTxRx(port, 1, ADDR_HW_ERROR) == (0x01, COMM_SUCCESS, 0x80)
    assert PH.read2ByteTxRx(port, 1, 144)[0] == 80
    assert PH.read1ByteTxRx(port, 1, ADDR_TORQUE)[0] == 1
    emulator.set_input_voltage(12.0)
    assert PH.read1ByteTxRx(port, 1, ADDR_HW_ERROR) == (0, COMM_SUCCESS, 0)


def test_no_response_and_slow_response(port, emulator):
    emulator.set_no_response(True)
    with listening_for_silence(port):
        assert PH.ping(port, 1)[1] == COMM_RX_TIMEOUT
    emulator.set_no_response(False)
    # far beyond the client's packet timeout (SILENCE_S), so that no scheduler delay of
    # the client can make it read the late reply in time
    emulator.set_extra_delay(20 * SILENCE_S)
    with listening_for_silence(port):
        assert PH.ping(port, 1)[1] == COMM_RX_TIMEOUT
    emulator.clear_faults()
    # the late reply may still be pending: the SDK clears the port before each packet and
    # a late ping reply would be the same as the one expected here
    assert PH.ping(port, 1)[1] == COMM_SUCCESS


def test_status_return_level_one_answers_reads_only(port):
    assert PH.write1ByteTxRx(port, 1, 68, 1) == (COMM_SUCCESS, 0)
    with listening_for_silence(port):
        assert PH.write1ByteTxRx(port, 1, ADDR_LED, 1)[0] == COMM_RX_TIMEOUT
    assert PH.read1ByteTxRx(port, 1, ADDR_LED) == (1, COMM_SUCCESS, 0)


def test_host_at_another_baud_rate_gets_no_reply(emulator):
    handler = open_port(emulator.link.link_path, 57_600)
    try:
        with listening_for_silence(handler):
            assert PH.ping(handler, 1)[1] == COMM_RX_TIMEOUT
        assert handler.setBaudRate(BAUD)
        assert PH.ping(handler, 1)[1] == COMM_SUCCESS  # at its own baud rate it answers
    finally:
        handler.closePort()


def test_wire_time_follows_the_baud_rate(tmp_path):
    def transaction_times(baud: int) -> list[float]:
        with Xm430Emulator(tmp_path / f"x{baud}", baudrate=baud) as emu:
            handler = open_port(emu.link.link_path, baud)
            PH.write1ByteTxRx(handler, 1, 9, 0)            # Return Delay Time 0
            group = GroupSyncRead(handler, PH, 0, 147)      # a long reply
            group.addParam(1)
            times = []
            for _ in range(20):
                t0 = time.perf_counter()
                assert group.txRxPacket() == COMM_SUCCESS
                times.append(time.perf_counter() - t0)
            handler.closePort()
            return times
    # 172 wire bytes: 15 ms at 115200 bps, 0.4 ms at 4 Mbps. Every transaction at 115200
    # takes at least its wire time (a busy machine only adds to it); the fastest at 4 Mbps
    # beats that by far (a scheduler would have to delay all 20 by over 14 ms to break it).
    wire_115200 = 172 * 10 / 115_200
    assert min(transaction_times(115_200)) >= wire_115200
    assert min(transaction_times(4_000_000)) < wire_115200 - 0.01


def test_easy_sdk_drives_the_emulator(emulator, monkeypatch):
    # the easy SDK's own PortHandler, with a packet timeout a busy machine cannot exceed
    monkeypatch.setattr(dynamixel_easy_sdk.connector, "PortHandler", PatientPortHandler)
    connector = Connector(str(emulator.link.link_path), BAUD)
    try:
        motor = connector.createMotor(1)
        assert motor.model_name == "xm430_w210.model"
        motor.setProfileConfiguration(ProfileConfiguration.VELOCITY_BASED)
        motor.setOperatingMode(OperatingMode.CURRENT_BASED_POSITION)
        assert motor.getOperatingMode() == OperatingMode.CURRENT_BASED_POSITION
        motor.enableTorque()
        motor.setGoalCurrent(200)
        motor.setGoalPosition(2200)                     # closing, short of the rod
        assert wait_until(lambda: abs(motor.getPresentPosition() - 2200) <= 2)
        executor = connector.createGroupExecutor()
        executor.addCmd(motor.stageSetGoalPosition(2250))
        executor.executeWrite()                         # sync write
        executor.addCmd(motor.stageGetPresentPosition())
        assert wait_until(lambda: abs(executor.executeRead()[0] - 2250) <= 2)  # sync read
        motor.reboot()
        time.sleep(emulator.reboot_s + 0.02)
        assert motor.isTorqueOn() == 0
    finally:
        connector.closePort()


def test_control_commands_and_errors(emulator):
    assert emulator.control("fault electrical_shock") == "latched electrical_shock"
    assert emulator.hardware_error == {"electrical_shock"}
    assert emulator.control("rod none") == "rod removed"
    with pytest.raises(SimError, match="Unknown control command"):
        emulator.control("explode now")
    with pytest.raises(SimError, match="Bad control command"):
        emulator.control("voltage twelve")
    with pytest.raises(SimError, match="negative"):
        emulator.set_extra_delay(-1)
    with pytest.raises(SimError, match="There is no object to lift"):
        emulator.control("object lift")


def test_the_object_is_lifted_and_set_down_through_the_control_commands(tmp_path):
    held = HeldObject(ObjectSpec(0.1, 0.5, 0.4), TangentialStiffness([0.001], [340.0]))
    world = GripperWorld(linear_skin(), held=held)
    with Xm430Emulator(tmp_path / "xm430", baudrate=BAUD, world=world) as emu:
        assert emu.control("object lift") == "object lifted"
        assert wait_until(lambda: world.latest.held is not None and world.latest.held.lifted)
        assert emu.control("object down") == "object set down"
        assert wait_until(lambda: not world.latest.held.lifted)


def test_bad_constructor_arguments(tmp_path):
    with pytest.raises(SimError, match="no 12345 bps"):
        Xm430Emulator(tmp_path / "x", baudrate=12345)
    with pytest.raises(SimError, match=r"outside 0\.\.252"):
        Xm430Emulator(tmp_path / "x", servo_id=300)


@pytest.mark.slow
def test_cli_runs_takes_fifo_commands_and_cleans_up(tmp_path):
    link, control = tmp_path / "xm430", tmp_path / "control"
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[2]))
    proc = subprocess.Popen(
        [sys.executable, "-m", "tactile_sensor.sim.xm430_emulator", "--link", str(link),
         "--baud", str(BAUD), "--no-world", "--control", str(control)],
        env=env, stderr=subprocess.PIPE, text=True)
    try:
        assert wait_until(lambda: (link.exists() and control.exists()) or proc.poll() is not None)
        assert proc.poll() is None
        handler = open_port(link)
        assert PH.ping(handler, 1)[1] == COMM_SUCCESS
        with open(control, "w") as fifo:
            fifo.write("fault overload\n")
        assert wait_until(lambda: PH.read1ByteTxRx(handler, 1, ADDR_HW_ERROR)[0] == 0x20)
        handler.closePort()
    finally:
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=PATIENCE_S)
    assert proc.returncode == 0, err
    assert "latched overload" in err
    assert not link.exists()


@pytest.mark.slow
def test_cli_reports_bad_baud_without_traceback(tmp_path):
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[2]))
    done = subprocess.run(
        [sys.executable, "-m", "tactile_sensor.sim.xm430_emulator", "--link",
         str(tmp_path / "x"), "--baud", "12345", "--no-world"],
        env=env, capture_output=True, text=True, timeout=30)
    assert done.returncode == 1
    assert "no 12345 bps setting" in done.stderr and "Traceback" not in done.stderr
