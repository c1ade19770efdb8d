"""Household objects to hold: YCB masses, and the silicone skin's friction on their surfaces.

Why: a hold that changes the grip (the adaptive hold's probe) must be judged on objects
like the ones it will meet, not only on a grid. Each object here is one of the YCB object
set's (B. Calli, A. Walsman, A. Singh, S. Srinivasa, P. Abbeel, A. M. Dollar,
"Benchmarking in Manipulation Research: The YCB Object and Model Set and Benchmarking
Protocols", IEEE Robotics & Automation Magazine 22(3), 36-52, 2015, Table I: the masses;
the gelatin box's 0.097 kg is also the mass of Drake's ycb_objects/gelatin_box.sdf).

Friction: silicone rubber has a coefficient from under 0.25 to over 0.75 on smooth hard
surfaces, and about 1.0 where it is tacky (NuSil's static and kinetic measurements of
silicone on steel; the range docs/array-calibration.md takes for the shear grid). No
source gives silicone on each YCB surface, so each surface class takes one value inside
that range, ordered as the surfaces' hardness and smoothness order them (polished metal
lowest, then hard plastic, coated card, wood and leather, then elastomer and foam, the
tacky end). The kinetic coefficient is the static one or 0.8 of it, the two the slip
study spans (no kinetic drop has been measured for this skin): 0.8 where the surface is
soft or fibrous (card, leather, felt, foam, rubber), whose friction drops once sliding
(viscoelastic and adhesive friction), and 1.0 on smooth hard surfaces.

The objects are what the gripper's 20 mm rod model holds: its size across the fingers is
the rod's; only mass and friction enter. ``held_out`` marks the objects kept out of the
adaptive hold's design (every fourth, by name order): judge a change on them last.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from tactile_sensor.sim.errors import SimError
from tactile_sensor.sim.held_object import STANDARD_GRAVITY_M_S2, ObjectSpec

#: Silicone on each surface class: (static friction, kinetic over static) [1, 1] (module
#: doc: inside NuSil's 0.25 to over 0.75, tacky about 1.0).
SURFACE_FRICTION: dict[str, tuple[float, float]] = {
    "polished metal": (0.30, 1.0),
    "painted metal": (0.35, 1.0),
    "hard plastic": (0.40, 1.0),
    "coated card": (0.50, 0.8),
    "wood": (0.60, 0.8),
    "leather": (0.65, 0.8),
    "felt": (0.70, 0.8),
    "rubber": (0.90, 0.8),
    "foam": (1.00, 0.8),
}


@dataclass(frozen=True)
class HouseholdObject:
    """One object: its YCB name, mass [kg] and the surface the skins touch."""

    name: str
    mass_kg: float
    surface: str
    held_out: bool = False

    def __post_init__(self) -> None:
        if not (math.isfinite(self.mass_kg) and self.mass_kg > 0):
            raise SimError(f"Object {self.name!r} has mass {self.mass_kg!r}; give a finite "
                           "mass > 0 kg.")
        if self.surface not in SURFACE_FRICTION:
            raise SimError(f"Object {self.name!r} has surface {self.surface!r}; use one of "
                           f"{', '.join(SURFACE_FRICTION)}.")

    @property
    def friction_static(self) -> float:
        return SURFACE_FRICTION[self.surface][0]

    @property
    def friction_kinetic(self) -> float:
        static, share = SURFACE_FRICTION[self.surface]
        return static * share

    @property
    def weight_n(self) -> float:
        return self.mass_kg * STANDARD_GRAVITY_M_S2

    def spec(self, **kwargs: object) -> ObjectSpec:
        """The held object's spec (a ``load`` script may be given)."""
        return ObjectSpec(self.mass_kg, self.friction_static, self.friction_kinetic,
                          **kwargs)  # type: ignore[arg-type]


def _objects() -> tuple[HouseholdObject, ...]:
    rows = (
        ("002 master chef can", 0.414, "painted metal"),
        ("003 cracker box", 0.411, "coated card"),
        ("004 sugar box", 0.514, "coated card"),
        ("005 tomato soup can", 0.349, "painted metal"),
        ("006 mustard bottle", 0.603, "hard plastic"),
        ("007 tuna fish can", 0.171, "polished metal"),
        ("008 pudding box", 0.187, "coated card"),
        ("009 gelatin box", 0.097, "coated card"),
        ("010 potted meat can", 0.370, "painted metal"),
        ("011 banana", 0.066, "hard plastic"),
        ("012 strawberry", 0.018, "hard plastic"),
        ("013 apple", 0.068, "hard plastic"),
        ("014 lemon", 0.029, "hard plastic"),
        ("017 orange", 0.047, "hard plastic"),
        ("025 mug", 0.118, "hard plastic"),
        ("030 fork", 0.034, "polished metal"),
        ("036 wood block", 0.729, "wood"),
        ("037 scissors", 0.082, "hard plastic"),
        ("040 large marker", 0.0158, "hard plastic"),
        ("043 phillips screwdriver", 0.097, "hard plastic"),
        ("051 large clamp", 0.125, "hard plastic"),
        ("054 softball", 0.191, "leather"),
        ("055 baseball", 0.148, "leather"),
        ("056 tennis ball", 0.058, "felt"),
        ("057 racquetball", 0.041, "rubber"),
        ("061 foam brick", 0.028, "foam"),
        ("077 rubiks cube", 0.252, "hard plastic"),
    )
    return tuple(HouseholdObject(name, mass, surface, held_out=i % 4 == 3)
                 for i, (name, mass, surface) in enumerate(rows))


#: The household objects (YCB), in YCB number order.
HOUSEHOLD_OBJECTS: tuple[HouseholdObject, ...] = _objects()
