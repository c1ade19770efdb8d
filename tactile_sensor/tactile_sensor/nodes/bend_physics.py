"""The finger's FEM (physics/bend.py) as the mock's world and the driver's calibration.

One place reads the physics of the bending finger, so that the mock's modules and the
driver's calibration come from the same cached FEM response: the mock builds its
``BendWorld`` from it, the driver fits its ``BendCalibration`` on the response's table.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from tactile_sensor.sensing.bend_calibration import BendCalibration, bend_layout_refusal
from tactile_sensor.sensing.errors import CalibrationError
from tactile_sensor.sim.bend_world import BendPath, BendWorld, parse_actuation_profile
from tactile_sensor.sim.errors import SimError

#: The calibration's table over the response's angle and tip-force ranges: points in each.
TABLE_ANGLES = 46
TABLE_FORCES = 12
#: The finger's actuator is its tendon (physics/fem/finger.py): a tension [N].
ACTUATION_UNIT = "N"


#: The places the driver and the mock name, and which of the FEM's modules each is (the
#: physics' default layout: over the joint's middle, then at the fingertip).
PLACES = ("joint", "tip")


class _Modules:
    """The response's columns of the modules named, in that order."""

    def __init__(self, response: Any, places: tuple[str, ...]) -> None:
        if (refusal := bend_layout_refusal(places)) is not None:
            raise SimError(refusal)
        unknown = [p for p in places if p not in PLACES]
        if unknown:
            raise SimError(f"The finger has modules {', '.join(PLACES)}, not "
                           f"{', '.join(unknown)}; name modules among those.")
        self.columns = [PLACES.index(p) for p in places]
        self.response = response

    @property
    def angle_range_rad(self) -> tuple[float, float]:
        lo, hi = self.response.angle_range_rad
        return float(lo), float(hi)

    def output_v(self, angle_rad: Any, tip_force_n: Any) -> np.ndarray:
        out = np.asarray(self.response.output_v(angle_rad, tip_force_n), float)
        return out[..., self.columns]


class _Tendon:
    """The finger's drive as the world takes it: the tension that holds an angle under a
    tip force (the FEM's own unknown), and the angle a tension holds."""

    unit = ACTUATION_UNIT

    def __init__(self, response: Any) -> None:
        self.response = response

    def actuation_for(self, angle_rad: Any, tip_force_n: Any) -> np.ndarray:
        return np.asarray(self.response.tension_n(angle_rad, tip_force_n), float)

    def angle_rad(self, tension_n: Any, tip_force_n: Any) -> np.ndarray:
        return np.asarray(self.response.angle_from_tension(tension_n, tip_force_n), float)


def load_response(cache_dir: Path | str | None = None, progress: Any = None) -> Any:
    """The finger's FEM response for the default layout (computed and cached on a first
    run; physics/bend.py)."""
    try:
        from tactile_sensor.physics import bend
        from tactile_sensor.physics.errors import PhysicsError
    except ImportError as exc:
        raise SimError(f"The finger's physics model is not available ({exc}); install the "
                       "complete tactile_sensor package.") from None
    try:
        return bend.load_or_compute_response(
            bend.BendGeometry(), bend.DEFAULT_MODULES,
            cache_dir=None if cache_dir is None else Path(cache_dir), progress=progress)
    except PhysicsError as exc:
        raise SimError(f"The finger's FEM failed ({exc}).") from None


def _digest(response: Any) -> str:
    from tactile_sensor.physics.bend import response_digest

    return response_digest(response.geometry, response.modules,
                           response.angles_rad.tolist(), response.forces_n.tolist())


def fem_bend_calibration(places: tuple[str, ...], cache_dir: Path | str | None = None
                         ) -> BendCalibration:
    """The driver's calibration for these modules, fitted on the FEM's table."""
    try:
        response = load_response(cache_dir)
        modules = _Modules(response, places)
    except SimError as exc:
        raise CalibrationError(str(exc)) from None
    lo, hi = modules.angle_range_rad
    f_lo, f_hi = (float(v) for v in response.force_range_n)
    angles = np.linspace(lo, hi, TABLE_ANGLES)
    forces = np.linspace(f_lo, f_hi, TABLE_FORCES)
    a, f = np.meshgrid(angles, forces, indexing="ij")
    return BendCalibration.fit(places, angles, forces, modules.output_v(a, f),
                               source=f"fem-bend:{_digest(response)}")


def bend_world(values: dict[str, Any], cache_dir: Path | None, progress: Any = None
               ) -> BendWorld:
    """The mock's finger from its parameters (``bend.*`` and the protocol's)."""
    places = tuple(p.strip() for p in str(values["bend.modules"]).split(",") if p.strip())
    if (refusal := bend_layout_refusal(places)) is not None:
        raise SimError(refusal)
    path = BendPath(angle_rad=values["protocol.angle"],
                    frequencies_hz=tuple(values["protocol.frequencies"]),
                    cycles=values["protocol.cycles"], tip_force_n=values["protocol.tip_force"],
                    rest_s=values["protocol.rest"])
    # refused before the FEM loads: the finger's tendon pulls, its tension is >= 0 N
    actuation = parse_actuation_profile(values["bend.actuation_profile"], ACTUATION_UNIT)
    response = load_response(cache_dir, progress)
    modules = _Modules(response, places)
    rest = np.asarray(response.voltage_v(0.0, 0.0), float)[modules.columns]
    if not np.all(np.isfinite(rest)):
        raise SimError("The finger's modules have no finite voltage at rest; check the "
                       "physics parameters.")
    return BendWorld(path, modules, _Tendon(response), rest, places, actuation)


def describe_world(world: BendWorld) -> str:
    """One line for the mock's log."""
    peak = math.degrees(float(np.max(world.angle_rad(np.linspace(0, world.duration_s, 2000)))))
    return (f"finger with modules {', '.join(world.faces)}, bends to {peak:.0f} deg over "
            f"{world.duration_s:.1f} s")
