"""The servo as loop, goals and cancel share it (control/servo_link.py), on a scripted
in-memory client: retries, sampling, the cancel's stop and command ordering."""

from __future__ import annotations

import math
import threading

import pytest
from hypothesis import given
from hypothesis import strategies as st

from tactile_sensor.control.grasp import GraspConfig, ServoCommand
from tactile_sensor.control.servo_link import ServoLink, call_retrying
from tactile_sensor.hardware.errors import (
    CommunicationTimeout,
    CorruptPacket,
    PortLost,
    ServoHardwareError,
)
from tactile_sensor.hardware.xm430 import ServoState
from tactile_sensor.hardware.xm430_table import OperatingMode


def state(position: float = math.pi, velocity: float = 0.0,
          bits: frozenset[str] = frozenset()) -> ServoState:
    return ServoState(position, velocity, 0.1, 12.0, 30.0, velocity != 0.0, bits)


class ScriptedServo:
    """Answers with ``states`` (the last repeats); ``faults`` are raised first, in order."""

    def __init__(self, *states: ServoState) -> None:
        self.states = list(states) or [state()]
        self.faults: list[Exception] = []
        self.log: list[tuple] = []
        self.torque = False

    def _call(self, *entry: object) -> None:
        if self.faults:
            raise self.faults.pop(0)
        self.log.append(entry)

    def read_state(self) -> ServoState:
        self._call("read")
        return self.states.pop(0) if len(self.states) > 1 else self.states[0]

    def command_position(self, position_rad: float, velocity_rad_s: float,
                         acceleration_rad_s2: float = math.inf,
                         goal_current_a: float | None = None) -> None:
        self._call("command", position_rad, velocity_rad_s, goal_current_a)

    def set_torque(self, enabled: bool) -> None:
        self._call("torque", enabled)
        self.torque = enabled

    def torque_enabled(self) -> bool:
        self._call("torque?")
        return self.torque

    def set_operating_mode(self, mode: OperatingMode) -> None:
        self._call("mode", mode)

    def set_current_limit_a(self, amps: float) -> None:
        self._call("current_limit", amps)

    def reboot(self, wait_s: float = 2.0) -> None:
        self._call("reboot")

    def commands(self) -> list[tuple]:
        return [e for e in self.log if e[0] == "command"]


class Clock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def link(client: ScriptedServo, clock: Clock | None = None, retries: int = 2) -> ServoLink:
    return ServoLink(client, GraspConfig(), period_s=0.01, retries=retries,
                     clock=clock or Clock())


@given(st.integers(0, 5), st.integers(0, 5))
def test_lost_packets_are_retried_up_to_the_limit(failures, retries):
    calls = []

    def call() -> str:
        calls.append(1)
        if len(calls) <= failures:
            raise (CommunicationTimeout if len(calls) % 2 else CorruptPacket)("lost")
        return "answer"

    if failures <= retries:
        assert call_retrying(call, retries) == "answer"
    else:
        with pytest.raises((CommunicationTimeout, CorruptPacket)):
            call_retrying(call, retries)
    assert len(calls) == min(failures, retries) + 1


@pytest.mark.parametrize("fault", [PortLost("unplugged"), ServoHardwareError("hot", frozenset(
    {"overheating"})), ValueError("bug")])
def test_other_faults_are_not_retried(fault):
    calls = []

    def call() -> None:
        calls.append(1)
        raise fault

    with pytest.raises(type(fault)):
        call_retrying(call, 3)
    assert calls == [1]


def test_a_negative_retry_count_is_refused():
    with pytest.raises(ValueError, match="retries"):
        call_retrying(lambda: None, -1)


def test_poll_reports_a_loss_once_and_the_recovery():
    client = ScriptedServo()
    servo = link(client, retries=0)
    client.faults = [CommunicationTimeout("no reply"), CommunicationTimeout("no reply")]
    first, second = servo.poll(), servo.poll()
    assert (first.state, first.lost, first.error) == (None, True, "no reply")
    assert (second.lost, servo.comm_error) == (False, "no reply")
    back = servo.poll()
    assert back.recovered and back.state == servo.state and servo.comm_error == ""
    assert not servo.poll().recovered


def test_poll_stamps_the_middle_of_the_read():
    clock = Clock()
    client = ScriptedServo()
    read = client.read_state

    def slow_read() -> ServoState:
        clock.now += 0.004
        return read()

    client.read_state = slow_read  # type: ignore[method-assign]
    assert link(client, clock).poll().half_trip_s == pytest.approx(0.002)


def test_poll_reports_a_hardware_error_when_it_is_latched_only():
    bits = frozenset({"overload"})
    servo = link(ScriptedServo(state(), state(bits=bits), state(bits=bits), state()))
    assert [servo.poll().new_hardware_error for _ in range(4)] == [
        frozenset(), bits, frozenset(), frozenset()]
    assert servo.hardware_error == frozenset()


def test_await_sample_is_woken_by_the_next_poll():
    servo = link(ScriptedServo())
    assert not servo.await_sample(0.0)
    woken = threading.Event()
    waiter = threading.Thread(target=lambda: woken.set() if servo.await_sample(60.0) else None)
    waiter.start()
    while waiter.is_alive():
        servo.poll()
        waiter.join(0.001)
    assert woken.is_set()


def test_a_stopped_goal_cannot_command_again_but_another_goal_can():
    client = ScriptedServo()
    servo = link(client)
    servo.hold_here()
    command = ServoCommand(4.0, 0.7, 0.6)
    servo.stop("goal A")
    servo.send(command, "goal A")
    servo.send(None, "goal B")
    assert client.commands()[-1][1] != 4.0 and servo.stop_written == "goal A"
    servo.send(command, "goal B")
    assert client.commands()[-1] == ("command", 4.0, 0.7, 0.6)


def test_a_goal_that_lost_the_fingers_cannot_command_and_the_question_is_asked_at_the_write():
    """A tick under way when a newer goal took over: its command is dropped, so it cannot
    land after the newer goal's (a release once stopped 0.9 mm short of open that way)."""
    client = ScriptedServo()
    servo = link(client)
    servo.hold_here()
    before = len(client.commands())
    asked: list[bool] = []

    def owns() -> bool:
        asked.append(servo._command_lock.locked())
        return False

    servo.send(ServoCommand(4.0, 0.7, 0.6), "goal A", owns)
    assert len(client.commands()) == before and asked == [True]
    assert servo.send_safely(ServoCommand(4.0, 0.7, 0.6), "goal A", lambda: True) is None
    assert client.commands()[-1] == ("command", 4.0, 0.7, 0.6)


def closing_and_sampled(age_s: float, *later: ServoState
                        ) -> tuple[Clock, ScriptedServo, ServoLink]:
    """A link that sent a closing command, then sampled the servo moving at 0.5 rad/s
    from 3.0 rad, ``age_s`` ago; ``later``: what the servo answers to reads after that."""
    clock = Clock()
    client = ScriptedServo(state(position=3.0, velocity=0.5), *later)
    servo = link(client, clock)
    servo.send(ServoCommand(4.0, 0.5, 0.6))
    clock.now += 0.001
    servo.poll()
    clock.now += age_s
    return clock, client, servo


def test_stop_on_a_fresh_sample_is_one_write_carried_forward():
    _, client, servo = closing_and_sampled(0.01)
    before = len(client.log)
    servo.stop("goal")
    assert client.log[before:] == [("command", pytest.approx(3.0 + 0.5 * 0.01),
                                    servo.config.stop_velocity_rad_s,
                                    servo.config.hold_current_a)]


@pytest.mark.parametrize("age_s", [0.031, None])
def test_stop_reads_the_servo_when_the_sample_cannot_be_trusted(age_s):
    """A sample older than three periods, or none since the last command, is not used."""
    clock = Clock()
    client = ScriptedServo(state(position=3.0, velocity=0.5), state(position=3.2))
    servo = link(client, clock)
    if age_s is None:
        servo.poll()
        servo.send(ServoCommand(4.0, 0.5, 0.6))
    else:
        servo.poll()
        clock.now += age_s
    before = len(client.log)
    servo.stop("goal")
    assert [e[:2] for e in client.log[before:]] == [("read",), ("command", 3.2)]


def test_a_hold_here_command_holds_where_the_fingers_are_when_it_lands():
    """A controller that says "hold here" judged a sample the fingers have moved on from
    by the time its write lands (a starved goal thread): holding at that sample as it was
    would send them back. The link carries its freshest sample forward instead, and reads
    the servo when that sample cannot be trusted; a plain command keeps its position."""
    _, client, servo = closing_and_sampled(0.02, state(position=3.2))
    before = len(client.log)
    servo.send(ServoCommand(3.0, 0.1, 0.6, hold_present=True), "goal")
    assert client.log[before:] == [("command", pytest.approx(3.0 + 0.5 * 0.02), 0.1, 0.6)]
    # the sample now predates the last command: the servo is read
    before = len(client.log)
    servo.send(ServoCommand(3.0, 0.1, 0.6, hold_present=True), "goal")
    assert [e[:2] for e in client.log[before:]] == [("read",), ("command", 3.2)]
    servo.send(ServoCommand(2.5, 0.1, 0.6), "goal")
    assert client.log[-1][:2] == ("command", 2.5)


def test_send_safely_tells_an_unreachable_servo_from_a_hardware_error():
    client = ScriptedServo()
    servo = link(client, retries=0)
    client.faults = [ServoHardwareError("overload", frozenset({"overload"}))]
    assert servo.send_safely(ServoCommand(4.0, 0.5, 0.6)) is None and servo.comm_error == ""
    client.faults = [CommunicationTimeout("no reply")]
    assert servo.send_safely(ServoCommand(4.0, 0.5, 0.6)) == "no reply"
    assert servo.comm_error == "no reply"


def test_torque_off_reports_its_failure():
    client = ScriptedServo()
    servo = link(client)
    assert servo.torque_off() is None and client.log[-1] == ("torque", False)
    client.faults = [PortLost("unplugged")]
    assert servo.torque_off() == "unplugged"


def test_ensure_torque_holds_where_the_fingers_are_only_when_off():
    client = ScriptedServo(state(position=3.1))
    servo = link(client)
    servo.ensure_torque()
    assert client.log[-2:] == [("torque", True), ("command", 3.1,
                                                  servo.config.stop_velocity_rad_s,
                                                  servo.config.hold_current_a)]
    before = len(client.log)
    servo.ensure_torque()
    assert client.log[before:] == [("torque?",)]


def test_reboot_sets_up_again_and_clears_the_hardware_error():
    bits = frozenset({"overheating"})
    client = ScriptedServo(state(bits=bits), state())
    servo = link(client)
    servo.poll()
    assert servo.hardware_error == bits
    servo.reboot(1.0)
    assert servo.hardware_error == frozenset() and client.torque
    names = [e[0] for e in client.log[1:]]
    assert names == ["reboot", "torque", "mode", "current_limit", "read", "torque",
                     "command"]
    assert ("mode", OperatingMode.CURRENT_BASED_POSITION) in client.log


def test_the_set_up_is_retried_as_a_whole():
    client = ScriptedServo()
    client.faults = [CorruptPacket("noise")]
    link(client).prepare(0.8)
    assert client.log == [("torque", False), ("mode", OperatingMode.CURRENT_BASED_POSITION),
                          ("current_limit", 0.8)]


def test_a_failed_reboot_keeps_the_hardware_error():
    bits = frozenset({"overheating"})
    client = ScriptedServo(state(bits=bits))
    servo = link(client)
    servo.poll()
    client.faults = [PortLost("unplugged")]
    with pytest.raises(PortLost):
        servo.reboot(1.0)
    assert servo.hardware_error == bits


def test_the_sample_age_counts_from_when_the_servo_took_it():
    now = [10.0]
    link = ServoLink(ScriptedServo(), GraspConfig(), period_s=0.01, clock=lambda: now[0])
    assert link.sample_age_s() == math.inf
    link.poll()
    now[0] = 10.25
    assert link.sample_age_s() == pytest.approx(0.25)
