"""What a lift did to the object, from the mock world's ground truth and the ``~/slip``
events: per phase the true grip and the slip, and for the load's last rise the figures the
slip goals are judged on (docs/gripper.md, "The lift protocol").

- *least grip*: the normal force on each skin that holds a load L along the fingers with
  static friction mu_s on two skins, L / (2 mu_s); the ratio is the peak true grip over it.
- *slip onset*: the ground truth's slip, grown ``ONSET_SLIP_M`` past its value when the
  load started to rise; an object that never slipped has the hold's first ``onset`` event
  instead (the detector warned before the contacts broke away), and none without one.
- *grip rise*: the true grip first ``GRIP_RISE_N`` above its level when the load started to
  rise; the latency is grip rise less slip onset (negative: the grip rose first).

Pure: arrays of host times [s] and values in, numbers out.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from tactile_sensor.analysis.slip.signature import least_grip_n
from tactile_sensor.sim.held_object import STANDARD_GRAVITY_M_S2, LoadScript

#: Slip past the load's start that counts as the onset [m]: ten times the truth's
#: resolution of a stuck contact's creep (the skins' rate effect), far under the 2 mm goal.
ONSET_SLIP_M = 2e-5
#: Rise of the true grip over its level at the load's start that counts as the grip rising
#: [N] (the hold's tolerance at a 1 N grip).
GRIP_RISE_N = 0.05


def load_rise(load: LoadScript) -> tuple[float, float] | None:
    """The load profile's last rise: (start, end) in seconds after the lift, the last run
    of points over which the pull only grows; None for a profile that never rises."""
    forces, times = load.forces_n, load.times_s
    end = len(forces) - 1
    while end > 0 and forces[end] <= forces[end - 1]:
        end -= 1
    if end <= 0:
        return None
    start = end
    while start > 0 and forces[start - 1] < forces[start]:
        start -= 1
    return times[start], times[end]


def peak_load_n(mass_kg: float, load: LoadScript) -> float:
    """Gravity plus the largest pull of the profile [N]."""
    return mass_kg * STANDARD_GRAVITY_M_S2 + max((*load.forces_n, 0.0))


@dataclass(frozen=True)
class Trace:
    """One ground-truth series: host times [s] and values."""

    t_s: np.ndarray
    value: np.ndarray

    @classmethod
    def of(cls, rows: list[tuple[float, float]]) -> Trace:
        array = np.asarray(rows, dtype=float).reshape(-1, 2)
        order = np.argsort(array[:, 0], kind="stable")
        return cls(array[order, 0], array[order, 1])

    def between(self, start_s: float, end_s: float) -> np.ndarray:
        return self.value[(self.t_s >= start_s) & (self.t_s <= end_s)]

    def at(self, t_s: float) -> float:
        """The last value at or before ``t_s`` (NaN before the first)."""
        i = int(np.searchsorted(self.t_s, t_s, side="right")) - 1
        return float(self.value[i]) if i >= 0 else math.nan

    def first_after(self, t_s: float, above: float) -> float | None:
        """The first time from ``t_s`` on at which the value exceeds ``above``."""
        mask = (self.t_s >= t_s) & (self.value > above)
        return float(self.t_s[mask][0]) if mask.any() else None


@dataclass(frozen=True)
class PhaseSummary:
    name: str
    start_s: float
    end_s: float
    grip_mean_n: float
    grip_peak_n: float
    #: The slip gained over the phase [m].
    slip_m: float

    def line(self) -> str:
        return (f"phase {self.name} ({self.end_s - self.start_s:.2f} s): true grip mean "
                f"{self.grip_mean_n:.2f} N, peak {self.grip_peak_n:.2f} N; slip "
                f"{self.slip_m * 1e3:.2f} mm")


def phase_summary(name: str, start_s: float, end_s: float, grip: Trace, slip: Trace
                  ) -> PhaseSummary:
    """The true grip and the slip gained between two host times."""
    held = grip.between(start_s, end_s)
    before = abs(slip.at(start_s))
    slid = slip.between(start_s, end_s)
    # the largest slip in the phase past the slip it began with (a set-down resets it)
    gained = (max(0.0, float(np.max(np.abs(slid))) - (0.0 if math.isnan(before) else before))
              if slid.size else 0.0)
    return PhaseSummary(name, start_s, end_s,
                        float(held.mean()) if held.size else math.nan,
                        float(held.max()) if held.size else math.nan, gained)


@dataclass(frozen=True)
class LiftFigures:
    """The slip goals' figures of one lift (module doc)."""

    slip_m: float
    peak_grip_n: float
    least_grip_n: float
    onset_s: float | None
    grip_rise_s: float | None
    dropped: bool

    @property
    def ratio(self) -> float:
        return self.peak_grip_n / self.least_grip_n

    @property
    def latency_s(self) -> float | None:
        if self.onset_s is None or self.grip_rise_s is None:
            return None
        return self.grip_rise_s - self.onset_s

    def line(self) -> str:
        """One ``key=value`` line (what ``benchmarks/bench_lift.py`` reads)."""
        latency = self.latency_s
        return (f"slip_mm={self.slip_m * 1e3:.3f} peak_grip_n={self.peak_grip_n:.3f} "
                f"least_grip_n={self.least_grip_n:.3f} ratio={self.ratio:.2f} "
                f"latency_ms={'nan' if latency is None else f'{latency * 1e3:.1f}'} "
                f"dropped={'yes' if self.dropped else 'no'}")


def lift_figures(lift_s: float, end_s: float, rise: tuple[float, float] | None,
                 least_n: float, grip: Trace, slip: Trace, onset_events_s: list[float],
                 dropped: bool) -> LiftFigures:
    """The figures of a lift at host time ``lift_s`` held until ``end_s``; ``rise``: the
    load's last rise after the lift (``load_rise``)."""
    slid = slip.between(lift_s, end_s)
    held = grip.between(lift_s, end_s)
    onset = rise_at = None
    if rise is not None:
        start = lift_s + rise[0]
        base_slip, base_grip = slip.at(start), grip.at(start)
        if not math.isnan(base_slip):
            onset = _first_slip(slip, start, end_s, base_slip)
        if onset is None:
            onset = next((t for t in sorted(onset_events_s) if start <= t <= end_s), None)
        if not math.isnan(base_grip):
            rise_at = grip.first_after(start, base_grip + GRIP_RISE_N)
            if rise_at is not None and rise_at > end_s:
                rise_at = None
    return LiftFigures(float(np.max(np.abs(slid))) if slid.size else 0.0,
                       float(held.max()) if held.size else math.nan, least_n, onset,
                       rise_at, dropped)


def _first_slip(slip: Trace, start_s: float, end_s: float, base_m: float) -> float | None:
    mask = (slip.t_s >= start_s) & (slip.t_s <= end_s) & (
        np.abs(slip.value - base_m) > ONSET_SLIP_M)
    return float(slip.t_s[mask][0]) if mask.any() else None


#: The weight eases on over this long after the lift [s] (a hand lifts in a fraction of a
#: second; the mock's support drops the weight as a step, which rings on the skins).
EASE_S = 0.5
#: The load doubles this long after the lift [s]: after the adaptive hold has had the
#: steady shear and the probe it waits for (two 0.3 s windows and a fall at 4 N/s) ...
DOUBLE_AT_S = 3.0
#: ... over this long [s] (the study's slower doubling).
DOUBLE_OVER_S = 0.1
#: The grasp's target against the least grip for the doubled load [1]: 1.5 x the least grip
#: for the weight alone, so a fixed grasp there lifts the object and not its doubled load.
TARGET_OF_LEAST = 0.75
#: The gentlest target the benchmark asks [N] (the contact and hold goals' lowest).
MIN_TARGET_N = 1.0


@dataclass(frozen=True)
class BenchObject:
    mass_kg: float
    friction_static: float
    friction_kinetic: float

    @property
    def weight_n(self) -> float:
        return self.mass_kg * STANDARD_GRAVITY_M_S2

    @property
    def least_doubled_n(self) -> float:
        """The least grip that holds the doubled load: 2 m g / (2 mu_s)."""
        return least_grip_n(2.0 * self.weight_n, self.friction_static)

    @property
    def target_n(self) -> float:
        return max(MIN_TARGET_N, TARGET_OF_LEAST * self.least_doubled_n)

    @property
    def load_profile(self) -> list[str]:
        """Weight eased on, then a pull of one more weight: the load doubles."""
        w, t = self.weight_n, DOUBLE_AT_S
        return [f"0:{-w:.6g}", f"{EASE_S:g}:0", f"{t:g}:0", f"{t + DOUBLE_OVER_S:g}:{w:.6g}"]


def bench_objects(count: int, seed: int, ceiling_n: float) -> list[BenchObject]:
    """``count`` objects of 50-300 g with static friction 0.3-1.0 (kinetic equal or 0.8 of
    it, alternately), drawn with ``seed``; those whose doubled load needs more than 0.8 of
    ``ceiling_n`` are drawn again (a hold keeps them with a margin under it)."""
    rng = np.random.default_rng(seed)
    found: list[BenchObject] = []
    while len(found) < count:
        mass, mu = round(float(rng.uniform(0.05, 0.3)), 3), round(float(rng.uniform(0.3, 1.0)), 2)
        candidate = BenchObject(mass, mu, round(mu * (1.0 if len(found) % 2 == 0 else 0.8), 2))
        if candidate.least_doubled_n <= 0.8 * ceiling_n:
            found.append(candidate)
    return found
