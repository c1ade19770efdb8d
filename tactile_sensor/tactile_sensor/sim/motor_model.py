"""A quasi-static model of the XM430-W210 in (current-based) position control.

Why quasi-static: the servo's 212.6:1 gearbox and its position loop make the output follow
the profile trajectory closely until the load needs more torque than the current limit
allows; then the output stalls where the load torque equals the available torque. Modelling
exactly that (instead of a stiff second-order plant) stays stable at any step size against
a stiff rod, and gives the two things the gripper cares about: where the fingers stop and
what Present Current reads while they press.

With a :class:`~tactile_sensor.sim.drivetrain.Drivetrain` (the default: sources in
sim/drivetrain.py) the output is no longer ideal: current-based position mode's P loop
sets the current from the trajectory's lead over the output (clipped at the current
limit), the motor's torque meets the friction budget (torque offset, Coulomb, Stribeck,
load-dependent, viscous) and the load through the play between the output and the racks.
Each 1 ms step the output sticks while the net torque stays within the budget at rest, or
moves to where the net torque equals the budget at the speed it moves with (no inertia:
the 212.6:1 gear's reflected inertia settles within a step). ``drivetrain=None`` keeps the
ideal servo (torque = current x the datasheet's constant, 0.02 A of friction).

Sign convention: positive angle closes the gripper; ``load_torque(position)`` is the torque
the motor must supply to hold that position (positive when the load pushes back against
closing).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

from tactile_sensor.sim.drivetrain import DEFAULT_DRIVETRAIN, Drivetrain

#: Torque constant at the output shaft [N m/A] (3.0 N m stall at 2.3 A, 12 V datasheet).
TORQUE_CONSTANT_NM_PER_A = 3.0 / 2.3
#: Winding resistance so that 12 V drives 2.3 A at stall [ohm].
WINDING_RESISTANCE_OHM = 12.0 / 2.3
#: No-load speed at 12 V (77 rpm) [rad/s].
NO_LOAD_SPEED_RAD_S_AT_12V = 77.0 * 2.0 * math.pi / 60.0
#: Torque that back-drives the gearbox with the torque off [N m].
BACKDRIVE_TORQUE_NM = 0.15
#: Coulomb friction of gearbox and guide seen as current [A].
FRICTION_CURRENT_A = 0.02


@dataclass(frozen=True)
class MotorCommand:
    """What the control table asks of the motor this step (SI units)."""

    torque_on: bool
    goal_position_rad: float
    #: 0 means "no profile" (as Profile Velocity 0 on the servo): run at the no-load speed.
    profile_velocity_rad_s: float
    #: 0 means an infinite acceleration (as Profile Acceleration 0).
    profile_acceleration_rad_s2: float
    #: Magnitude of the available current (Goal Current in current-based position mode,
    #: Current Limit in position mode).
    current_limit_a: float
    input_voltage_v: float = 12.0
    #: Position P Gain (control table item 84; factory 800).
    position_p_gain: float = 800.0


@dataclass
class MotorState:
    #: The output shaft (what Present Position reads).
    position_rad: float
    velocity_rad_s: float = 0.0
    current_a: float = 0.0
    trajectory_position_rad: float = 0.0
    trajectory_velocity_rad_s: float = 0.0
    stalled: bool = False
    #: Where the racks (the fingers) are, in pinion angle: the output less the play.
    rack_position_rad: float = 0.0


class MotorModel:
    """Profile generator + torque-limited quasi-static output stage + thermal model."""

    def __init__(self, position_rad: float = 0.0,
                 load_torque: Callable[[float], float] | None = None,
                 ambient_temperature_c: float = 30.0,
                 drivetrain: Drivetrain | None = DEFAULT_DRIVETRAIN,
                 pitch_radius_m: float = 0.014) -> None:
        #: Torque the load needs at a rack position (positive resists closing).
        self.load_torque = load_torque or (lambda _p: 0.0)
        self.drivetrain = drivetrain
        #: Where the fingers' guide friction acts on the pinion [m].
        self.pitch_radius_m = pitch_radius_m
        # the fingers last opened: the racks sit on the pinion's opening face
        self.state = MotorState(position_rad, trajectory_position_rad=position_rad,
                                rack_position_rad=position_rad)
        self.temperature_c = ambient_temperature_c
        self.ambient_temperature_c = ambient_temperature_c
        #: Seconds the current has been at the stall value (drives the overload flag).
        self.overload_time_s = 0.0

    def reset_trajectory(self) -> None:
        """Restart the profile from where the output is (torque on, mode change, reboot)."""
        self.state.trajectory_position_rad = self.state.position_rad
        self.state.trajectory_velocity_rad_s = 0.0

    def step(self, dt: float, command: MotorCommand) -> MotorState:
        """Advance by ``dt`` seconds (sub-stepped at 1 ms); no time, no change."""
        if not dt > 0:
            return self.state
        steps = max(1, math.ceil(dt / 1e-3))
        for _ in range(steps):
            self._step(dt / steps, command)
        return self.state

    # -- internals -------------------------------------------------------------------------

    def _speed_limit(self, voltage_v: float) -> float:
        return NO_LOAD_SPEED_RAD_S_AT_12V * max(voltage_v, 0.0) / 12.0

    def _advance_profile(self, dt: float, command: MotorCommand) -> None:
        """One step of the profile generator. A new goal starts from the present trajectory
        velocity (the XM430's "velocity override"): with a finite Profile Acceleration a
        goal behind a moving output is overshot and approached again from the other side;
        with 0 (unlimited) the trajectory changes velocity at once."""
        s = self.state
        v_max = command.profile_velocity_rad_s or self._speed_limit(command.input_voltage_v)
        v_max = min(v_max, self._speed_limit(command.input_voltage_v))
        a_max = command.profile_acceleration_rad_s2 or math.inf
        error = command.goal_position_rad - s.trajectory_position_rad
        if math.isfinite(a_max):
            # fastest speed from which we can still stop at the goal
            v_target = math.copysign(min(v_max, math.sqrt(2.0 * a_max * abs(error))), error)
            dv = max(-a_max * dt, min(a_max * dt, v_target - s.trajectory_velocity_rad_s))
            v = s.trajectory_velocity_rad_s + dv
            can_stop = abs(v) <= 2.0 * a_max * dt
        else:
            v = math.copysign(min(v_max, abs(error) / dt), error) if error else 0.0
            can_stop = True
        after = s.trajectory_position_rad + v * dt
        reached = error == 0.0 or (command.goal_position_rad - after) * error <= 0.0
        if reached and can_stop:
            s.trajectory_position_rad = command.goal_position_rad
            s.trajectory_velocity_rad_s = 0.0
        else:
            s.trajectory_position_rad = after
            s.trajectory_velocity_rad_s = v

    def _capacity_nm(self, command: MotorCommand) -> float:
        if not command.torque_on:
            return BACKDRIVE_TORQUE_NM
        stall_a = max(command.input_voltage_v, 0.0) / WINDING_RESISTANCE_OHM
        return TORQUE_CONSTANT_NM_PER_A * min(abs(command.current_limit_a), stall_a)

    def _solve(self, inside: float, outside: float, capacity: float) -> float:
        """Bisect for the position between ``inside`` (load within capacity) and ``outside``."""
        for _ in range(40):
            mid = 0.5 * (inside + outside)
            if abs(self.load_torque(mid)) <= capacity:
                inside = mid
            else:
                outside = mid
            if abs(outside - inside) < 1e-7:
                break
        return inside

    def _step(self, dt: float, command: MotorCommand) -> None:
        if self.drivetrain is not None:
            self._step_drivetrain(dt, command, self.drivetrain)
        else:
            self._step_ideal(dt, command)
        self._heat(dt, command)

    def _current_cap_a(self, command: MotorCommand) -> float:
        stall_a = max(command.input_voltage_v, 0.0) / WINDING_RESISTANCE_OHM
        return min(abs(command.current_limit_a), stall_a)

    def _rack_at(self, output_rad: float, train: Drivetrain) -> tuple[float, bool]:
        """(rack position, whether the pinion bears on it) with the output there: the play
        operator; inside the play a rack the skin pushes open goes to the closing face."""
        before = self.state.rack_position_rad
        rack = train.rack_after(before, output_rad)
        closing_face = output_rad - train.backlash_rad
        if rack > closing_face and self.load_torque(rack) > 0.0:
            rack = closing_face
        return rack, rack != before or rack in (closing_face, output_rad)

    def _step_drivetrain(self, dt: float, command: MotorCommand, train: Drivetrain) -> None:
        s = self.state
        if command.torque_on:
            self._advance_profile(dt, command)
        else:
            self.reset_trajectory()
        trajectory = s.trajectory_position_rad
        cap = self._current_cap_a(command)
        kp = train.gain_a_per_rad(command.position_p_gain)
        guide_nm = 2.0 * train.guide_friction_n * self.pitch_radius_m

        def current(output: float) -> float:
            if not command.torque_on:
                return 0.0
            return max(-cap, min(cap, kp * (trajectory - output)))

        def net_and_budget(output: float, velocity: float) -> tuple[float, float]:
            rack, engaged = self._rack_at(output, train)
            torque = TORQUE_CONSTANT_NM_PER_A * current(output)
            budget = train.friction_nm(velocity, torque, guide_nm if engaged else 0.0)
            if not command.torque_on:
                budget = max(budget, BACKDRIVE_TORQUE_NM)
            return torque - self.load_torque(rack), budget

        p0 = s.position_rad
        # Without inertia the output slides at the trajectory's speed or rests: a sliding
        # output keeps sliding against the friction at that speed, one at rest breaks away
        # only past the friction at rest (the stick-slip of a trajectory that starts).
        sliding = abs(s.trajectory_velocity_rad_s)
        net0, holding = net_and_budget(p0, sliding if s.velocity_rad_s else 0.0)
        p1 = p0
        if abs(net0) > holding:
            direction = math.copysign(1.0, net0)
            far = p0 + direction * self._speed_limit(command.input_voltage_v) * dt

            def surplus(output: float) -> float:
                net, budget = net_and_budget(output, sliding)
                return direction * net - budget

            at_far = surplus(far)
            p1 = far if at_far >= 0.0 else _root(surplus, p0, abs(net0) - holding, far, at_far)
        s.rack_position_rad = self._rack_at(p1, train)[0]
        s.velocity_rad_s = (p1 - p0) / dt
        s.position_rad = p1
        s.current_a = current(p1)
        s.stalled = command.torque_on and abs(s.current_a) >= cap > 0.0 and p1 == p0

    def _step_ideal(self, dt: float, command: MotorCommand) -> None:
        s = self.state
        capacity = self._capacity_nm(command)
        p0 = s.position_rad
        if command.torque_on:
            self._advance_profile(dt, command)
            wanted = s.trajectory_position_rad
        else:
            wanted = p0
            self.reset_trajectory()
        max_move = self._speed_limit(command.input_voltage_v) * dt
        p1 = p0 + max(-max_move, min(max_move, wanted - p0))
        within = abs(self.load_torque(p1)) <= capacity
        s.stalled = False
        if not within:
            s.stalled = True
            load0 = abs(self.load_torque(p0))
            if abs(capacity - load0) <= 1e-6 * capacity:
                p1 = p0  # already pressing with everything allowed: stay
            elif load0 <= capacity:
                p1 = self._solve(p0, p1, capacity)
            else:
                # back-driven: yield in the direction that relieves the load
                back = p0 - math.copysign(max_move, self.load_torque(p0))
                p1 = self._solve(back, p0, capacity) if abs(
                    self.load_torque(back)) <= capacity else back
        velocity = (p1 - p0) / dt
        load = self.load_torque(p1)
        current = load / TORQUE_CONSTANT_NM_PER_A
        if command.torque_on:
            if velocity:
                current += math.copysign(FRICTION_CURRENT_A, velocity)
            if s.stalled:
                # the position loop saturates: it pushes with everything it is allowed
                current = math.copysign(capacity / TORQUE_CONSTANT_NM_PER_A,
                                        load if load else wanted - p1)
        else:
            current = 0.0
        s.position_rad, s.velocity_rad_s, s.current_a = p1, velocity, current
        s.rack_position_rad = p1

    def _heat(self, dt: float, command: MotorCommand) -> None:
        current = self.state.current_a
        # first-order thermal model: ~10 K/W, 60 s time constant
        heat_w = current * current * WINDING_RESISTANCE_OHM
        target = self.ambient_temperature_c + 10.0 * heat_w
        self.temperature_c += (target - self.temperature_c) * min(1.0, dt / 60.0)
        stall_a = max(command.input_voltage_v, 0.0) / WINDING_RESISTANCE_OHM
        if command.torque_on and abs(current) >= 0.9 * stall_a > 0.0:
            self.overload_time_s += dt
        else:
            self.overload_time_s = 0.0


def _root(f: Callable[[float], float], inside: float, f_inside: float, outside: float,
          f_outside: float, tolerance_rad: float = 1e-7) -> float:
    """A root of ``f`` between ``inside`` (f > 0 there, ``f_inside``) and ``outside``
    (f < 0): the Illinois variant of regula falsi, a handful of load evaluations where
    bisection takes forty."""
    a, fa = inside, f_inside
    b, fb = outside, f_outside
    side = 0
    for _ in range(40):
        c = b - fb * (b - a) / (fb - fa) if fb != fa else 0.5 * (a + b)
        fc = f(c)
        if fc >= 0.0:
            a, fa = c, fc
            if side == 1:
                fb *= 0.5
            side = 1
        else:
            b, fb = c, fc
            if side == -1:
                fa *= 0.5
            side = -1
        if abs(b - a) < tolerance_rad:
            break
    return a
