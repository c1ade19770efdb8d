"""An object with mass held between the gripper's fingers, free to slip along them.

Along the fingers (+x toward the fingertips, the tactile frame's x) the object is one mass m.
Each finger touches it through its skin: the skin's contact patch is a tangential spring,
its stiffness k(d) from the FEM array grid at that finger's indentation d
(``sim/skin_shear.py``), in series with Coulomb friction against the object
(static mu_s, kinetic mu_k <= mu_s) that has a stick state (Karnopp 1985):

- stuck, the patch moves with the object and the skin carries F = k (x - anchor), with
  the silicone's rate effect; the contact breaks away once |F| > mu_s N (N: that
  finger's normal force);
- sliding, the friction force is mu_k N against the slide, the skin stays deflected by it
  (the patch is massless) and the anchor moves with the object; the contact sticks again
  in the step in which the sliding velocity reaches zero (it changes sign or vanishes):
  Karnopp's velocity band, one step's velocity change wide.

A grip that changes while a contact sticks changes its stiffness, not its force: the
annulus a firmer press adds to the patch carries no tangential traction, so a stuck
contact's tangential force moves only with its tangential displacement, at the stiffness
of the moment (Mindlin and Deresiewicz 1953; Johnson, *Contact Mechanics*, 1985, §7.4).
The anchor is moved so that k (x - anchor) stays what it was; a lighter grip likewise keeps
the force until the static limit, now lower, makes the contact slide.

The spring in series with a stick state is Haessig and Friedland's reset-integrator
friction model (1991). The rate effect is physics' Prony series, per axis as the bench
gauge has it; it is also what damps the object's ringing while it sticks. The object's
slip is how far its anchors moved: its travel over the skins, without their elastic
deflection.

Before the lift the object stands on its support, which holds it along the fingers: nothing
moves. From the lift on, gravity m g and the scripted pull (:class:`LoadScript`, seconds
after the lift) act along +x. The object's place across the fingers stays the rod's; once
it slipped farther than ``reach_m`` (off the skins' edge) it falls out of the fingers.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from tactile_sensor.sim.errors import SimError
from tactile_sensor.sim.skin_shear import TangentialStiffness

#: Standard gravity [m/s^2] (ISO 80000-3).
STANDARD_GRAVITY_M_S2 = 9.80665
#: Largest integration step [s]; shorter when the object is light (see ``HeldObject.step``).
MAX_STEP_S = 1e-3
#: Steps per period of the object on the skins' springs (semi-implicit Euler is stable for
#: omega h < 2; 0.1 rad per step resolves the ringing).
RADIANS_PER_STEP = 0.1


@dataclass(frozen=True)
class LoadScript:
    """A pull along the fingers [N] against the time since the lift [s]: linear between its
    points, the first value before the first and the last after the last (none: 0 N)."""

    times_s: tuple[float, ...] = ()
    forces_n: tuple[float, ...] = ()

    def __post_init__(self) -> None:
        if len(self.times_s) != len(self.forces_n):
            raise SimError("A load profile needs as many times as forces.")
        if not all(math.isfinite(v) for v in (*self.times_s, *self.forces_n)):
            raise SimError("object.load_profile holds a non-finite value; give every entry "
                           "as finite 'time:newtons', e.g. '1.0:0.5'.")
        if any(t < 0 for t in self.times_s) or any(
                b <= a for a, b in zip(self.times_s, self.times_s[1:], strict=False)):
            raise SimError("object.load_profile times must be >= 0 s and strictly "
                           "increasing; sort the entries and drop repeated times.")

    def force_n(self, t_s: float) -> float:
        """The pull at ``t_s`` seconds after the lift."""
        if not self.times_s:
            return 0.0
        return float(np.interp(t_s, self.times_s, self.forces_n))


def parse_load_profile(items: Sequence[str]) -> LoadScript:
    """``["0:0", "1:0.5"]`` (seconds after the lift : newtons along the fingers)."""
    points = []
    for item in items:
        time_text, sep, force_text = str(item).partition(":")
        try:
            if not sep:
                raise ValueError
            points.append((float(time_text), float(force_text)))
        except ValueError:
            raise SimError(f"object.load_profile entry {item!r} is not 'time:newtons' "
                           "(seconds after the lift and a pull along the fingers), e.g. "
                           "'1.0:0.5'.") from None
    return LoadScript(tuple(p[0] for p in points), tuple(p[1] for p in points))


@dataclass(frozen=True)
class ObjectSpec:
    """The object: mass [kg], friction against the skin [1] and the scripted pull."""

    mass_kg: float
    friction_static: float
    friction_kinetic: float
    load: LoadScript = field(default_factory=LoadScript)

    def __post_init__(self) -> None:
        if not (math.isfinite(self.mass_kg) and self.mass_kg > 0):
            raise SimError(f"object.mass_kg = {self.mass_kg!r} must be a finite mass > 0 kg "
                           "(0 = no object).")
        for name, mu in (("object.friction_static", self.friction_static),
                         ("object.friction_kinetic", self.friction_kinetic)):
            if not (math.isfinite(mu) and mu > 0):
                raise SimError(f"{name} = {mu!r} must be a finite friction coefficient > 0.")
        if self.friction_kinetic > self.friction_static:
            raise SimError(f"object.friction_kinetic = {self.friction_kinetic!r} is above "
                           f"object.friction_static = {self.friction_static!r}; kinetic "
                           "friction must not exceed static.")


class RateModel(Protocol):
    """What a contact needs of physics' ``RateDependentForce``."""

    def step(self, elastic_force_n: float, dt: float) -> float: ...

    def reset(self) -> None: ...


@dataclass
class Contact:
    """One finger's contact with the object; ``anchor_m``: the object's position at which
    this skin would be undeflected; ``slid_m``: the object's slide over this skin;
    ``force_n``: the skin's force along +x (the object's pull on it)."""

    rate: RateModel | None = None
    anchor_m: float = 0.0
    stuck: bool = True
    direction: float = 0.0
    slid_m: float = 0.0
    force_n: float = 0.0

    def release(self, x_m: float) -> None:
        """No touch: the skin springs back, the next touch sticks where the object is."""
        self.anchor_m, self.stuck, self.force_n = x_m, True, 0.0
        if self.rate is not None:
            self.rate.reset()

    def engage(self, x_m: float, h: float, normal_n: float, k: float, mu_s: float,
               mu_k: float, velocity_m_s: float = 0.0) -> float:
        """The skin's force with the object at ``x_m`` after a step ``h`` [s]: the deflected
        skin's (with the rate effect) while it sticks, else the kinetic friction.

        A stuck contact breaks away only while the object moves along the skin's force
        (``velocity_m_s``, the object's along +x): sliding must oppose the slide. An object
        moving back against it unloads the skin, which then carries at most its static
        limit; without this, a contact re-stuck at the limit (mu_k = mu_s) broke away
        again at each step toward its force while the object moved the other way, and its
        friction pushed the object on, out of the fingers."""
        e = k * (x_m - self.anchor_m)
        force = self.rate.step(e, h) if self.rate is not None else e
        limit = mu_s * normal_n
        if self.stuck and abs(force) > limit:
            if velocity_m_s * force < 0:
                force = math.copysign(limit, force)
                self.force_n = force
                return force
            self.stuck, self.direction = False, math.copysign(1.0, force)
        if not self.stuck:
            force = mu_k * normal_n * self.direction
            self.follow(x_m, force / k)
        self.force_n = force
        return force

    def restiffen(self, x_m: float, k_old: float, k_new: float) -> None:
        """The grip changed the stiffness from ``k_old`` to ``k_new`` [N/m]: the skin keeps
        its force (module docstring), so it is deflected k_old / k_new as far."""
        self.anchor_m = x_m - (x_m - self.anchor_m) * k_old / k_new

    def follow(self, x_m: float, deflection_m: float) -> None:
        """Sliding: the anchor moves with the object, the skin deflected by the friction."""
        anchor = x_m - deflection_m
        self.slid_m += anchor - self.anchor_m
        self.anchor_m = anchor


@dataclass(frozen=True)
class ObjectState:
    """Ground truth along the fingers: position and velocity from where it was gripped
    [m, m/s], its slip over the skins [m] (mean of the two), each skin's force [N]."""

    position_m: float = 0.0
    velocity_m_s: float = 0.0
    slip_m: float = 0.0
    force_a_n: float = 0.0
    force_b_n: float = 0.0
    lifted: bool = False
    #: It slipped off the skins and fell out of the fingers.
    dropped: bool = False
    #: Finger A's skin surface, displaced along +x by the object (its elastic deflection,
    #: what a fingertip with modules on its side faces reads) [m].
    deflection_a_m: float = 0.0


class HeldObject:
    """The object's motion along the fingers under the two skins' friction (module doc)."""

    def __init__(self, spec: ObjectSpec, stiffness: TangentialStiffness,
                 rate: Callable[[], RateModel] | None = None, reach_m: float = math.inf
                 ) -> None:
        self.spec = spec
        #: How far the object slips before it leaves the skins (and falls) [m].
        self.reach_m = reach_m
        self.dropped = False
        self.stiffness = stiffness
        self.contacts = (Contact(rate() if rate else None), Contact(rate() if rate else None))
        self.x_m = 0.0
        self.v_m_s = 0.0
        self._t_s: float | None = None
        self._lift_s: float | None = None
        self._lift_wanted = False
        self._k: tuple[float, ...] = (0.0, 0.0)  # each contact's stiffness at the last step

    # -- support -----------------------------------------------------------------------------
    def lift(self) -> None:
        """Take the support away at the next step: gravity and the pull act from then on."""
        self._lift_wanted = True

    def set_down(self) -> None:
        """Put the object back on its support: it stops where it is, or, once it fell out of
        the fingers, where it started, as a new object."""
        self._lift_wanted, self._lift_s, self.v_m_s = False, None, 0.0
        if self.dropped:
            self.dropped, self.x_m = False, 0.0
            for contact in self.contacts:
                contact.release(0.0)
                contact.slid_m = 0.0

    @property
    def lifted(self) -> bool:
        return self._lift_s is not None

    def load_n(self, t_s: float) -> float:
        """Gravity plus the pull along +x at world time ``t_s`` (0 before the lift)."""
        if self._lift_s is None:
            return 0.0
        return self.spec.mass_kg * STANDARD_GRAVITY_M_S2 + self.spec.load.force_n(
            t_s - self._lift_s)

    # -- motion ------------------------------------------------------------------------------
    def step(self, t_s: float, normal_n: tuple[float, float],
             indentation_m: tuple[float, float]) -> ObjectState:
        """Advance to world time ``t_s`` with the fingers' normal forces [N] and
        indentations [m] held over the interval (the servo moves them between calls)."""
        if self._t_s is None:
            self._t_s = t_s
        if self._lift_wanted and self._lift_s is None:
            self._lift_s = self._t_s = t_s  # on the support until now
        if self.dropped:
            normal_n = (0.0, 0.0)
        k = tuple(self.stiffness(d) if n > 0 else 0.0
                  for n, d in zip(normal_n, indentation_m, strict=True))
        for contact, n, old, new in zip(self.contacts, normal_n, self._k, k, strict=True):
            if n <= 0:
                contact.release(self.x_m)
            elif old > 0 and new != old and contact.stuck:
                contact.restiffen(self.x_m, old, new)
        self._k = k
        span = t_s - self._t_s
        self._t_s = t_s
        if self._lift_s is not None and span > 0:
            omega = math.sqrt(max(sum(k), 1e-12) / self.spec.mass_kg)
            steps = max(1, math.ceil(span / min(MAX_STEP_S, RADIANS_PER_STEP / omega)))
            h = span / steps
            for i in range(steps):
                self._advance(t_s - span + (i + 1) * h, h, normal_n, k)
        else:
            self._hold(normal_n, k)
        return self.state

    def _hold(self, normal_n: tuple[float, float], k: tuple[float, ...]) -> None:
        """On the support: the object stays, the skins carry what they are deflected by."""
        for contact, n, kk in zip(self.contacts, normal_n, k, strict=True):
            contact.force_n = kk * (self.x_m - contact.anchor_m) if n > 0 else 0.0

    def _advance(self, t_s: float, h: float, normal_n: tuple[float, float],
                 k: tuple[float, ...]) -> None:
        s = self.spec
        total = 0.0
        for contact, n, kk in zip(self.contacts, normal_n, k, strict=True):
            if n <= 0:
                continue
            total += contact.engage(self.x_m, h, n, kk, s.friction_static,
                                    s.friction_kinetic, self.v_m_s)
        self.v_m_s += (self.load_n(t_s) - total) / s.mass_kg * h
        self.x_m += self.v_m_s * h
        for contact, n, kk in zip(self.contacts, normal_n, k, strict=True):
            if n > 0 and not contact.stuck:
                contact.follow(self.x_m, contact.force_n / kk)
                if self.v_m_s * contact.direction <= 0:
                    contact.stuck = True  # the slide stopped in this step
        a, b = self.contacts
        if abs(a.slid_m + b.slid_m) > 2.0 * self.reach_m:
            self.dropped = True  # off the skins' edge: it falls
            for contact in self.contacts:
                contact.release(self.x_m)

    @property
    def state(self) -> ObjectState:
        a, b = self.contacts
        return ObjectState(self.x_m, self.v_m_s, 0.5 * (a.slid_m + b.slid_m), a.force_n,
                           b.force_n, self.lifted, self.dropped, self.x_m - a.anchor_m)


def object_from_values(mass_kg: float, friction_static: float, friction_kinetic: float,
                       load_profile: Sequence[str]) -> ObjectSpec | None:
    """The object the ``object.*`` parameters describe (None for mass 0: the fixed rod);
    each is checked even without an object, so a bad one is refused before anything moves."""
    load = parse_load_profile(load_profile)
    if mass_kg == 0:
        ObjectSpec(1.0, friction_static, friction_kinetic, load)  # checks the rest
        return None
    return ObjectSpec(mass_kg, friction_static, friction_kinetic, load)
