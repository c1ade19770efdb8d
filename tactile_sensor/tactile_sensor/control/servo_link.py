"""The gripper's one servo as the control loop and the goals share it (no ROS).

Three threads touch the servo: the control loop samples it every period, the running goal
writes its commands, and a cancel writes a stop. This class owns what they share: the latest
sample, the last command, the communication and hardware-error state, and the lock that
orders a goal's commands against its stop (once a goal's stop is written, no command of that
goal may follow it and restart the fingers). Goals are told apart by a token (any object:
the node passes the ROS goal handle).

Bus faults: a lost or damaged status packet is retried (``comm_retries`` times), since one
bad packet on a busy bus must not abort a grasp; hardware errors and anything else pass
straight through.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol, TypeVar

from tactile_sensor.control.grasp import GraspConfig, ServoCommand
from tactile_sensor.control.stop import stop_position_rad
from tactile_sensor.hardware.errors import (
    CommunicationTimeout,
    CorruptPacket,
    DynamixelError,
    ServoHardwareError,
)
from tactile_sensor.hardware.xm430 import ServoState
from tactile_sensor.hardware.xm430_table import OperatingMode

T = TypeVar("T")
#: Samples whose host time ``sampled_at`` still knows: a goal asks for the one it was just
#: given, and the loop may have sampled again meanwhile.
SAMPLE_TIMES_KEPT = 8


class ServoClient(Protocol):
    """What the link needs of an XM430 client (hardware/xm430.py's Xm430Client)."""

    def read_state(self) -> ServoState: ...
    def command_position(self, position_rad: float, velocity_rad_s: float,
                         acceleration_rad_s2: float = ...,
                         goal_current_a: float | None = None) -> None: ...
    def set_torque(self, enabled: bool) -> None: ...
    def torque_enabled(self) -> bool: ...
    def set_operating_mode(self, mode: OperatingMode) -> None: ...
    def set_current_limit_a(self, amps: float) -> None: ...
    def reboot(self, wait_s: float = ...) -> None: ...


def call_retrying(call: Callable[[], T], retries: int) -> T:
    """``call()``, repeated up to ``retries`` more times while its status packet is lost or
    damaged; the last such fault, and every other error, propagates."""
    if retries < 0:
        raise ValueError(f"retries = {retries} must be >= 0; pass how many repeats a lost "
                         "packet gets (e.g. 2).")
    for attempt in range(retries + 1):
        try:
            return call()
        except (CommunicationTimeout, CorruptPacket):
            if attempt == retries:
                raise
    raise AssertionError("unreachable")


@dataclass(frozen=True)
class Poll:
    """What one sample of the control loop found."""

    state: ServoState | None
    #: Half the read's round trip [s]: the servo sampled this long before the reply came.
    half_trip_s: float = 0.0
    #: Why the servo did not answer ("" when it did).
    error: str = ""
    #: This failure is the first since the servo last answered (log it once).
    lost: bool = False
    #: The servo answers again after failures.
    recovered: bool = False
    #: Hardware-error bits latched since the previous sample (empty: none new).
    new_hardware_error: frozenset[str] = frozenset()


class ServoLink:
    """The servo, its latest sample and its last command, shared by loop, goals and cancel."""

    def __init__(self, client: ServoClient, config: GraspConfig, *, period_s: float,
                 retries: int = 2, clock: Callable[[], float] = time.monotonic,
                 wall_clock: Callable[[], float] = time.time) -> None:
        self.client, self.config, self.period_s = client, config, period_s
        self.retries, self._clock, self._wall = retries, clock, wall_clock
        self.state: ServoState | None = None
        #: The latest sample, when the servo took it (clock [s]) and half that read's round
        #: trip (how long a packet takes to reach the servo) [s].
        self._sample: tuple[ServoState, float, float] | None = None
        self.comm_error = ""
        self.hardware_error: frozenset[str] = frozenset()
        self._command_lock = threading.Lock()
        self._halted: object | None = None
        #: The token whose stop was written last (a failed stop leaves the previous one).
        self.stop_written: object | None = None
        #: The goal last written and when (clock [s]): a sample older than the last command
        #: does not tell how the output moves now.
        self._heading_to_rad: float | None = None
        self._commanded_at = 0.0
        self._sampled = threading.Event()
        #: (sample, host time [s] the servo took it): what stamps are compared with.
        self._sample_times: deque[tuple[ServoState, float]] = deque(maxlen=SAMPLE_TIMES_KEPT)

    def retrying(self, call: Callable[[], T]) -> T:
        return call_retrying(call, self.retries)

    # -- setup and recovery -------------------------------------------------------------
    def prepare(self, current_limit_a: float) -> None:
        """Torque off, current-based position mode, the current limit (EEPROM items)."""
        def prepare_once() -> None:
            self.client.set_torque(False)
            self.client.set_operating_mode(OperatingMode.CURRENT_BASED_POSITION)
            self.client.set_current_limit_a(current_limit_a)
        self.retrying(prepare_once)

    def hold_here(self, torque: bool = False) -> None:
        """Command the present position (turning torque on first when asked)."""
        def hold_once() -> None:
            state = self.client.read_state()
            self.state = state
            if torque:
                self.client.set_torque(True)
            self._command(state.position_rad, self.config.stop_velocity_rad_s,
                          self.config.hold_current_a)
        self.retrying(hold_once)

    def ensure_torque(self) -> None:
        """Torque on, holding where the fingers are, unless it is on already."""
        if not self.retrying(self.client.torque_enabled):
            self.hold_here(torque=True)

    def reboot(self, current_limit_a: float) -> None:
        """Reboot (clears a latched hardware error), set up again, hold with torque on."""
        self.client.reboot()
        self.prepare(current_limit_a)
        self.hardware_error = frozenset()
        self.hold_here(torque=True)

    def torque_off(self) -> str | None:
        """Torque off, once; why it failed, or None."""
        try:
            self.client.set_torque(False)
        except DynamixelError as exc:
            return str(exc)
        return None

    # -- the control loop ---------------------------------------------------------------
    def poll(self) -> Poll:
        """Sample the servo once (the control loop's read) and wake whoever awaits it."""
        before = self._clock()
        try:
            state = self.retrying(self.client.read_state)
        except DynamixelError as exc:
            lost = not self.comm_error
            self.comm_error = str(exc)
            return Poll(None, error=self.comm_error, lost=lost)
        after, wall_after = self._clock(), self._wall()
        # the servo sampled its state between request and reply: stamp the middle
        half = 0.5 * (after - before)
        self._sample_times.append((state, wall_after - half))
        recovered = bool(self.comm_error)
        self.comm_error = ""
        self.state = state
        self._sample = (state, after - half, half)
        self._sampled.set()
        bits = state.hardware_error
        new = bits if bits and bits != self.hardware_error else frozenset()
        self.hardware_error = bits
        return Poll(state, half, recovered=recovered, new_hardware_error=new)

    def sample_age_s(self) -> float:
        """How long ago the servo took the latest sample [s] (inf before the first): a goal
        that acts on an older one acts on where the fingers no longer are."""
        sample = self._sample
        return self._clock() - sample[1] if sample is not None else float("inf")

    def sampled_at(self, state: object) -> float | None:
        """Host time [s] (``wall_clock``, the clock messages are stamped with) at which the
        servo took ``state``, one of the last samples; None for any other."""
        for sample, at_s in reversed(tuple(self._sample_times)):  # one step under the GIL
            if sample is state:
                return at_s
        return None

    def await_sample(self, timeout_s: float) -> bool:
        """Wait for the loop's next sample (or ``timeout_s``); True when one came."""
        self._sampled.clear()
        return self._sampled.wait(timeout_s)

    # -- commands -----------------------------------------------------------------------
    def _command(self, goal_rad: float, velocity_rad_s: float, current_a: float) -> None:
        self.client.command_position(goal_rad, velocity_rad_s, goal_current_a=current_a)
        self._heading_to_rad = goal_rad
        self._commanded_at = self._clock()

    def send(self, command: ServoCommand | None, token: object | None = None,
             owns: Callable[[], bool] | None = None) -> None:
        """Write a goal's command, unless that goal has been stopped by a cancel or, asked
        under the write's lock, ``owns()`` says a newer goal has the fingers now: a tick
        under way when the newer goal took over would otherwise land after the newer
        goal's first command and send the fingers back where the old goal wanted them."""
        if command is None:
            return
        with self._command_lock:
            if token is not None and self._halted is token:
                return
            if owns is not None and not owns():
                return
            goal = (self._present_position_rad() if command.hold_present
                    else command.goal_position_rad)
            self.retrying(lambda: self._command(
                goal, command.profile_velocity_rad_s, command.goal_current_a))

    def send_safely(self, command: ServoCommand | None, token: object | None = None,
                    owns: Callable[[], bool] | None = None) -> str | None:
        """``send``; why the servo is unreachable (also left in ``comm_error``), or None. A
        hardware error is not a failure here: the loop reports it through the state."""
        try:
            self.send(command, token, owns)
        except ServoHardwareError:
            return None
        except DynamixelError as exc:
            self.comm_error = str(exc)
            return self.comm_error
        return None

    def stop(self, token: object) -> None:
        """Stop the fingers where they are now, in ONE write when the loop's last sample is
        fresh (its position carried forward by velocity x age; see control/stop.py), else
        read the servo first. Later commands of ``token``'s goal are dropped."""
        config = self.config
        with self._command_lock:
            self._halted = token
            goal = self._present_position_rad()
            self.retrying(lambda: self._command(goal, config.stop_velocity_rad_s,
                                                config.hold_current_a))
            self.stop_written = token

    def _present_position_rad(self) -> float:
        """Where the output will be when a write sent now reaches the servo: the loop's
        last sample carried forward (control/stop.py) while it is fresh and newer than the
        last command, else read from the servo (one more transaction). Holding at a sample
        as it was would send the fingers back by the distance they moved since it was
        taken: a goal thread starved for 0.1 s at 10 mm/s reverses them 1 mm."""
        sample = self._sample
        if (sample is not None and not sample[0].hardware_error
                and sample[1] > self._commanded_at):
            state, sampled_at, half = sample
            lands_at = self._clock() + min(half, 0.5 * self.period_s)
            goal = stop_position_rad(
                state.position_rad, state.velocity_rad_s, lands_at - sampled_at,
                max_age_s=3.0 * self.period_s, heading_to_rad=self._heading_to_rad)
            if goal is not None:
                return goal
        return self.retrying(self.client.read_state).position_rad
