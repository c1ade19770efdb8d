"""The XM430's drivetrain as sources give it: torque offset, friction, play and its P loop.

Why: an ideal servo (torque = current x the datasheet's constant) makes current-limited
grasping exact, so the mock could not show what touch adds. A geared hobby servo loses a
large share of its torque at this gripper's forces (a 1.5 N grip is 0.021 N m on the
14 mm pinion), and its position loop acts through that friction and the gears' play.

Parameters (``drivetrain.*`` on the mock, all at the servo's output):

- ``torque_offset_nm`` 0.132 N m: the current that turns no load. ROBOTIS's performance
  graph of the XM430-W350, fitted on the ROBOTIS forum from three of its points, gives
  torque = 1.769 A^-1 N m x I - 0.22 N m (no torque below about 0.125 A). The W210 has
  the same motor and case behind a 212.6:1 instead of a 353.5:1 gear (e-manual), so a loss
  at the motor is 212.6 / 353.5 of it at the output: 0.22 x 0.601 = 0.132 N m.
- ``coulomb_friction_nm`` 0.0615, ``stribeck_friction_nm`` 0.0239,
  ``stribeck_velocity_rad_s`` 1.52, ``viscous_friction_nm_s`` 0.0148,
  ``load_friction_ratio`` 0.234: the Dynamixel MX-64 (200:1, the identified servo closest
  to the W210's 212.6:1 and 3 N m class) in the M4 model "Stribeck load-dependent" of
  Duclusaud, Passault, Padois, Ly, "Extended Friction Models for the Physics Simulation
  of Servo Actuators" (arXiv 2410.08650; parameters in the Rhoban/bam repository,
  params/mx64/m4.json: friction_base, friction_stribeck, dtheta_stribeck,
  friction_viscous, load_friction_stribeck; its load_friction_base is 2e-10, so the
  load-dependent friction acts through the Stribeck coefficient alone). The Stribeck
  curve's exponent is that model's ``alpha``, 1.33. The XM430 has no identification.
- ``backlash_rad`` 4.36e-3 rad: the X-series e-manual's 15 arcmin (0.25 deg). That is the
  gearbox's play, and the servo's encoder reads the output shaft, so it lies inside the
  position loop, which closes on the output: a quasi-static model cannot show it there.
  The model puts a play of that size where the fingers could feel it, between the output
  and the racks (the rack-and-pinion mesh, for which no source gives a figure). Even
  there a skin between the fingers hides it: the skins push the racks onto the pinion's
  closing face whichever way it turns (test_drivetrain.py shows a record with the play
  equal to one without it on an object nearer by the play).
- ``guide_friction_n`` 0.001 N per finger: a ball carriage's rolling friction
  (coefficient 0.002-0.003, Thomson's profile rail notes) on a finger's weight (~0.3 N).
  Seal drag, which the catalogues do not quantify, would add to it.

The friction budget (bam's formulation): ``offset + coulomb + s(v) (stribeck +
load_ratio |torque|) + viscous |v|`` with ``s(v) = exp(-(|v| / v_s)^alpha)``: the output
sticks while the net torque on it stays within the budget at rest, and moves where the
net torque equals the budget at the velocity it moves with.

The position loop: current-based position mode's P term, ``I = Kp (trajectory -
position)`` clipped at |Goal Current| (and the stall current), with Kp = Position P Gain
x 0.01 A/rad, the firmware's conversion identified for the X-series XL330 in
current-based position mode (bam's XL330CurrentActuator ``error_gain``). The factory
gain 800 gives 8 A/rad. Present Current reads that current: what the motor draws,
friction included.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

#: Current-based position mode: target current per rad of error per unit of Position P
#: Gain [A/rad] (bam, XL330CurrentActuator).
A_PER_RAD_PER_P_GAIN = 0.01
#: The Stribeck curve's exponent (bam MX-64 M4 ``alpha``) [1].
STRIBECK_EXPONENT = 1.33


class DrivetrainError(ValueError):
    """A drivetrain parameter the mock cannot model; the message names it and the fix."""


@dataclass(frozen=True)
class Drivetrain:
    """The servo's losses and play at its output (SI units; sources in the module doc)."""

    torque_offset_nm: float = 0.22 * 212.6 / 353.5
    coulomb_friction_nm: float = 0.0615
    stribeck_friction_nm: float = 0.0239
    stribeck_velocity_rad_s: float = 1.52
    viscous_friction_nm_s: float = 0.0148
    load_friction_ratio: float = 0.234
    backlash_rad: float = math.radians(0.25)
    guide_friction_n: float = 0.001

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
                raise DrivetrainError(
                    f"drivetrain.{f.name} = {value!r} must be a finite number >= 0; set it "
                    "from the servo's data (see docs/gripper.md, the mock's drivetrain).")
        if self.stribeck_velocity_rad_s == 0:
            raise DrivetrainError(
                "drivetrain.stribeck_velocity_rad_s must be above 0 (the speed over which "
                "the friction at rest falls off); give e.g. 1.52 rad/s.")
        if self.load_friction_ratio >= 1:
            raise DrivetrainError(
                f"drivetrain.load_friction_ratio = {self.load_friction_ratio} would stop "
                "the servo transmitting any torque; give a ratio below 1 (e.g. 0.234).")

    @classmethod
    def ideal(cls) -> Drivetrain:
        """No loss and no play (the datasheet's servo), for comparison."""
        return cls(0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0)

    @classmethod
    def from_parameters(cls, values: dict[str, float]) -> Drivetrain:
        """From the mock's ``drivetrain.*`` parameters (missing ones take the defaults)."""
        names = {f.name for f in fields(cls)}
        return cls(**{k.removeprefix("drivetrain."): float(v) for k, v in values.items()
                      if k.startswith("drivetrain.") and k.removeprefix("drivetrain.")
                      in names})

    def check_clearance(self, clearance_rad: float) -> None:
        """Refuse a play as large as the free travel to the object (the fingers could not
        be told to touch it)."""
        if math.isfinite(clearance_rad) and self.backlash_rad >= clearance_rad:
            raise DrivetrainError(
                f"drivetrain.backlash_rad = {self.backlash_rad:.4g} rad is as large as the "
                f"rod's clearance ({clearance_rad:.4g} rad of the pinion from the open "
                "fingers); give a backlash below it (the e-manual's 0.0044 rad).")

    def stribeck(self, velocity_rad_s: float) -> float:
        """1 at rest, falling to 0 above the Stribeck velocity."""
        return math.exp(-(abs(velocity_rad_s) / self.stribeck_velocity_rad_s)
                        ** STRIBECK_EXPONENT)

    def friction_nm(self, velocity_rad_s: float, motor_torque_nm: float,
                    guide_torque_nm: float = 0.0) -> float:
        """The friction budget at this velocity and transmitted torque [N m]."""
        s = self.stribeck(velocity_rad_s)
        return (self.torque_offset_nm + self.coulomb_friction_nm + guide_torque_nm
                + s * (self.stribeck_friction_nm
                       + self.load_friction_ratio * abs(motor_torque_nm))
                + self.viscous_friction_nm_s * abs(velocity_rad_s))

    @staticmethod
    def gain_a_per_rad(position_p_gain: float) -> float:
        """The position loop's current per radian of error for a Position P Gain."""
        return A_PER_RAD_PER_P_GAIN * position_p_gain

    def rack_after(self, rack_rad: float, output_rad: float) -> float:
        """Where the racks are (in pinion angle) once the output is at ``output_rad``: the
        play operator; the pinion pushes them closed at ``output - backlash`` and open at
        ``output``."""
        return min(max(rack_rad, output_rad - self.backlash_rad), output_rad)


#: The sources' drivetrain of the XM430-W210 (the mock's default).
DEFAULT_DRIVETRAIN = Drivetrain()
