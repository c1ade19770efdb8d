"""A skin that is pressed, sheared, tilted and twisted, and the six-axis bench around it.

``WrenchSkin`` answers a probe state (indentation d, lateral displacement sx, sy [m],
rotation rx, ry, rz [rad]: tilt about x, tilt about y, twist about z) with every module's
output and the wrench (Fx, Fy, Fz, Tx, Ty, Tz) on the skin, from the FEM alone:

- Press and shear: ``ArraySkin`` (the array grid) for the outputs and forces. The grid
  carries no torque, so the torque of a press is the wrench set's press path and that of
  a shear is the set's shear paths: per metre of lateral displacement along each axis and
  sense, a coefficient that depends on d (interpolated in d, zero at d = 0), the lateral
  displacement clamped at the grid's slip limit as in ``ArraySkin``.
- Rotation: for each rotation axis and sense, each indentation level of the set's path
  gives the change of every output and wrench component against the press path at the
  same indentation, per radian. The answer adds coefficient(d) x |rotation| per axis: linear
  in each rotation, exact at the set's points, zero at d = 0. The opposite sense comes from
  the set's mirror images (a mirror turns a tilt or twist about +a into one about -a), so
  what is even in the rotation (a twist shortens the skin whichever way it turns) stays
  even; only a layout without that mirror falls back to oddness (-a reads minus +a).
- Beyond the set: rotations larger than the set's (``wrench_tilt``, ``wrench_twist``)
  and several rotations at once extrapolate linearly (superposition); beyond the deepest
  level the coefficients hold their d_max values (the forces of the press keep the grid's
  last slope).

Wrench convention: the FEM's, the probe's force and torque on the skin (Fz = the grid's
``force_n``, pressing positive), torques about the probe's centre, right-hand rule.

``WrenchBenchWorld`` is ``ArrayBenchWorld`` with a six-axis stage (d, sx, sy, rx, ry, rz)
and a six-axis gauge carrying the viscoelastic rate effect on every component.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Protocol

import numpy as np
import numpy.typing as npt

from tactile_sensor.sim.array_world import (
    ArrayBenchWorld,
    ArraySkin,
    Progress,
    StageProfile,
    stage_path,
)
from tactile_sensor.sim.bench_world import TimeLike
from tactile_sensor.sim.errors import SimError

#: Modules a wrench protocol needs at least: one output per wrench component.
WRENCH_MIN_MODULES = 6


class WrenchSetLike(Protocol):
    """What ``WrenchSkin`` reads of ``physics.wrench.WrenchSet``."""

    wrench: np.ndarray
    outputs_v: dict[str, np.ndarray]
    path: np.ndarray
    digest: str


class WrenchPoints:
    """The set's points with the probe state each was solved at: indentation d (n,),
    shear (n, 2) [m], rotation (n, 3) [rad], outputs (n, modules) [V], wrench (n, 6)."""

    def __init__(self, modules: tuple[str, ...], d: np.ndarray, shear: np.ndarray,
                 rotation: np.ndarray, outputs: np.ndarray, wrench: np.ndarray) -> None:
        self.modules = modules
        self.d, self.shear, self.rotation = d, shear, rotation
        self.outputs, self.wrench = outputs, wrench


def wrench_points(params: Any, data: WrenchSetLike) -> WrenchPoints:
    """Label every point of a set from ``params`` (what ``compute_wrench_set`` solved): its
    rows are path after path, each followed by its mirror images (``symmetries`` order,
    the press once), ``array_steps`` load steps each (rest once, first)."""
    from tactile_sensor.physics.array_grid import symmetries
    from tactile_sensor.physics.errors import PhysicsError
    from tactile_sensor.physics.wrench import wrench_paths

    try:
        paths = wrench_paths(params)
    except PhysicsError as exc:
        raise SimError(str(exc)) from None
    maps = symmetries(params)
    steps, d_max = int(params.array_steps), float(params.max_indentation)
    fractions = np.arange(steps + 1) / steps
    d, shear, rotation = [], [], []
    for k, p in enumerate(paths):
        for j, g in enumerate(maps):
            if j and k == 0:
                continue
            f = fractions if (k == 0 and j == 0) else fractions[1:]
            m = np.eye(3)
            m[:2, :2] = g
            s = g @ np.array([p.shear_x_m, p.shear_y_m])
            r = np.linalg.det(m) * (m @ np.array([p.tilt_x_rad, p.tilt_y_rad,
                                                    p.twist_z_rad]))
            d.append(f * d_max)
            shear.append(f[:, None] * s)
            rotation.append(f[:, None] * r)
    n = sum(x.size for x in d)
    modules = tuple(params.module_faces)
    if n != np.asarray(data.path).size or set(data.outputs_v) != set(modules):
        raise SimError("The wrench set does not match the physics parameters (other paths, "
                       "steps or modules); delete it from the cache and recompute.")
    return WrenchPoints(modules, np.concatenate(d), np.concatenate(shear),
                        np.concatenate(rotation),
                        np.stack([np.asarray(data.outputs_v[m], float) for m in modules], 1),
                        np.asarray(data.wrench, float))


class WrenchSkin:
    """(d, sx, sy, rx, ry, rz) -> module outputs and (Fx, Fy, Fz, Tx, Ty, Tz); vectorised."""

    #: What acts on it: indentation, lateral displacement (x, y), tilt (x, y), twist (z).
    axes = 6

    def __init__(self, skin: ArraySkin, points: WrenchPoints, half_width_m: float = 0.011,
                 half_depth_m: float = 0.011, source: str = "") -> None:
        if set(points.modules) != set(skin.faces):
            raise SimError("The wrench set and the array grid read different modules; "
                           "compute both from the same physics parameters.")
        order = [points.modules.index(f) for f in skin.faces]
        values = np.column_stack([points.outputs[:, order], points.wrench])
        self.skin = skin
        self.faces = skin.faces
        self.rest_voltage_v = skin.rest_voltage_v
        self.half_width_m, self.half_depth_m = float(half_width_m), float(half_depth_m)
        self.source = source or skin.source
        m = len(self.faces)
        self._m = m
        levels = np.unique(np.round(points.d, 12))
        if levels[0] != 0.0 or levels.size < 2:
            raise SimError("The wrench set has no rest point or no indentation level; "
                           "recompute it.")
        self._d = levels
        k = np.searchsorted(levels, np.round(points.d, 12))
        moved = np.any(points.shear != 0, axis=1) | np.any(points.rotation != 0, axis=1)
        press = np.full((levels.size, m + 6), np.nan)
        press[k[~moved]] = values[~moved]
        if np.isnan(press).any():
            raise SimError("The wrench set lacks its press path at some indentation; "
                           "recompute it.")
        self._press_torque = press[:, m + 3:]
        delta = values - press[k]
        # rotation: coefficient tables [axis, sense 0:+ 1:-][level, column] per radian
        self._rot = np.zeros((3, 2, levels.size, m + 6))
        self._rot_seen = np.zeros((3, 2), bool)
        # shear torque: [axis, sense][level, torque] per metre
        self._shear = np.zeros((2, 2, levels.size, 3))
        shear_seen = np.zeros((2, 2), bool)
        for table, seen, amounts, other, cols in (
                (self._rot, self._rot_seen, points.rotation, points.shear, slice(None)),
                (self._shear, shear_seen, points.shear, points.rotation, slice(m + 3, None))):
            for a in range(amounts.shape[1]):
                single = (np.count_nonzero(amounts, axis=1) == 1) & (amounts[:, a] != 0) & \
                    ~np.any(other != 0, axis=1)
                for sense, sign in ((0, 1.0), (1, -1.0)):
                    rows = np.flatnonzero(single & (np.sign(amounts[:, a]) == sign))
                    if rows.size == 0:
                        continue
                    per = delta[rows][:, cols] / np.abs(amounts[rows, a])[:, None]
                    for level in np.unique(k[rows]):   # images at one level: their mean
                        table[a, sense, level] = per[k[rows] == level].mean(axis=0)
                    if np.unique(k[rows]).size != levels.size - 1:
                        raise SimError("The wrench set lacks a load step of a path; "
                                       "recompute it.")
                    seen[a, sense] = True
                if seen[a, 0] != seen[a, 1]:          # no mirror image: odd in the motion
                    have = 0 if seen[a, 0] else 1
                    table[a, 1 - have] = -table[a, have]
                    seen[a, 1 - have] = True
        if not (self._rot_seen.all() and shear_seen.all()):
            raise SimError("The wrench set lacks a shear or rotation axis; recompute it "
                           "with the current physics/wrench.py.")
        self.max_tilt_rad = float(np.abs(points.rotation[:, :2]).max())
        self.max_twist_rad = float(np.abs(points.rotation[:, 2]).max())

    @classmethod
    def from_params(cls, params: Any, cache_dir: Path | None = None,
                    progress: Progress | None = None, workers: int = 1) -> WrenchSkin:
        """The wrench skin of ``params`` (several ``modules``): the cached grid and wrench
        set, each computed (and cached) first when missing."""
        try:
            from tactile_sensor.physics.errors import PhysicsError
            from tactile_sensor.physics.wrench import load_or_compute_wrench_set
        except ImportError as exc:
            raise SimError(f"The physics model is not available ({exc}); install the "
                           "complete tactile_sensor package.") from None
        skin = ArraySkin.from_params(params, cache_dir, progress, workers)
        try:
            data = load_or_compute_wrench_set(params, cache_dir, progress, workers)
        except PhysicsError as exc:
            raise SimError(f"The wrench set failed ({exc}).") from None
        return cls(skin, wrench_points(params, data), params.width / 2, params.depth / 2,
                   source=f"{skin.source}+wrench:{data.digest}")

    @property
    def max_indentation_m(self) -> float:
        return self.skin.max_indentation_m

    @property
    def max_shear_ratio(self) -> float:
        return self.skin.max_shear_ratio

    def _weights(self, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        levels = self._d
        deep = np.clip(d, 0.0, levels[-1])
        k0 = np.clip(np.searchsorted(levels, deep, side="right") - 1, 0, levels.size - 2)
        return k0, ((deep - levels[k0]) / (levels[k0 + 1] - levels[k0]))[:, None]

    def state(self, indentation_m: npt.ArrayLike, shear_x_m: npt.ArrayLike = 0.0,
              shear_y_m: npt.ArrayLike = 0.0, tilt_x_rad: npt.ArrayLike = 0.0,
              tilt_y_rad: npt.ArrayLike = 0.0, twist_z_rad: npt.ArrayLike = 0.0
              ) -> np.ndarray:
        """Outputs [V] of every module (``faces`` order), then Fx, Fy, Fz [N] and Tx, Ty,
        Tz [N m]: shape (..., modules + 6) for states broadcast from the arguments."""
        args = np.broadcast_arrays(*(np.asarray(a, float) for a in (
            indentation_m, shear_x_m, shear_y_m, tilt_x_rad, tilt_y_rad, twist_z_rad)))
        shape = args[0].shape
        d, sx, sy, rx, ry, rz = (a.ravel() for a in args)
        if not all(np.all(np.isfinite(a)) for a in (rx, ry, rz)):
            raise SimError("Probe rotations must be finite numbers (tilt and twist in rad).")
        base = self.skin.state(d, sx, sy)
        d = np.maximum(d, 0.0)
        k0, w = self._weights(d)
        m = self._m

        def at(table: np.ndarray) -> np.ndarray:
            return table[k0] * (1.0 - w) + table[k0 + 1] * w

        out = np.zeros((d.size, m + 6))
        out[:, :m + 3] = base
        out[:, m + 3:] = at(self._press_torque)
        # lateral displacement clamped at the slip limit, as the grid does
        s = np.hypot(sx, sy)
        limit = self.skin.max_shear_ratio * d
        scale = np.where(s > limit, np.divide(limit, s, out=np.zeros_like(s), where=s > 0),
                         1.0)
        for a, amount in enumerate((sx * scale, sy * scale)):
            for sense, sign in ((0, 1.0), (1, -1.0)):
                on = np.sign(amount) == sign
                if np.any(on):
                    out[on, m + 3:] += at(self._shear[a, sense])[on] * \
                        np.abs(amount[on])[:, None]
        for a, amount in enumerate((rx, ry, rz)):
            for sense, sign in ((0, 1.0), (1, -1.0)):
                on = np.sign(amount) == sign
                if np.any(on):
                    out[on] += at(self._rot[a, sense])[on] * np.abs(amount[on])[:, None]
        return out.reshape(*shape, m + 6)

    def outputs_v(self, *state: npt.ArrayLike) -> np.ndarray:
        """Module outputs [V], shape (..., modules), of ``state(*state)``."""
        return self.state(*state)[..., :self._m]

    def voltages_v(self, *state: npt.ArrayLike) -> np.ndarray:
        """Photoreflector voltages [V], shape (..., modules)."""
        return self.rest_voltage_v - self.outputs_v(*state)

    def wrench(self, *state: npt.ArrayLike) -> np.ndarray:
        """(Fx, Fy, Fz, Tx, Ty, Tz) [N, N m], shape (..., 6)."""
        return self.state(*state)[..., self._m:]

    def edge_lift_m(self, tilt_x_rad: npt.ArrayLike, tilt_y_rad: npt.ArrayLike) -> Any:
        """How far a tilt raises the probe's highest corner above its centre [m]."""
        return np.abs(tilt_x_rad) * self.half_depth_m + np.abs(tilt_y_rad) * self.half_width_m


def wrench_stage_path(profile: StageProfile, t_s: npt.ArrayLike) -> np.ndarray:
    """(n, 6) stage positions: indentation, lateral x, y [m], tilt x, y, twist z [rad]."""
    t = np.asarray(t_s, float)
    lin = stage_path(profile, t)
    rotation = getattr(profile, "rotation", None)
    rot = np.zeros_like(lin) if rotation is None else np.stack(
        [np.asarray(r, float) for r in rotation(t)], axis=-1)
    return np.concatenate([lin, rot], axis=-1)


class WrenchBenchWorld(ArrayBenchWorld):
    """Ground truth of one six-axis bench run: stage (d, sx, sy, rx, ry, rz) and gauge
    (Fx, Fy, Fz, Tx, Ty, Tz), the probe's force and torque on the skin as the FEM and the
    three-axis gauge give them, each with the viscoelastic rate effect (linear in the
    elastic history, so per component). Precomputed on a ``grid_hz`` grid."""

    skin: WrenchSkin  # type: ignore[assignment]
    _protocol = "wrench"
    _stage_path = staticmethod(wrench_stage_path)

    def _refuse_path(self, profile: StageProfile, skin: ArraySkin) -> None:
        super()._refuse_path(profile, skin)
        knots = getattr(profile, "knots", None)
        if knots is None:
            return
        _, pts = knots()
        if pts.shape[1] == 6:   # the lift is convex along each segment: knots suffice
            lift = skin.edge_lift_m(pts[:, 3], pts[:, 4])  # type: ignore[attr-defined]
            worst = int(np.argmax(lift - pts[:, 0]))
            if lift[worst] > pts[worst, 0] + 1e-12:
                raise SimError(
                    f"The protocol's tilt lifts the probe's edge {lift[worst] * 1e3:.3g} mm"
                    f" at {pts[worst, 0] * 1e3:.3g} mm depth (the edge would leave the "
                    "skin); lower protocol.tilt or raise protocol.depth.")

    def wrench_n(self, t: TimeLike) -> Any:
        """Gauge (Fx, Fy, Fz [N], Tx, Ty, Tz [N m]) with the rate effect, shape (..., 6)."""
        return self._at(t, self._w)

    def elastic_wrench_n(self, t: TimeLike) -> Any:
        """Quasi-static wrench at the same stage position, shape (..., 6)."""
        return self._at(t, self._w_el)

    def stage_and_gauge(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return np.asarray(self.stage_m(t), float), np.asarray(self.wrench_n(t), float)
