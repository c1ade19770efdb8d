"""The gripper of the paper's section III-E as a small 1-D world the servo emulator drives.

Geometry (documented in docs/gripper.md): one XM430 turns a spur gear (module 1, 28 teeth,
pitch radius 14 mm) between two racks, so both fingers move symmetrically along the linear
guide. Servo angle ``theta`` is measured from ``open_position_rad`` (fingers fully open);
**positive rotation closes**: ``opening = open_opening_m - 2 * pitch_radius_m * theta``.
``opening`` is the distance between the two skin surfaces. A rod of ``rod_diameter_m`` is held
fixed at ``rod_offset_m`` from the gripper centre (positive towards finger B). Each
fingertip is a skin block (``sim/skin_block.py``), the same skin model the bench presses:
finger A's carries the tactile module, finger B's the same skin without a module. A
fingertip that feels shear (``fingertip``: the FEM array grid, ``sim/array_world.ArraySkin``)
puts modules on finger A's side faces: they read the press and the object's shear of the
skin (finger A's elastic deflection along the fingers, the skin block's x); the fingers'
normal forces stay the curve's, on both fingers alike.

Contact: a finger's skin indentation is how far its surface has passed the rod's edge; the
skin's response (force and photoreflector voltage against indentation) comes from the physics
layer through :class:`TabulatedSkin`. Beyond the table the skin bottoms out on the resin
frame, modelled as a stiff spring. The motor must supply ``pitch_radius_m * (F_A + F_B)`` to
hold a position; hard stops at both ends of the travel do the same with a stiff spring.

An object with mass (``held``, sim/held_object.py) makes the rod free along the fingers:
it stands on its support until :meth:`GripperWorld.lift`, then gravity and a scripted pull
act on it, and the skins' friction holds it or lets it slip. Without one the rod is fixed.

Threads: the emulator thread calls :meth:`GripperWorld.update`; the mock ADC thread calls
:meth:`GripperWorld.module_voltages`; a lock guards the shared state.
"""

from __future__ import annotations

import bisect
import threading
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import numpy.typing as npt

from tactile_sensor.control.geometry import GripperGeometry
from tactile_sensor.sim.held_object import HeldObject, ObjectState
from tactile_sensor.sim.skin_block import SkinBlock
from tactile_sensor.sim.skin_response import RIGID_STIFFNESS_N_PER_M, SkinResponse


@dataclass(frozen=True)
class WorldSample:
    """Ground truth at one instant; ``voltages_v``: finger A's modules, layout order."""

    t_s: float
    position_rad: float
    opening_m: float
    indentation_a_m: float
    indentation_b_m: float
    force_a_n: float
    force_b_n: float
    voltages_v: tuple[float, ...]
    #: The object along the fingers (None: the rod is fixed).
    held: ObjectState | None = None


class GripperWorld:
    """Fingers, skins and the rod; feeds load torque to the motor and voltages to the ADC."""

    def __init__(self, skin: SkinResponse, geometry: GripperGeometry | None = None,
                 rod_diameter_m: float | None = 0.020, rod_offset_m: float = 0.0,
                 history_s: float = 5.0, stiffness_ratio: float = 1.0,
                 held: HeldObject | None = None, fingertip: Any = None) -> None:
        self.geometry = geometry or GripperGeometry()
        if rod_diameter_m is not None and rod_diameter_m <= 0:
            raise ValueError("rod_diameter_m must be positive (or None for no rod)")
        #: Finger A's and finger B's skins (their normal forces) and finger A's modules:
        #: the skin's own module, or a fingertip's several (the world's channels).
        self.finger_a = SkinBlock(skin, stiffness_ratio=stiffness_ratio)
        self.finger_b = SkinBlock(skin, faces=(), stiffness_ratio=stiffness_ratio)
        self.fingertip = self.finger_a if fingertip is None else SkinBlock(fingertip)
        self.faces = self.fingertip.faces
        if held is not None and rod_diameter_m is None:
            raise ValueError("an object with mass needs a rod diameter (its size)")
        self.held = held
        self._lock = threading.Lock()
        #: Moves whenever the modules' voltages do: the mock ADC samples a world that holds
        #: still ahead of time in one call (sim/adc_device.py), one frame at a time otherwise.
        self.revision = 0
        self._rod: tuple[float, float] | None = None
        self.set_rod(rod_diameter_m, rod_offset_m)
        self._times: list[float] = []
        self._forces: list[float] = []
        self._history_s = history_s
        self._latest = self._sample(0.0, self.geometry.open_position_rad)
        if held is not None:
            self._latest = replace(self._latest, held=held.state)

    # -- configuration ---------------------------------------------------------------------

    def set_rod(self, diameter_m: float | None, offset_m: float = 0.0) -> None:
        """Place (or remove, with None) the rod between the fingers."""
        with self._lock:
            self._rod = None if diameter_m is None else (float(diameter_m), float(offset_m))

    def lift(self) -> bool:
        """Take the object off its support (False: there is no object)."""
        with self._lock:
            if self.held is None:
                return False
            self.held.lift()
            return True

    def set_down(self) -> bool:
        """Put the object back on its support (False: there is no object)."""
        with self._lock:
            if self.held is None:
                return False
            self.held.set_down()
            return True

    @property
    def rod_clearance_rad(self) -> float:
        """The pinion's free turn from the open fingers to the rod's nearer side (inf: no
        rod): a play as large would leave the fingers unable to tell touching from not."""
        rod = self._rod
        if rod is None:
            return float("inf")
        diameter, offset = rod
        gap_m = 0.5 * (self.geometry.open_opening_m - diameter) - abs(offset)
        return max(gap_m, 0.0) / self.geometry.pitch_radius_m

    @property
    def initial_position_rad(self) -> float:
        return self.geometry.open_position_rad

    # -- physics ---------------------------------------------------------------------------

    def indentations_m(self, position_rad: float) -> tuple[float, float]:
        """Skin indentation of finger A (at -opening/2) and finger B (at +opening/2)."""
        rod = self._rod
        if rod is None or (self.held is not None and self.held.dropped):
            return 0.0, 0.0
        diameter, offset = rod
        half = 0.5 * self.geometry.opening_m(position_rad)
        # surfaces are at -half and +half; the rod spans offset +- diameter/2
        d_a = max(0.0, -half - (offset - 0.5 * diameter))
        d_b = max(0.0, (offset + 0.5 * diameter) - half)
        return d_a, d_b

    def load_torque_nm(self, position_rad: float) -> float:
        """Torque the servo must supply to hold ``position_rad`` (positive resists closing)."""
        g = self.geometry
        d_a, d_b = self.indentations_m(position_rad)
        force = (self.finger_a.load(d_a) if d_a else 0.0) + (
            self.finger_b.load(d_b) if d_b else 0.0)
        opening = g.opening_m(position_rad)
        if opening < g.closed_opening_m:
            force += RIGID_STIFFNESS_N_PER_M * (g.closed_opening_m - opening)
        if opening > g.open_opening_m:
            force -= RIGID_STIFFNESS_N_PER_M * (opening - g.open_opening_m)
        # each rack pushes its finger with the skin force; the pinion feels both
        return g.pitch_radius_m * force

    def _sample(self, t_s: float, position_rad: float, shear_m: float = 0.0) -> WorldSample:
        d_a, d_b = self.indentations_m(position_rad)
        return WorldSample(t_s, position_rad, self.geometry.opening_m(position_rad), d_a, d_b,
                           self.finger_a.load(d_a) if d_a else 0.0,
                           self.finger_b.load(d_b) if d_b else 0.0,
                           self._voltages(d_a, shear_m))

    def _voltages(self, indentation_m: float, shear_m: float) -> tuple[float, ...]:
        """Finger A's modules at that press and that deflection along the fingers."""
        tip = self.fingertip
        if tip.axes > 1:
            return tuple(np.asarray(tip.module_voltages(indentation_m, shear_m, 0.0),
                                    dtype=float).tolist())
        return tuple(tip.module_voltages(indentation_m).tolist())

    def update(self, t_s: float, position_rad: float) -> WorldSample:
        """Record the fingers at ``position_rad`` at time ``t_s`` (emulator thread)."""
        sample = self._sample(t_s, position_rad)
        with self._lock:
            if self.held is not None:
                held = self.held.step(t_s, (sample.force_a_n, sample.force_b_n),
                                      (sample.indentation_a_m, sample.indentation_b_m))
                sample = replace(sample, held=held)
                if self.fingertip.axes > 1 and held.deflection_a_m:
                    sample = replace(sample, voltages_v=self._voltages(
                        sample.indentation_a_m, held.deflection_a_m))
            if sample.voltages_v != self._latest.voltages_v:
                self.revision += 1
            self._latest = sample
            self._times.append(t_s)
            self._forces.append(sample.force_a_n)
            if self._times[0] < t_s - 2.0 * self._history_s:
                cut = bisect.bisect_left(self._times, t_s - self._history_s)
                del self._times[:cut], self._forces[:cut]
        return sample

    # -- readers (any thread) ----------------------------------------------------------------

    @property
    def latest(self) -> WorldSample:
        with self._lock:
            return self._latest

    def photoreflector_voltage(self, t: float) -> float:
        """Voltage of finger A's (first) photoreflector now (``t`` is the ADC's clock; the world
        answers with its latest state, which the emulator keeps within a millisecond)."""
        del t
        with self._lock:
            return self._latest.voltages_v[0]

    def module_voltages(self, t: float | npt.ArrayLike) -> npt.NDArray[np.float64]:
        """Finger A's modules' voltages [V] now, shape (..., modules) for the times ``t``
        (the ADC's clock; the latest state for each, as ``photoreflector_voltage``)."""
        with self._lock:
            volts = self._latest.voltages_v
        return np.broadcast_to(np.asarray(volts, dtype=float), (*np.shape(t), len(volts)))

    @property
    def voltage_source(self) -> ModuleVoltages:
        """What the mock ADC samples: ``module_voltages`` with this world's ``revision``."""
        return ModuleVoltages(self)

    def force_at(self, t_s: float) -> float:
        """Finger A's skin force at time ``t_s`` from the recorded history (interpolated;
        the first/last sample outside it)."""
        with self._lock:
            times, forces = self._times, self._forces
            if not times:
                return self._latest.force_a_n
            i = bisect.bisect_left(times, t_s)
            if i <= 0:
                return forces[0]
            if i >= len(times):
                return forces[-1]
            t0, t1, f0, f1 = times[i - 1], times[i], forces[i - 1], forces[i]
        w = (t_s - t0) / (t1 - t0) if t1 > t0 else 1.0
        return f0 + w * (f1 - f0)


class ModuleVoltages:
    """A world's ``module_voltages`` as a voltage source that carries its ``revision``."""

    def __init__(self, world: GripperWorld) -> None:
        self.world = world

    def __call__(self, t: float | npt.ArrayLike) -> npt.NDArray[np.float64]:
        return self.world.module_voltages(t)

    @property
    def revision(self) -> int:
        return self.world.revision
