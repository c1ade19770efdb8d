"""Which rig settings cannot go together, each refused in one sentence naming the fix.

Decided before any device opens, from the settings alone, so that the mock node (and any
other caller that builds a world) refuses the same combinations the same way.
"""

from __future__ import annotations

from dataclasses import dataclass

from tactile_sensor.sim.wrench_world import WRENCH_MIN_MODULES


@dataclass(frozen=True)
class RigSettings:
    """What the refusals look at: the world, its modules and what acts on them."""

    world: str  # 'bench' | 'gripper'
    modules: int
    shear_m: float = 0.0
    tilt_rad: float = 0.0
    twist_rad: float = 0.0
    stiffness_ratio: float = 1.0
    has_object: bool = False
    rod_diameter_m: float = 0.0
    scenario: str = ""
    dark: bool = True

    @property
    def array(self) -> bool:
        """Several modules: the skin is the FEM array grid (the bench's, or finger A's)."""
        return self.modules > 1

    @property
    def wrench(self) -> bool:
        return self.tilt_rad > 0 or self.twist_rad > 0


def wrench_refusal(world: str, modules: int) -> str | None:
    """Why a wrench protocol cannot run on this rig, in one sentence (None: it can)."""
    if world != "bench":
        return ("A wrench protocol (protocol.tilt or protocol.twist > 0) needs the bench "
                "world; set world to bench or protocol.tilt and protocol.twist to 0.")
    if modules < WRENCH_MIN_MODULES:
        return (f"A wrench protocol needs at least {WRENCH_MIN_MODULES} modules to tell six "
                f"wrench components apart, the physics parameter modules names {modules}; "
                "set e.g. modules to front@-0.0055,front@0.0055,back@-0.0055,back@0.0055,"
                "left@-0.0055,left@0.0055,right@-0.0055,right@0.0055.")
    return None


def rig_refusal(rig: RigSettings) -> str | None:
    """The first reason these settings cannot run, in one sentence; None when they can."""
    if rig.has_object and rig.world != "gripper":
        return ("An object with mass (object.mass_kg > 0) is held by the gripper; set world "
                "to gripper or object.mass_kg to 0.")
    if rig.has_object and rig.rod_diameter_m <= 0:
        return ("An object with mass (object.mass_kg > 0) is the rod between the fingers; "
                "give rod.diameter > 0 m.")
    if rig.scenario and not rig.dark:
        return (f"protocol.scenario '{rig.scenario}' sets the light itself; leave the "
                "ambient.* parameters at 0 or the scenario empty.")
    if rig.wrench and (refusal := wrench_refusal(rig.world, rig.modules)):
        return refusal
    if rig.array and rig.stiffness_ratio != 1.0:
        return ("skin.stiffness_ratio applies to a single-module skin (the bench or the "
                "gripper); set it to 1.0 for a module array.")
    if rig.world == "bench" and rig.shear_m > 0 and not rig.array:
        return ("A shear protocol needs a module array; set the physics parameter modules to "
                "several faces (e.g. front,back,left,right) or protocol.shear to 0.")
    return None


def lift_refusal(in_process_mock: bool, has_object: bool) -> str | None:
    """Why the gripper's lift protocol cannot run, in one sentence (None: it can); decided
    before the fingers move."""
    if not in_process_mock:
        return ("The lift protocol lifts the mock's object through its servo emulator; run "
                "it on mock hardware (without --no-mock).")
    if not has_object:
        return ("The lift protocol needs an object between the fingers and none is "
                "configured (object.mass_kg is 0); give gripper_world an object with "
                "--config, e.g. object.mass_kg: 0.1 and object.friction_static: 0.6.")
    return None
