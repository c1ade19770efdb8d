"""The slip-aware hold: grip at a margin over the least force that keeps the object, learn
the friction from a probe's slip, raise the grip when the friction margin closes.

Why this way (docs/gripper.md, "The adaptive hold"): the slip study chose the friction
margin m = mu Fn - |Ft|, low-passed at 20 Hz, against k sigma_m (sensing/slip_margin.py);
it warns while the load still rises, before the contact breaks away, but it needs mu. The
hold therefore runs in three phases:

1. *waiting*: mu unknown, the grip stays where the grasp settled. Each steady shear it
   sees (two windows of ``steady_s`` alike, not ringing, above the noise's own |Ft|)
   shows that the grip kept it: the least grip per |Ft| so far is a ratio that keeps the
   object, so a load that rises k sigma_t above what the grip covers raises the grip in
   that ratio at once (``onset``, margin NaN), with no friction needed. Once the steady
   shear is four of the falls a probe resolves deep (``PROBE_LEVELS`` x 0.078 N: 0.31 N
   on each skin, an object of about 65 g; the 20 Hz margin's 3 k sigma_t, 0.78 N, would
   leave every object under 160 g unprobed), and the grip is at most half the ceiling
   (``probe_headroom``: an object the ceiling cannot double the grip of keeps this
   reflex):
2. *probing*: lower the grip at ``probe_rate_n_s``. While the object sticks, |Ft| stays at
   its level; at the break-away it drops by (mu_s - mu_k) Fn and then falls with the grip
   as mu_k Fn. The probe stops at the first run of its latest ticks (1 to 20) whose mean
   |Ft| is ``probe_sigmas`` standard errors below the level (the detector's false-alarm
   rate at the ticks' bandwidth): a step shows in a tick or two, a slow fall in a longer
   run. mu is the slope of |Ft| on Fn through the origin
   over the sliding ticks (at least 5: the ticks just before the break-away sat at mu_s),
   two standard errors lower (the kinetic friction, what the margin needs; erring low),
   and the grip goes at once to the least grip plus the detector's least margin: (|Ft| +
   2 k sigma_m) / mu. A probe that reaches ``max_friction`` without a slip takes the
   ratio it saw, a lower bound (more grip).
3. *holding*: whenever the margin is below k sigma_m (an onset) the grip goes to (|Ft| +
   2 k sigma_m) / mu in one command: the reflex. Never above ``ceiling_n``; when the grip
   at the ceiling has had ``settle_s`` and the margin is still closed, the hold says
   ``slipping`` and stays at the ceiling.

Grip to position: the skin's stiffness at the pinion (``newton_per_rad``) from an anchor,
the servo position and the mean force over the last rest; re-anchored after each rest of
``settle_s``, so the grip converges on its target as the fixed hold does (within
``tolerance``); a raise carries the position loop's lead through the servo's friction,
read at the output's first tick at rest after a close (``_regulate``). Pure: one
``update`` a control tick, no clock, no I/O.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from enum import StrEnum

from tactile_sensor.control.errors import InvalidConfiguration, InvalidRequest
from tactile_sensor.hardware.xm430_table import RAD_PER_PULSE
from tactile_sensor.sensing.slip_margin import MarginFilter, MarginNoise, threshold_sigmas

#: The ticks over which a probe that saw no slip takes the ratio |Ft| / Fn (100 ms at
#: 100 Hz).
RATIO_TICKS = 10
#: The longest run of ticks a probe tests for a fall of |Ft| (200 ms at 100 Hz).
PROBE_TICKS = 20
#: A probe starts on a steady |Ft| this many of its falls deep [1].
PROBE_LEVELS = 4.0
#: The hold modes a goal may ask for: today's fixed force, or the slip-aware hold.
HOLD_MODES = ("fixed", "adaptive")
#: The shear fingertip's force noise (docs/gripper.md, "Can the sensor see slip?": 38.9 mN
#: of Ft and 57.0 mN of Fn at 10 Hz, the array layout at 1 mm) [N / sqrt(Hz)].
SHEAR_FINGERTIP_NOISE = MarginNoise(shear_density=0.0389 / math.sqrt(10.0),
                                    normal_density=0.0570 / math.sqrt(10.0))


@dataclass(frozen=True)
class HoldSettings:
    """The gripper's hold parameters (``hold_mode``, ``hold_time``, ``shear_sensing``,
    ``slip_bandwidth``): what a goal gets when it asks for nothing."""

    mode: str = "fixed"
    #: How long an adaptive hold runs before the result; 0 = until a cancel or a newer
    #: goal [s].
    hold_time_s: float = 0.0
    #: The fingertip reports the force along and across the fingers (gripper_shear).
    shear_sensing: bool = False
    bandwidth_hz: float = 20.0
    noise: MarginNoise = SHEAR_FINGERTIP_NOISE

    def __post_init__(self) -> None:
        if self.mode not in HOLD_MODES or not (math.isfinite(self.hold_time_s)
                                               and self.hold_time_s >= 0):
            raise InvalidConfiguration(
                f"Parameter 'hold_mode' = {self.mode!r} or 'hold_time' = {self.hold_time_s!r}"
                f" is not valid; use one of {', '.join(HOLD_MODES)} and a time >= 0 s.")
        if self.mode == "adaptive" and not self.shear_sensing:
            raise InvalidConfiguration(
                "Parameter 'hold_mode' is 'adaptive' but 'shear_sensing' is false: an "
                "adaptive hold needs a fingertip that feels shear; use configuration "
                "gripper_shear or hold_mode fixed.")

    def resolve(self, mode: str, hold_time_s: float) -> tuple[str, float]:
        """A goal's mode and hold time ('' and 0: these settings'); InvalidRequest in one
        sentence for one the gripper cannot run."""
        mode = mode or self.mode
        if mode not in HOLD_MODES:
            raise InvalidRequest(f"Hold mode {mode!r} is not one of {', '.join(HOLD_MODES)};"
                                 " ask for one of them (or '' for the gripper's hold_mode).")
        if not (math.isfinite(hold_time_s) and hold_time_s >= 0):
            raise InvalidRequest(f"Hold time {hold_time_s} s must be >= 0 (0: the "
                                 "gripper's hold_time); request e.g. 5 s.")
        if mode == "adaptive" and not self.shear_sensing:
            raise InvalidRequest("An adaptive hold needs a fingertip that feels shear, and "
                                 "this gripper has none (shear_sensing is false); use "
                                 "configuration gripper_shear or hold_mode fixed.")
        return mode, hold_time_s or self.hold_time_s


class HoldPhase(StrEnum):
    WAITING = "waiting"
    PROBING = "probing"
    HOLDING = "holding"
    SLIPPING = "slipping"


class EventKind(StrEnum):
    """What a ``~/slip`` event says."""

    #: A probe's slip gave the friction; the grip went to the least grip plus the margin.
    LEARNED = "learned"
    #: The margin closed: the grip was raised.
    ONSET = "onset"
    #: The margin stays closed at the force ceiling: the object slips.
    SLIPPING = "slipping"


@dataclass(frozen=True)
class SlipHoldConfig:
    noise: MarginNoise
    #: The most the grip may reach [N] (the gripper's force ceiling).
    ceiling_n: float
    #: The skin's force per radian of the pinion [N/rad].
    newton_per_rad: float
    #: Lowest closing position the grip may command (the closed limit) [rad].
    closed_position_rad: float
    bandwidth_hz: float = 20.0
    control_rate_hz: float = 100.0
    #: The grip falls this fast while probing [N/s].
    probe_rate_n_s: float = 8.0
    #: The shear steady this long before a probe [s].
    steady_s: float = 0.3
    #: A probe stops at |Ft| / Fn = this without a slip [1].
    max_friction: float = 2.0
    #: At rest this long after a command before the mean force is judged [s].
    settle_s: float = 0.15
    #: The grip is on target within this fraction [1].
    tolerance: float = 0.05
    #: A probe starts only at a grip this many times under the ceiling [1]: a hold that
    #: cannot double its grip does not trade the waiting phase's reflex for a friction
    #: (``_wait``).
    probe_headroom: float = 2.0

    def __post_init__(self) -> None:
        positive = ("ceiling_n", "newton_per_rad", "bandwidth_hz", "probe_rate_n_s",
                    "steady_s", "max_friction", "settle_s")
        bad = [name for name in positive if not getattr(self, name) > 0]
        if not self.probe_headroom >= 1.0:
            bad.append("probe_headroom (>= 1)")
        if bad or not 2 * self.bandwidth_hz < self.control_rate_hz:
            raise InvalidConfiguration(
                f"The adaptive hold needs {', '.join(bad) or 'bandwidth_hz'} > 0 and a "
                "slip bandwidth under half the control rate; fix the slip parameters.")

    @property
    def probe_grip_limit_n(self) -> float:
        """The largest grip a probe starts from [N]."""
        return self.ceiling_n / self.probe_headroom

    @property
    def shear_threshold_n(self) -> float:
        """k sigma_t: a change of |Ft| this large is not noise."""
        k = threshold_sigmas(self.noise.false_alarms_per_hour, self.bandwidth_hz)
        return k * self.noise.shear_sigma_n(self.bandwidth_hz)

    def threshold_n(self, friction: float) -> float:
        return self.noise.threshold_n(friction, self.bandwidth_hz)

    @property
    def tick_shear_sigma_n(self) -> float:
        """The noise of one tick's mean |Ft| (the 1 kHz stream over half the control
        rate) [N]."""
        return self.noise.shear_density * math.sqrt(self.control_rate_hz / 2.0)

    @property
    def probe_sigmas(self) -> float:
        """k of the probe's fall test, from the detector's ``false_alarms_per_hour``: the
        tick means are the 1 kHz stream's 10 ms means, white at the control rate, a
        bandwidth of half of it, so Rice's rate there (4.92 at 100 Hz and one an hour).
        Checked on still Gaussian noise with the probe's own test (its 1-20 tick runs
        each tick, the level's error; benchmarks/probe_false_alarms.py): 0.83 false alarms
        an hour of probing here, 5.4 at 4.5, 42 at 4.0, 1100 at 3.0. A false one learns a
        stuck ratio, under mu_s: 0.96-1.8 times the grip a true slip leaves on the
        household objects (docs/gripper-adaptive-hold-measured.md)."""
        return threshold_sigmas(self.noise.false_alarms_per_hour, self.control_rate_hz / 2.0)

    @property
    def probe_threshold_n(self) -> float:
        """A fall of the probe window's mean |Ft| this large is a slip: 4 sigma of that
        mean (a false one makes the friction err low, toward more grip) [N]."""
        return 4.0 * self.tick_shear_sigma_n / math.sqrt(PROBE_TICKS)


@dataclass(frozen=True)
class SlipEvent:
    kind: EventKind
    #: When the hold saw it (the goal's clock) [s].
    time_s: float
    #: The filtered margin mu Fn - |Ft| then [N].
    margin_n: float
    friction: float
    #: The grip the hold commands after it [N].
    grip_n: float


@dataclass(frozen=True)
class HoldStep:
    #: Goal position to send this tick, or None.
    goal_rad: float | None
    phase: HoldPhase
    #: The grip the hold aims at [N].
    grip_n: float
    #: The filtered margin [N]; NaN while the friction is unknown.
    margin_n: float
    event: SlipEvent | None = None
    #: One sentence once the ceiling is not enough (the result's ``slipping: ...``).
    slipping: str | None = None


class SlipHold:
    def __init__(self, config: SlipHoldConfig, grip_n: float, position_rad: float,
                 closing_lead_rad: float = 0.0) -> None:
        """``closing_lead_rad``: the position loop's lead the grasp's settle read at rest
        after a close [rad] (0: not known), so the first raise passes the servo's friction
        (``_regulate``)."""
        self.config = config
        self.phase = HoldPhase.WAITING
        self.friction: float | None = None
        self.grip_n = min(grip_n, config.ceiling_n)
        self._filter = MarginFilter(config.bandwidth_hz, config.control_rate_hz)
        self._anchor = (position_rad, grip_n)
        #: No goal closes past where the assumed skin carries the ceiling, counted from
        #: the start (the settled grasp, its force read at a level the sensor reads well):
        #: re-anchoring follows the sensor, and a sensor reading low (a sheared,
        #: saturated or miscalibrated skin) would otherwise close the fingers on until
        #: the servo's current stalls them (27.9 N at the hold current).
        self._ceiling_rad = position_rad + (config.ceiling_n - grip_n) / config.newton_per_rad
        self._goal_rad = position_rad
        self._commanded_s: float | None = None
        #: The position loop's lead at rest after a close [rad] (the band's closing edge;
        #: 0 until a rest shows it) and whether the last goal closed.
        self._closing_lead_rad = max(closing_lead_rad, 0.0)
        self._last_closed = True
        #: The output moved since the last goal (its next tick at rest shows the lead).
        self._moved = False
        self._rest_sum, self._rest_count = 0.0, 0
        # (the last window's mean |Ft|, this window's start, its sum, sum of squares, count)
        self._steady: tuple[float, float | None, float, float, int] = (
            math.nan, None, 0.0, 0.0, 0)
        self._probe = (0.0, 0.0, 0.0)  # (steady |Ft|, grip at start, start time)
        self._recent: deque[tuple[float, float]] = deque(maxlen=PROBE_TICKS)
        self._probe_ticks = 0
        #: The least grip per |Ft| that kept the object still [1] and the |Ft| the grip
        #: covers [N] (None: no steady shear seen yet).
        self._reference: tuple[float, float] | None = None
        self._shear_window: deque[float] = deque(maxlen=PROBE_TICKS)
        self._ceiling_since: float | None = None
        #: The filtered margin at the last tick [N] (NaN while the friction is unknown).
        self.last_margin_n = math.nan

    def margin_n(self, fn_n: float, ft_n: float) -> float:
        return math.nan if self.friction is None else self.friction * fn_n - ft_n

    def update(self, now_s: float, fn_n: float, fx_n: float, fy_n: float,
               position_rad: float, moving: bool) -> HoldStep:
        """One control tick: the mean forces since the last tick [N], the servo."""
        fn, ft = self._filter.update(fn_n, fx_n, fy_n)
        self._recent.append((fn_n, math.hypot(fx_n, fy_n)))
        self._shear_window.append(math.hypot(fx_n, fy_n))
        event, slipping = None, None
        if self.phase is HoldPhase.WAITING:
            event = self._follow_load(now_s, fn, ft)
            self._wait(now_s, fn, ft)
        elif self.phase is HoldPhase.PROBING:
            event = self._probe_tick(now_s, fn, ft)
        elif self.phase is HoldPhase.HOLDING:
            event, slipping = self._hold_tick(now_s, fn, ft)
        goal = self._regulate(now_s, fn_n, position_rad, moving, event is not None)
        self.last_margin_n = self.margin_n(fn, ft)
        return HoldStep(goal, self.phase, self.grip_n, self.last_margin_n, event, slipping)

    # -- phases --------------------------------------------------------------------------
    def _wait(self, now_s: float, fn: float, ft: float) -> None:
        """The probe starts once two consecutive windows of ``steady_s`` hold mean |Ft|
        within k sigma_t of each other at a level the probe's fall can show (``PROBE_LEVELS``
        of its falls),
        and the later one's tick means spread no more than twice their noise: an object
        ringing on stuck skins after a sudden lift (7-19 Hz in the model, for seconds)
        could slip at a ring's peak before the probe sees it. The later window's mean is
        the probe's reference.

        No probe starts from a grip over ``probe_grip_limit_n`` (half the ceiling). After a
        probe the hold meets a rising load with the detector's least margin and a reflex
        that acts once that margin has closed, 20-30 ms after the forces show it, and the
        probe's catch has left the object ringing on the stuck skins by about that margin.
        Waiting, the load-following reflex acts on a rise of k sigma_t, in the ratio that
        kept the object. A grip the ceiling cannot double leaves no room to be late: a
        load that doubles in 0.1 s breaks such an object away before the reflex after a
        probe, where the waiting hold takes it to the ceiling in time
        (docs/gripper-adaptive-hold-measured.md, the cracker box)."""
        cfg = self.config
        last, since, total, squares, count = self._steady
        raw = self._shear_window[-1]
        if since is None or now_s - since < cfg.steady_s:
            self._steady = (last, now_s if since is None else since, total + raw,
                            squares + raw * raw, count + 1)
            return
        mean = total / count
        spread = math.sqrt(max(squares / count - mean * mean, 0.0))
        self._steady = (mean, now_s, raw, raw * raw, 1)
        steady = (abs(mean - last) <= cfg.shear_threshold_n
                  and spread <= 2.0 * cfg.tick_shear_sigma_n)
        error = cfg.tick_shear_sigma_n / math.sqrt(count)  # of one window's mean
        # |Ft| of two noisy axes averages 1.25 sigma with no shear at all: a level
        # twice that is the object's
        k = cfg.probe_sigmas
        if (steady and mean > 2.0 * cfg.tick_shear_sigma_n + k * error
                and abs(mean - last) <= k * math.sqrt(2.0) * error):
            # the least grip per shear that kept the object still (a load still easing on
            # would give more, the safe side)
            ratio = self.grip_n / mean
            if self._reference is not None:
                ratio = min(ratio, self._reference[0])
            self._reference = (ratio, mean)
        if (steady and mean >= PROBE_LEVELS * cfg.probe_threshold_n
                and self.grip_n <= cfg.probe_grip_limit_n):
            self.phase = HoldPhase.PROBING
            self._probe, self._probe_ticks = (mean, fn, now_s), 0

    def _follow_load(self, now_s: float, fn: float, ft: float) -> SlipEvent | None:
        """While the friction is unknown: the grip kept a steady shear ``level`` without a
        slip, so |Ft| / Fn <= mu_s there; a grip that rises with the load in that ratio
        keeps it too. Once the filtered |Ft| is k sigma_t above what the grip covers, the
        grip goes to that ratio of |Ft| plus k sigma_t (the rise not yet seen) at once: a
        reflex that needs no friction, for a load that grows before a probe, or on an
        object too light to probe."""
        if self._reference is None:
            return None
        ratio, covered = self._reference
        threshold = self.config.shear_threshold_n
        if ft <= covered + threshold:
            return None
        # the grip covers |Ft| up to here now: a raised grip stiffens the stuck skins
        # and lifts their |Ft| a little, which is not a new load
        self._reference = (ratio, ft + threshold)
        needed = min(self.config.ceiling_n, ratio * (ft + threshold))
        if needed <= self.grip_n:
            return None
        self.grip_n = needed
        return SlipEvent(EventKind.ONSET, now_s, math.nan, 1.0 / ratio, self.grip_n)

    def _probe_tick(self, now_s: float, fn: float, ft: float) -> SlipEvent | None:
        cfg = self.config
        level, start_grip, start_s = self._probe
        window = self._shear_window
        if sum(window) / len(window) > level + cfg.shear_threshold_n:
            # the load rose: wait for it to settle
            self.phase, self._steady = HoldPhase.WAITING, (math.nan, None, 0.0, 0.0, 0)
            self.grip_n = start_grip
            return None
        self._probe_ticks += 1
        sliding = self._sliding_ticks(level)
        floor = level / cfg.max_friction
        if not sliding and start_grip - cfg.probe_rate_n_s * (now_s - start_s) > floor:
            self.grip_n = start_grip - cfg.probe_rate_n_s * (now_s - start_s)
            if self._reference is not None:  # it sticks at this grip too
                self._reference = (min(self._reference[0], fn / level), self._reference[1])
            return None
        # a slide seen within a tick or two carries too few ticks for the friction: the
        # ticks just before it were at the break-away, |Ft| / Fn close under mu_s
        self.friction = self._ratio(max(sliding, RATIO_TICKS // 2) if sliding
                                    else RATIO_TICKS)
        self.phase = HoldPhase.HOLDING
        self.grip_n = self._needed(level)
        return SlipEvent(EventKind.LEARNED, now_s, self.margin_n(fn, ft), self.friction,
                         self.grip_n)

    def _sliding_ticks(self, level: float) -> int:
        """How many of the last ticks slid (0: none seen): the shortest run of the probe's
        latest ticks whose mean |Ft| lies ``probe_sigmas`` of its noise (and the level's)
        below the level. Sliding, |Ft| = mu_k Fn falls with the grip, and at break-away it
        drops at once by (mu_s - mu_k) Fn: a short run sees a step, a long one a slow
        fall, so the probe stops within a few ticks of the break-away rather than once a
        window's mean has fallen."""
        cfg = self.config
        sigma = cfg.tick_shear_sigma_n
        level_var = sigma * sigma / (cfg.steady_s * cfg.control_rate_hz)
        k = cfg.probe_sigmas
        window = list(self._shear_window)[-min(self._probe_ticks, PROBE_TICKS):]
        total = 0.0
        for n, shear in enumerate(reversed(window), start=1):
            total += shear
            if level - total / n > k * math.sqrt(sigma * sigma / n + level_var):
                return n
        return 0

    def _ratio(self, ticks: int) -> float:
        """The kinetic friction from the last ``ticks`` ticks: sliding, |Ft| = mu_k Fn, so
        the least-squares slope of |Ft| on Fn through the origin, moved two of its standard
        errors lower (toward more grip); stuck ticks give less (|Ft| <= mu_s Fn)."""
        cfg = self.config
        recent = list(self._recent)[-max(ticks, 1):]
        fn2 = sum(f * f for f, _ in recent)
        if fn2 <= 0:
            return cfg.max_friction
        slope = sum(f * t for f, t in recent) / fn2
        error = cfg.tick_shear_sigma_n / math.sqrt(fn2)
        return min(max(slope - 2.0 * error, 0.05), cfg.max_friction)

    def _needed(self, ft: float) -> float:
        """The least grip for ``ft`` plus the detector's least margin, under the ceiling."""
        assert self.friction is not None
        mu = self.friction
        return min(self.config.ceiling_n, (ft + 2.0 * self.config.threshold_n(mu)) / mu)

    def _hold_tick(self, now_s: float, fn: float,
                   ft: float) -> tuple[SlipEvent | None, str | None]:
        cfg = self.config
        assert self.friction is not None
        mu = self.friction
        margin = mu * fn - ft
        if margin >= cfg.threshold_n(mu):
            self._ceiling_since = None
            return None, None
        event = None
        needed = self._needed(ft)
        # an onset raises the grip; a grip already raised and still on its way (the
        # filtered force lags it) is not a new one
        if needed > self.grip_n and (needed >= cfg.ceiling_n or needed > self.grip_n * (
                1.0 + 0.5 * cfg.tolerance)):
            self.grip_n = needed
            event = SlipEvent(EventKind.ONSET, now_s, margin, mu, self.grip_n)
        if self.grip_n < cfg.ceiling_n:
            return event, None
        if self._ceiling_since is None:
            self._ceiling_since = now_s
        if now_s - self._ceiling_since < cfg.settle_s + 1.0 / cfg.bandwidth_hz:
            return event, None
        self.phase = HoldPhase.SLIPPING
        want = (ft + 2.0 * cfg.threshold_n(mu)) / mu
        return (SlipEvent(EventKind.SLIPPING, now_s, margin, mu, self.grip_n),
                f"the object needs {want:.2f} N of grip at friction {mu:.2f}, above the "
                f"force ceiling of {cfg.ceiling_n:.2f} N; holding at the ceiling")

    # -- grip -> position ------------------------------------------------------------------
    def _regulate(self, now_s: float, fn_n: float, position_rad: float, moving: bool,
                  urgent: bool) -> float | None:
        """The goal for the grip: at once when the grip target moved (a probe's step, a
        reflex); after ``settle_s`` at rest, from the mean force of that rest.

        Through a geared servo's friction the output rests short of a closing goal by the
        position loop's lead (the friction and the load over the P gain; control/hold.py),
        and a goal moved within that band moves nothing. A grip to raise therefore gets
        the largest lead seen at rest after a close (the grasp's settle's to begin with) on
        top of where the output is to be:
        without it a raise the output cannot follow leaves the grip where it was while
        the hold counts on the new one (a reflex that keeps nothing). A grip to lower gets
        no lead: the output rests above an opening goal, on the side of more grip.

        The lead is read as soon as the output, having moved toward a closing goal, is
        still at a tick: not only after ``settle_s``, which a force mean needs and a lead
        does not. A hold started without the settle's lead has not seen the grasp's
        close, so its first raise (the reflex after a probe's slip) carries no lead and the
        output rests short by the band's closing edge (28 pulses on the default
        drivetrain) while the object slides on; read at the first rest, the lead puts the
        catching grip on its target a rest of ``settle_s`` sooner
        (docs/gripper-adaptive-hold-measured.md); on a servo whose band is wider than the
        raise the output does not move at all. A tick at
        rest after moving is on that edge, not a stick-slip pause: a profile still running
        at the hold's 6 rad/s adds 0.06 rad of lead a tick, more than the whole band
        (about 35 pulses, 0.054 rad), so a stuck output breaks away within the tick. A
        tick that never saw the output move (a goal inside the band, or a servo state
        older than the command) says nothing of the edge."""
        cfg = self.config
        grip = self.grip_n
        if moving:
            self._moved = True
        elif self._moved and self._last_closed and self._commanded_s is not None:
            # at rest after moving toward a closing goal: on the band's closing edge
            self._closing_lead_rad = max(self._closing_lead_rad,
                                         self._goal_rad - position_rad)
            self._moved = False
        if self._commanded_s is not None and (moving or now_s - self._commanded_s
                                              < cfg.settle_s):
            self._rest_sum, self._rest_count = 0.0, 0
        else:
            self._rest_sum += fn_n
            self._rest_count += 1
            if self._rest_count * (1.0 / cfg.control_rate_hz) >= cfg.settle_s:
                mean = self._rest_sum / self._rest_count
                self._rest_sum, self._rest_count = 0.0, 0
                if self._last_closed and self._commanded_s is not None:
                    # at rest after a close: the output sits on the band's closing edge
                    self._closing_lead_rad = max(self._closing_lead_rad,
                                                 self._goal_rad - position_rad)
                # a mean under half the grip: the object is gone (dropped, pulled out);
                # chasing the grip would close the fingers on nothing
                if (abs(mean - grip) > cfg.tolerance * grip
                        and mean > 0.5 * grip):
                    self._anchor = (position_rad, mean)
        anchor_rad, anchor_n = self._anchor
        target = min(self._ceiling_rad, anchor_rad + (grip - anchor_n) / cfg.newton_per_rad)
        closing = target >= position_rad - 0.5 * RAD_PER_PULSE
        goal = min(cfg.closed_position_rad,
                   target + (self._closing_lead_rad if closing else 0.0))
        if abs(goal - self._goal_rad) < (0.5 if urgent else 1.0) * RAD_PER_PULSE:
            return None
        self._goal_rad, self._commanded_s = goal, now_s
        self._last_closed, self._moved = closing, False
        self._rest_sum, self._rest_count = 0.0, 0
        return goal
