"""Xm430Client against the emulator over a real pseudo-terminal: typed values and errors."""

from __future__ import annotations

import math
import time

import pytest
from dynamixel_sdk import COMM_PORT_BUSY, COMM_RX_CORRUPT, COMM_TX_FAIL

# share_the_gil_fairly: an autouse fixture, in force for every test here
from emulated_xm430 import linear_skin, share_the_gil_fairly  # noqa: F401

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
from tactile_sensor.hardware.xm430 import Xm430Client
from tactile_sensor.hardware.xm430_table import OperatingMode
from tactile_sensor.sim.drivetrain import Drivetrain
from tactile_sensor.sim.gripper_world import GripperWorld
from tactile_sensor.sim.xm430_emulator import Xm430Emulator

BAUD = 1_000_000


@pytest.fixture
def world():
    return GripperWorld(linear_skin())


@pytest.fixture
def emulator(tmp_path, world):
    with Xm430Emulator(tmp_path / "xm430", baudrate=BAUD, world=world) as emu:
        yield emu


# A reply waits this long at most: the emulator is a thread of this process, which a busy
# machine can hold up far beyond a real servo's microseconds (it ends at the reply).
PATIENT_TIMEOUT_S = 5.0


@pytest.fixture
def client(emulator):
    with Xm430Client(str(emulator.link.link_path), BAUD, 1, timeout_s=PATIENT_TIMEOUT_S) as c:
        yield c


def test_connect_reads_model_and_state_in_si(client):
    assert client.firmware_version == 46
    state = client.read_state()
    assert state.position_rad == pytest.approx(math.pi)
    assert state.input_voltage_v == pytest.approx(12.0)
    assert state.hardware_error == frozenset() and not state.moving


@pytest.fixture
def ideal_client(tmp_path, world):
    """A client of a servo without the drivetrain's losses: on the sourced drivetrain 0.1 A
    is below what the torque offset and friction take, and nothing would close
    (test_drivetrain.py, docs/gripper-drivetrain.md)."""
    with Xm430Emulator(tmp_path / "ideal", baudrate=BAUD, world=world,
                       drivetrain=Drivetrain.ideal()) as emu, \
            Xm430Client(str(emu.link.link_path), BAUD, 1, timeout_s=PATIENT_TIMEOUT_S) as c:
        yield c


def test_closing_on_the_rod_raises_current_and_stalls(ideal_client, world):
    client = ideal_client
    client.set_operating_mode(OperatingMode.CURRENT_BASED_POSITION)
    client.set_torque(True)
    g = world.geometry
    client.command_position(g.closed_position_rad, 2.0, goal_current_a=0.1)
    deadline = time.monotonic() + 30.0
    while world.latest.force_a_n == 0.0 or client.read_state().moving:
        assert time.monotonic() < deadline
        time.sleep(0.02)
    state = client.read_state()
    assert state.current_a == pytest.approx(0.1, abs=0.005)   # pushing at its budget
    assert 0.015 < g.opening_m(state.position_rad) < 0.020    # pressed into the 20 mm rod
    # the skin force balances the torque: r * (F_a + F_b) = kt * I
    assert world.latest.force_a_n == pytest.approx(0.1 * (3.0 / 2.3) / 0.014 / 2, rel=0.03)


def test_one_write_per_command(client, emulator):
    before = emulator.counters["packets"]
    client.command_position(math.pi + 0.1, 1.0, 10.0, goal_current_a=0.2)
    assert emulator.counters["packets"] == before + 1
    assert emulator.item("Goal Current") == round(0.2 / 2.69e-3)
    assert emulator.item("Profile Velocity") == round(1.0 / (0.229 * 2 * math.pi / 60))


def test_small_profile_never_becomes_unlimited(client, emulator):
    client.set_profile(1e-4, 1e-4)
    assert emulator.item("Profile Velocity") == 1
    assert emulator.item("Profile Acceleration") == 1
    client.set_profile(math.inf)
    assert emulator.item("Profile Velocity") == 0


@pytest.mark.parametrize("call", [
    lambda c: c.set_goal_position_rad(float("nan")),
    lambda c: c.set_goal_position_rad(1e6),
    lambda c: c.set_current_limit_a(5.0),
    lambda c: c.set_profile(-1.0),
    lambda c: c.write_items({"Goal Current": 0, "Goal Position": 0}),
])
def test_invalid_values_are_refused_before_sending(client, call):
    with pytest.raises(InvalidServoValue):
        call(client)


def test_servo_rejections_are_typed(client):
    client.set_current_limit_a(0.5)
    with pytest.raises(ServoRejected, match="beyond a limit") as info:
        client.set_goal_current_a(1.0)
    assert info.value.code == 6
    client.set_torque(True)
    with pytest.raises(ServoRejected, match="turn torque off") as info:
        client.set_operating_mode(OperatingMode.POSITION)
    assert info.value.code == 7


def test_hardware_error_reported_in_state_raised_on_command_cleared_by_reboot(
        client, emulator):
    client.set_torque(True)
    emulator.inject_hardware_error("overload")
    assert client.read_state().hardware_error == {"overload"}
    assert client.read_hardware_error() == {"overload"}
    with pytest.raises(ServoHardwareError, match="overload") as info:
        client.set_goal_current_a(0.1)
    assert info.value.bits == {"overload"}
    client.set_torque(False)                   # allowed while the error is latched
    client.reboot(wait_s=6 * PATIENT_TIMEOUT_S)  # pings in the boot time wait for a reply
    assert client.read_state().hardware_error == frozenset()
    assert not client.torque_enabled()


def test_timeout_is_typed_and_names_the_fix(emulator):
    # a short timeout: load can delay an answer, never make a missing one appear
    with Xm430Client(str(emulator.link.link_path), BAUD, 1, timeout_s=0.1) as client:
        emulator.set_no_response(True)
        with pytest.raises(CommunicationTimeout, match="check power, id and baud rate"):
            client.read_state()
    emulator.set_no_response(False)
    with Xm430Client(str(emulator.link.link_path), BAUD, 1,
                     timeout_s=PATIENT_TIMEOUT_S) as client:
        assert client.read_state().position_rad == pytest.approx(math.pi)


def test_model_mismatch(emulator):
    emulator.table.set("Model Number", 1020)
    with pytest.raises(ModelMismatch, match="not the XM430-W210"):
        Xm430Client(str(emulator.link.link_path), BAUD, 1).connect()


def test_wrong_id_times_out_and_port_is_released(emulator):
    client = Xm430Client(str(emulator.link.link_path), BAUD, 7)
    with pytest.raises(CommunicationTimeout):
        client.connect()
    assert not client.is_connected


def test_port_and_argument_errors(tmp_path):
    with pytest.raises(PortOpenError, match="Cannot open"):
        Xm430Client(str(tmp_path / "missing"), BAUD, 1).connect()
    with pytest.raises(PortOpenError, match="not an XM430 baud rate"):
        Xm430Client(str(tmp_path / "missing"), 12345, 1).connect()
    with pytest.raises(InvalidServoValue, match=r"outside 0\.\.252"):
        Xm430Client("x", BAUD, 300)
    with pytest.raises(InvalidServoValue, match=r"timeout_s must be positive, not 0\.0"):
        Xm430Client("x", BAUD, 1, timeout_s=0.0)
    with pytest.raises(DynamixelError, match="not connected"):
        Xm430Client("x", BAUD, 1).read_state()


def test_a_vanished_device_raises_port_lost_every_time(client, emulator):
    client.read_state()
    emulator.stop()  # the adapter is pulled (or the mock exited): pyserial raises
    for _ in range(2):  # and again, not "port was busy": the SDK's busy flag is cleared
        with pytest.raises(PortLost, match=r"serial port .* failed .*reconnect it"):
            client.read_state()


@pytest.mark.parametrize(("result", "says"), [
    (COMM_RX_CORRUPT, "Damaged reply from servo id 1 on x at 1000000 bps to a ping: check "
                      "the baud rate"),
    (COMM_PORT_BUSY, "The port x was busy during a ping: use one client per port"),
    (COMM_TX_FAIL, "Could not exchange a ping with servo id 1 on x at 1000000 bps ("),
])
def test_each_failed_exchange_is_typed_and_names_the_fix(result, says):
    with pytest.raises(DynamixelError) as info:
        Xm430Client("x", BAUD, 1)._check("a ping", result, 0)
    assert str(info.value).startswith(says), str(info.value)
    assert isinstance(info.value, CorruptPacket) == (result == COMM_RX_CORRUPT)
