"""The hold after contact: regulate the tactile force onto the target, on pooled means.

Why pooled means: the tactile force carries the sensor's noise (the paper's 31.5 dB: 0.19 N
σ after a 9-point mean, so about 0.56 N σ per 1 kHz sample), and the driver's filter makes
consecutive forces correlated over its window (40 samples by default). One reading, or a
mean over a few control periods, cannot place a 1 N hold within 5 %: the mean's σ falls as
1/√samples (0.1 s of the 1 kHz stream: 0.56 N / √100 ≈ 0.06 N; 0.4 s: 0.03 N).

So the regulator keeps every force that arrived while the fingers were at rest since the
contact stop, and refers each to where the fingers are now through the skin's stiffness at
the pinion: one radian of the pinion moves each finger ``pitch_radius_m``, and each
finger's skin indents by that much against the fixed object, so the force changes by
``k × pitch_radius_m`` per radian. The servo's encoder says how far a correction really
moved the output, so a correction does not throw the mean away: the estimate after it is
the old mean plus the stiffness times the measured move, and a raise the stick-slip swallowed
shows at once as no move. The stiffness is the FEM skin's tangent at the target (it stiffens
from ~1750 N/m at touch to ~2850 N/m at 3 mm; ``fem_skin_stiffness_n_per_m``), so an error in
it costs only a fraction of each move, not of the force.

It corrects an error beyond the tolerance once it is beyond ``significance`` σ of the
pooled mean (a smaller one may be noise: more forces decide; a lowering, which crosses the
friction's band, needs ``lowering_significance``), by ``gain`` × the error, judged on
forces taken after its last move. A raise closes the error less one σ of the mean (but at
least a pulse): the force it leaves passes the target only where the mean read more than
that low, so a first mean 3 σ low (σ ≈ 0.055 N a tenth of a second after the stop) does
not press a 1 N hold 15 % over; a lowering undershoots, it never presses harder.

It has settled when the error plus the mean's σ is within ``tolerance`` of the target (or
the error is, and the mean is known to half the force of one position pulse), or when the
error is under half a pulse, widened by the stiffness's uncertainty: the servo cannot place
the fingers finer. One pulse (2π/4096 rad of the pinion, 21 µm of each finger) is 0.041 N
on the FEM skin at 1 N and 0.043 N at 1.5 N: 4.1 and 2.8 % of those targets, so their ±5 %
is ±1.2 and ±1.8 pulses.

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

#: The FEM skin under the module (physics' prediction curve, the one the model node
#: serves): its tangent stiffness at touch [N/m] and its rise per newton of force [N/m/N],
#: a line through the tangent at 0.05-7 N within 2 % (test_hold checks it against the FEM).
FEM_TOUCH_STIFFNESS_N_PER_M = 1750.0
FEM_STIFFENING_PER_N = 157.0


def fem_skin_stiffness_n_per_m(force_n: float) -> float:
    """The FEM skin's tangent stiffness at ``force_n`` [N/m]: what a hold there moves on."""
    return FEM_TOUCH_STIFFNESS_N_PER_M + FEM_STIFFENING_PER_N * max(0.0, force_n)


@dataclass
class ForceSettler:
    """Fixed-force hold: move the goal until the pooled mean force sits at the target."""

    geometry: GripperGeometry
    target_force_n: float
    #: The skin's stiffness at the target [N/m] (default: the FEM skin's there).
    skin_stiffness_n_per_m: float = 0.0
    tolerance: float = 0.03
    #: The least span of forces [s] (the goal's clock) and of ADC samples before the first
    #: judgment: the driver's filter correlates its forces over 40 ms.
    window_s: float = 0.08
    min_samples: int = 80
    gain: float = 0.9
    #: A correction needs the error beyond this many σ of the pooled mean: a raise is
    #: cheap, a lowering crosses the friction's band and approaches again from below.
    significance: float = 1.5
    lowering_significance: float = 2.5
    #: A raise closes the error less this many σ of the mean: the force after it passes
    #: the target only where the mean read more than that low, so a mean at a 3 σ low (one
    #: grasp in a few hundred) no longer presses a 1 N hold 15 % over. A lowering aims at
    #: the target: it undershoots, never presses harder.
    raise_caution: float = 1.0
    #: One tactile sample's noise [N] (the paper's 31.5 dB: 0.56 N at 1 kHz).
    sample_noise_n: float = 0.56
    #: The ADC rate that noise is per sample of [Hz]. A driver that publishes fewer forces
    #: (``publish_rate`` 250 Hz: the newest filtered force every 4 ms) still carries the
    #: filtered stream, so a batch counts the samples of the time it spans, at most a
    #: filter's length (``transient_s``) per force: one force stands for no more.
    sample_rate_hz: float = 1000.0
    #: Forces of this long after the fingers came to rest are left out [s]: the driver's
    #: filter (40 samples at 1 kHz) still carries the move in them.
    transient_s: float = 0.04
    #: The estimate [N] at the last judgment: the force the hold reports once settled
    #: (a single reading carries the sensor's full noise, 0.19 N σ after the filter).
    judged_n: float | None = None
    #: The loop's lead at rest after a close [rad]: what a goal needs over the output to
    #: move it closed (None until the first judgment reads it).
    closing_lead_rad: float | None = None
    #: The loop as the close saw it in free air (None: not known): the lead a force needs.
    loop: LoopLead | None = None
    #: How far the skin under the fingers may be from that stiffness (relative): a mean
    #: referred across a move is trusted less by that fraction of the force moved.
    stiffness_uncertainty: float = 0.2
    _pending_sum_n: float = 0.0
    _pending_count: int = 0
    _pending_samples: float = 0.0  # the ADC samples the pending forces stand for
    _last_add_s: float | None = None
    _mean_n: float = 0.0  # the pooled mean at ``_reference_rad`` and its variance [N, N²]
    _variance_n2: float = math.inf
    _count: float = 0.0  # ADC samples pooled
    _reference_rad: float | None = None
    _window_from_s: float | None = None
    _rest_from_s: float | None = None
    _seen_since_move: bool = False  # forces pooled since the last correction
    _last_closed: bool = True

    def __post_init__(self) -> None:
        if self.skin_stiffness_n_per_m == 0.0:
            self.skin_stiffness_n_per_m = fem_skin_stiffness_n_per_m(self.target_force_n)
        if not (self.target_force_n > 0 and self.skin_stiffness_n_per_m > 0
                and self.window_s >= 0 and 0 < self.gain <= 1 and self.tolerance >= 0
                and self.sample_noise_n >= 0 and self.min_samples >= 1 and self.transient_s >= 0
                and self.sample_rate_hz > 0
                and self.stiffness_uncertainty >= 0
                and self.significance >= 0 and self.raise_caution >= 0
                and self.lowering_significance >= 0):
            raise ValueError("ForceSettler needs a positive target and stiffness, a window "
                             "of at least 0 s and one sample, a gain in (0, 1], a noise, "
                             "significance, raise caution and stiffness uncertainty of at "
                             "least 0 and a positive sample rate.")

    @property
    def newton_per_rad(self) -> float:
        return self.skin_stiffness_n_per_m * self.geometry.pitch_radius_m

    def add(self, sum_n: float, count: int, now_s: float) -> None:
        """Forces that arrived since the last call (their sum and how many), all taken at
        rest where the next ``command`` finds the fingers; the window opens with the first."""
        if not count:
            return
        span_s = count / self.sample_rate_hz
        if self._last_add_s is not None:
            span_s = max(span_s, now_s - self._last_add_s)
        self._last_add_s = now_s
        if self._rest_from_s is None:
            self._rest_from_s = now_s
        if now_s - self._rest_from_s < self.transient_s:
            return
        if self._window_from_s is None:
            self._window_from_s = now_s
        self._pending_sum_n += sum_n
        self._pending_count += count
        self._pending_samples += min(span_s, count * max(self.transient_s, 1.0
                                                         / self.sample_rate_hz)
                                     ) * self.sample_rate_hz

    def estimate_n(self, position_rad: float) -> float | None:
        """The pooled mean force referred to ``position_rad`` (None before any force)."""
        return self._referred(position_rad)[0]

    def sigma_n(self, position_rad: float) -> float:
        """That mean's standard deviation there [N] (inf before any force)."""
        return math.sqrt(self._referred(position_rad)[1])

    def _referred(self, position_rad: float) -> tuple[float | None, float]:
        """The mean so far referred to ``position_rad`` through the stiffness, and its
        variance, grown by the stiffness's uncertainty over the force it moved."""
        if self._reference_rad is None:
            return None, math.inf
        moved_n = self.newton_per_rad * (position_rad - self._reference_rad)
        return (self._mean_n + moved_n,
                self._variance_n2 + (self.stiffness_uncertainty * moved_n) ** 2)

    def _pool(self, position_rad: float) -> None:
        """Fold the pending forces in, weighed against the mean so far referred here."""
        n, samples = self._pending_count, self._pending_samples
        if not n:
            return
        batch_n = self._pending_sum_n / n
        batch_var = self.sample_noise_n**2 / samples
        self._pending_sum_n, self._pending_count, self._pending_samples = 0.0, 0, 0.0
        self._count += samples
        self._seen_since_move = True
        prior, prior_var = self._referred(position_rad)
        self._reference_rad = position_rad
        if prior is None or batch_var == 0.0:
            self._mean_n, self._variance_n2 = batch_n, batch_var
            return
        weight = batch_var / (prior_var + batch_var)  # the prior's share
        self._mean_n = weight * prior + (1.0 - weight) * batch_n
        self._variance_n2 = prior_var * batch_var / (prior_var + batch_var)

    def command(self, now_s: float, servo: ServoReading, current_a: float,
                velocity_rad_s: float) -> tuple[ServoCommand | None, bool]:
        """(goal for this tick, or None to hold still; settled?)."""
        self._pool(servo.position_rad)
        if (not self._seen_since_move or self._window_from_s is None
                or now_s - self._window_from_s < self.window_s
                or self._count < self.min_samples):
            return None, False
        estimate = self.estimate_n(servo.position_rad)
        assert estimate is not None
        self.judged_n = estimate
        error = estimate - self.target_force_n
        sigma_n = self.sigma_n(servo.position_rad)
        allowed = self.tolerance * self.target_force_n
        step_rad = self.gain * self._missing_n(error, sigma_n) / self.newton_per_rad
        # within half a pulse of the target, the skin's stiffness as uncertain as assumed:
        # the next pulse either way lands no nearer
        tiny = abs(error) / self.newton_per_rad < (0.5 + self.stiffness_uncertainty
                                                   ) * RAD_PER_PULSE
        pulse_n = self.newton_per_rad * RAD_PER_PULSE
        if abs(error) <= allowed:
            if abs(error) + sigma_n <= allowed or sigma_n <= 0.5 * pulse_n:
                return None, True  # within, and known so (or finer than a pulse places)
            return None, False  # within as far as the mean tells: more forces decide
        if abs(error) <= (self.lowering_significance if error > 0.0
                          else self.significance) * sigma_n:
            return None, False  # the mean cannot yet tell this error from its noise
        if tiny:
            return None, True
        self._rest_from_s = self._last_add_s = None  # a new transient after this move
        self._seen_since_move = False  # judged again on forces taken after it
        return ServoCommand(self._goal_rad(servo, step_rad), velocity_rad_s, current_a), False

    def _missing_n(self, error_n: float, sigma_n: float) -> float:
        """The error a correction closes: a lowering's whole; a raise's less
        ``raise_caution`` σ, but at least one position pulse (up to the error): the servo
        places no finer, and a raise of a fraction of one waits out the stick-slip."""
        if error_n >= 0.0:
            return error_n
        pulse_n = self.newton_per_rad * RAD_PER_PULSE
        cautious = -error_n - self.raise_caution * sigma_n
        return -min(-error_n, max(cautious, pulse_n / self.gain))

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
