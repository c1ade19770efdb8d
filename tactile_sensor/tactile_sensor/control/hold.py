"""The hold after contact: regulate the tactile force onto the target, on windowed means.

Why windows: the tactile force carries the sensor's noise (the paper's 31.5 dB: 0.19 N σ
after a 9-point mean, so about 0.56 N σ per 1 kHz sample), and the driver's filter makes
consecutive forces correlated over its window (40 samples by default). A mean over a few
control periods is a mean of a handful of independent values: today's settle once judged
~30 ms means and held 2.33 N on a 2.0 N target. The regulator therefore gathers at least
``window_samples`` forces (stamped after its last correction took effect: the runner gates
them with ``TactileForce.count_after``) for ``window_s`` before it judges the error; the
mean's σ falls as 1/√samples (0.1 s of the 1 kHz stream: 0.56 N / √100 ≈ 0.06 N). Each
correction is smaller than the one before, so it needs a finer mean: the window doubles
after every correction, up to ``max_window_s`` (0.1, 0.2, 0.4 s: σ 0.06, 0.04, 0.03 N).

Each correction moves the goal by ``gain`` × the error over the skin's stiffness at the
pinion. One radian of the pinion moves each finger ``pitch_radius_m``, and each finger's
skin indents by that much against the fixed object, so the force changes by
``k × pitch_radius_m`` per radian. The FEM skin stiffens from ~1750 N/m at touch to
~2850 N/m at 3 mm; with the 2500 N/m default a gain of 0.8 converges without ringing over
that range (effective gain 0.56 to 0.91).

Settled when a window's mean is within ``tolerance`` of the target, or when the correction
is under half a position pulse (the servo cannot place the fingers finer).

Through the friction of a geared servo (sim/drivetrain.py) the output rests where the
position loop's torque no longer beats the load and the friction at rest: short of its
goal by the loop's lead after a close, past it after an opening, and a goal moved back
within that band moves nothing (about 35 pulses wide on the XM430's sources). The hold
therefore corrects from one side. A force too low raises the goal from the lead the loop
had at rest after closing (``closing_lead_rad``, read from the servo's Position
Trajectory), so the output moves by the correction whatever side of the band it sat on; a
force too high opens the goal by that lead and the correction below where the fingers
are, so the output comes to rest under the target, and the next correction closes onto it.
Within the band the output moves in the steps of its stick-slip (the friction at rest
over that in motion), not in single pulses.

An adaptive hold (one that raises the grip on slip) is a different regulator with the same
two calls: ``add`` the forces, ``command`` the next goal.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from tactile_sensor.control.geometry import GripperGeometry
from tactile_sensor.control.grasp import (
    XM430_LOAD_FRICTION_RATIO,
    LoopLead,
    ServoCommand,
    ServoReading,
    loop_lead_rad,
)
from tactile_sensor.hardware.xm430_table import RAD_PER_PULSE


@dataclass
class ForceSettler:
    """Fixed-force hold: move the goal until a window's mean force sits at the target."""

    geometry: GripperGeometry
    target_force_n: float
    skin_stiffness_n_per_m: float = 2500.0
    tolerance: float = 0.03
    #: The span of forces the first judged mean takes [s] (the goal's clock); it doubles
    #: after every correction up to ``max_window_s``.
    window_s: float = 0.1
    max_window_s: float = 0.4
    gain: float = 0.8
    #: One tactile sample's noise [N] (the paper's 31.5 dB: 0.56 N at 1 kHz): a mean over
    #: the target by less than twice its own σ is not lowered on (lowering through the
    #: friction costs the band's crossing), its window widens instead.
    sample_noise_n: float = 0.56
    #: The mean [N] of the last window judged: the force the hold reports once settled
    #: (a single reading carries the sensor's full noise, 0.19 N σ after the filter).
    judged_n: float | None = None
    #: The loop's lead at rest after a close [rad]: what a goal needs over the output to
    #: move it closed (None until the first judged window reads it).
    closing_lead_rad: float | None = None
    #: The loop as the close saw it in free air (None: not known): the lead a force needs.
    loop: LoopLead | None = None
    _sum_n: float = 0.0
    _count: int = 0
    _window_from_s: float | None = None
    _last_closed: bool = True

    def __post_init__(self) -> None:
        if not (self.target_force_n > 0 and self.skin_stiffness_n_per_m > 0
                and self.window_s >= 0 and 0 < self.gain <= 1 and self.tolerance >= 0
                and self.sample_noise_n >= 0):
            raise ValueError("ForceSettler needs a positive target and stiffness, a window "
                             "of at least 0 s, a gain in (0, 1] and a noise of at least 0.")

    def add(self, sum_n: float, count: int, now_s: float) -> None:
        """Forces that arrived since the last call (their sum and how many); the window
        opens with the first."""
        if count and self._window_from_s is None:
            self._window_from_s = now_s
        self._sum_n += sum_n
        self._count += count

    def restart_window(self) -> None:
        """Drop what the window held (a correction moved the fingers)."""
        self._sum_n, self._count, self._window_from_s = 0.0, 0, None

    def command(self, now_s: float, servo: ServoReading, current_a: float,
                velocity_rad_s: float) -> tuple[ServoCommand | None, bool]:
        """(goal for this tick, or None to hold still; settled?)."""
        if self._window_from_s is None or now_s - self._window_from_s < self.window_s:
            return None, False
        self.judged_n = self._sum_n / self._count
        error = self.judged_n - self.target_force_n
        sigma_n = self.sample_noise_n / math.sqrt(self._count)
        self.restart_window()
        if abs(error) <= self.tolerance * self.target_force_n:
            return None, True
        step_rad = self.gain * error / (self.skin_stiffness_n_per_m
                                        * self.geometry.pitch_radius_m)
        if abs(step_rad) < 0.5 * RAD_PER_PULSE:
            return None, True
        if 0.0 < error <= 2.0 * sigma_n:
            # the mean cannot tell this excess from its noise, and taking it off costs the
            # crossing of the friction's band and an approach from below: judge a longer
            # mean first (a force short of the target is raised at once: that is cheap)
            self.window_s = min(2.0 * self.window_s, max(self.max_window_s, self.window_s))
            return None, False
        self.window_s = min(2.0 * self.window_s, max(self.max_window_s, self.window_s))
        return ServoCommand(self._goal_rad(servo, step_rad), velocity_rad_s, current_a), False

    def _goal_rad(self, servo: ServoReading, step_rad: float) -> float:
        """The goal that moves the output by ``-step_rad`` through the loop's friction.

        The band's closing edge ``e_c`` is the free close's lead plus the lead the
        target's rack force needs (``LoopLead``), or a lead seen at rest after a close if
        larger. Its opening edge: with the motor's torque ``u = Kp e``, closing
        ``u (1 - ratio) = load + f`` and opening ``u (1 - ratio) = load - f`` (the motor
        pulls against friction the load cannot overcome), so ``e_o = 2 e_load / (1 -
        ratio) - e_c``, ``ratio`` the gears' load-dependent friction."""
        lead = loop_lead_rad(servo)
        if lead is not None and self._last_closed and lead > (self.closing_lead_rad or 0.0):
            self.closing_lead_rad = lead  # at rest after a close: on the closing edge
        closing = step_rad < 0.0
        self._last_closed = closing
        # both fingers push the target: the rack force is twice finger A's
        rack_n, radius = 2.0 * self.target_force_n, self.geometry.pitch_radius_m
        force_lead = self.loop.lead_for_n(rack_n, radius) if self.loop is not None else 0.0
        estimate = self.loop.closing_edge_rad(rack_n, radius) if self.loop is not None else 0.0
        closing_edge = max(estimate, self.closing_lead_rad or 0.0)
        if closing:
            present_goal = servo.position_rad + (lead if lead is not None else 0.0)
            return max(present_goal, servo.position_rad + closing_edge) - step_rad
        edge = 2.0 * force_lead / (1.0 - XM430_LOAD_FRICTION_RATIO) - closing_edge
        return servo.position_rad + edge - step_rad - 2.0 * RAD_PER_PULSE
