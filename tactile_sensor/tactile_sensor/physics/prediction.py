"""The prediction curve: indentation -> force, bulge, distance, voltage, module output.

One FEM sweep (``fem.extrapolated_sweep``: two meshes, Richardson-extrapolated) plus the
photoreflector optics gives the curve the model node serves, the mocks simulate and the
analysis overlays. It is cached on disk under the hash of every parameter that changes it,
so only the first run with new parameters pays for the sweep; the cache write is atomic (a
crashed run never leaves half a file).
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import os
import tempfile
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

import numpy as np
import numpy.typing as npt

from .errors import OutOfRangeError, PhysicsError
from .optics import Photoreflector
from .params import PhysicsParams

if TYPE_CHECKING:
    from .fem import SweepResult

Progress = Callable[[float, str], None]
T = TypeVar("T")
ARRAYS = ("indentation_m", "force_n", "bulge_m", "distance_m", "voltage_v", "output_v")
#: Per load step too, added with shear load paths; a file without them has them all zero.
SHEAR_ARRAYS = ("shear_x_m", "shear_y_m", "force_x_n", "force_y_n")
#: Per load step, added with tilt/twist load paths: the probe's rotation vector [rad] and its
#: torque on the skin about its centre [N m]. Written only when the path rotates (so the JSON
#: of a path without rotation is what it was); a file without them has them all zero.
ROTATION_ARRAYS = ("tilt_x_rad", "tilt_y_rad", "twist_z_rad",
                   "torque_x_nm", "torque_y_nm", "torque_z_nm")


@dataclass(frozen=True)
class CurvePoints:
    """The curve's quantities at requested indentations."""

    indentation_m: np.ndarray
    force_n: np.ndarray
    bulge_m: np.ndarray
    distance_m: np.ndarray
    voltage_v: np.ndarray
    output_v: np.ndarray


@dataclass(frozen=True, eq=False)
class PredictionCurve:
    """Per load step of the FEM sweep (SI units); ``digest`` names the parameters."""

    indentation_m: np.ndarray
    force_n: np.ndarray
    bulge_m: np.ndarray  # side-surface displacement toward the photoreflector
    distance_m: np.ndarray  # photoreflector-skin distance = gap - bulge
    voltage_v: np.ndarray
    output_v: np.ndarray  # paper's inverted output: V(rest) - V
    nodes: int
    seconds: float
    digest: str
    # probe's lateral position [m] and lateral force on the skin [N] (+x, +y)
    shear_x_m: np.ndarray = field(default=None)  # type: ignore[assignment]
    shear_y_m: np.ndarray = field(default=None)  # type: ignore[assignment]
    force_x_n: np.ndarray = field(default=None)  # type: ignore[assignment]
    force_y_n: np.ndarray = field(default=None)  # type: ignore[assignment]
    # every module's bulge [m] and output [V] by face; the first module's are the above
    module_bulges_m: dict[str, np.ndarray] = field(default=None)  # type: ignore[assignment]
    module_outputs_v: dict[str, np.ndarray] = field(default=None)  # type: ignore[assignment]
    # probe's rotation vector [rad] and torque on the skin about its centre [N m]
    tilt_x_rad: np.ndarray = field(default=None)  # type: ignore[assignment]
    tilt_y_rad: np.ndarray = field(default=None)  # type: ignore[assignment]
    twist_z_rad: np.ndarray = field(default=None)  # type: ignore[assignment]
    torque_x_nm: np.ndarray = field(default=None)  # type: ignore[assignment]
    torque_y_nm: np.ndarray = field(default=None)  # type: ignore[assignment]
    torque_z_nm: np.ndarray = field(default=None)  # type: ignore[assignment]
    # every module's window displacement along its face's counter-clockwise tangent [m]; a
    # file written without it has it zero (it only changes outputs with a pigment gradient,
    # which is part of the digest)
    module_tangents_m: dict[str, np.ndarray] = field(default=None)  # type: ignore[assignment]

    def __post_init__(self) -> None:
        zeros = np.zeros_like(self.indentation_m)
        for name in SHEAR_ARRAYS + ROTATION_ARRAYS:
            if getattr(self, name) is None:
                object.__setattr__(self, name, zeros)
        if self.module_bulges_m is None:
            object.__setattr__(self, "module_bulges_m", {"front": self.bulge_m})
        if self.module_outputs_v is None:
            object.__setattr__(self, "module_outputs_v", {"front": self.output_v})
        if self.module_tangents_m is None:
            object.__setattr__(self, "module_tangents_m",
                               {k: zeros for k in self.module_bulges_m})

    @property
    def rotates(self) -> bool:
        """Whether the load path tilts or twists the probe (then the JSON has the torque)."""
        return bool(np.any(self.tilt_x_rad) or np.any(self.tilt_y_rad)
                    or np.any(self.twist_z_rad))

    @property
    def max_indentation_m(self) -> float:
        return float(self.indentation_m[-1])

    def at(self, indentation_m: npt.ArrayLike) -> CurvePoints:
        """Linear interpolation between load steps; refuses to extrapolate."""
        d = np.atleast_1d(np.asarray(indentation_m, dtype=float))
        low, high = 0.0, self.max_indentation_m
        bad = ~np.isfinite(d) | (d < low - 1e-12) | (d > high + 1e-12)
        if np.any(bad):
            first = float(d[bad][0])
            raise OutOfRangeError(
                f"Indentation {first:g} m is outside the modelled range {low:g}..{high:g} m; "
                "ask within it or recompute the model with a larger max_indentation.")
        return self.at_clamped(d)

    def at_clamped(self, indentation_m: npt.ArrayLike) -> CurvePoints:
        """Like :meth:`at`, holding the end values outside the range (for simulators)."""
        d = np.asarray(indentation_m, dtype=float)
        return CurvePoints(*(np.interp(d, self.indentation_m, getattr(self, name))
                             for name in ARRAYS))

    def calibration(self) -> tuple[np.ndarray, np.ndarray]:
        """(output [V] strictly increasing, force [N]): the inverse used by the driver."""
        keep = [0]
        for i in range(1, self.output_v.size):
            if self.output_v[i] > self.output_v[keep[-1]] + 1e-12:
                keep.append(i)
        if len(keep) < 2:
            raise PhysicsError("The predicted output does not grow with indentation, so it "
                               "cannot calibrate force; check the window and gap parameters.")
        return self.output_v[keep].copy(), self.force_n[keep].copy()

    def force_from_output(self, output_v: npt.ArrayLike) -> np.ndarray:
        output, force = self.calibration()
        return np.interp(output_v, output, force)

    def to_dict(self) -> dict[str, Any]:
        names = ARRAYS + SHEAR_ARRAYS + (ROTATION_ARRAYS if self.rotates else ())
        data: dict[str, Any] = {name: getattr(self, name).tolist() for name in names}
        data.update(module_bulges_m={k: v.tolist() for k, v in self.module_bulges_m.items()},
                    module_outputs_v={k: v.tolist() for k, v in self.module_outputs_v.items()},
                    module_tangents_m={k: v.tolist() for k, v in self.module_tangents_m.items()},
                    nodes=self.nodes, seconds=self.seconds, digest=self.digest)
        return data

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> PredictionCurve:
        if not isinstance(data, dict):
            raise PhysicsError("A prediction file must hold a JSON object; regenerate it with "
                               "'tactile-sensor model sweep --json'.")
        try:
            arrays = {name: np.asarray(data[name], dtype=float) for name in ARRAYS}
            arrays.update({name: np.asarray(data[name], dtype=float)
                           for name in SHEAR_ARRAYS + ROTATION_ARRAYS if name in data})
            faces = {key: {str(k): np.asarray(v, dtype=float) for k, v in data[key].items()}
                     for key in ("module_bulges_m", "module_outputs_v", "module_tangents_m")
                     if key in data}
            curve = cls(**arrays, **faces, nodes=int(data["nodes"]),
                        seconds=float(data["seconds"]), digest=str(data.get("digest", "")))
        except (KeyError, TypeError, ValueError, AttributeError) as exc:
            raise PhysicsError(f"A prediction file lacks or mangles {exc}; regenerate it with "
                               "'tactile-sensor model sweep --json'.") from None
        arrays.update({f"{key}[{k}]": v for key, per_face in faces.items()
                       for k, v in per_face.items()})
        if any(a.ndim != 1 or not np.all(np.isfinite(a)) for a in arrays.values()):
            raise PhysicsError("A prediction file's arrays must be flat lists of finite "
                               "numbers; regenerate it.")
        sizes = {a.size for a in arrays.values()}
        if len(sizes) != 1 or sizes.pop() < 2 or np.any(np.diff(curve.indentation_m) <= 0):
            raise PhysicsError("A prediction file's arrays differ in length or its "
                               "indentations do not increase; regenerate it.")
        return curve


def module_output(params: PhysicsParams, bulge_m: npt.ArrayLike,
                  tangent_m: npt.ArrayLike = 0.0
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(distance [m], voltage [V], output [V]) of a module whose window bulges this much and
    slides ``tangent_m`` along the face's counter-clockwise tangent.

    With a graded pigment the skin now under the window's centre came from -u_t, so the
    window sees the white share ``pigment_white - window_pigment_gradient * u_t /
    window_width`` (clamped to 0..100); the rest voltage is the ungraded skin's.
    """
    optics = Photoreflector(params.pigment_white, params.supply_voltage)
    distance = params.gap - np.asarray(bulge_m, dtype=float)
    if np.any(distance < 0):
        raise PhysicsError("The skin would bulge past the photoreflector (distance < 0); "
                           "increase 'gap' or reduce 'max_indentation'.")
    voltage = optics.voltage(distance, white_share(params, tangent_m))
    rest = float(optics.voltage(params.gap))
    return distance, voltage, rest - voltage


def white_share(params: PhysicsParams, tangent_m: npt.ArrayLike) -> np.ndarray | None:
    """The pigment white share [%] the window sees after the skin slid ``tangent_m``, or
    None for uniform pigment (the photoreflector's own share, bit for bit)."""
    if params.window_pigment_gradient == 0:
        return None
    shift = np.asarray(tangent_m, dtype=float) / params.window_width
    return np.clip(params.pigment_white - params.window_pigment_gradient * shift, 0.0, 100.0)


def curve_from_sweep(params: PhysicsParams, indentation_m: np.ndarray, force_n: np.ndarray,
                     bulge_m: np.ndarray, nodes: int, seconds: float,
                     sweep: SweepResult | None = None) -> PredictionCurve:
    """Apply the optics to a mechanical sweep (``sweep``: its lateral load, rotation,
    torque and modules)."""
    tangent: npt.ArrayLike = 0.0
    extra: dict[str, Any] = {}
    if sweep is not None:
        tangent = sweep.tangents_m[params.module_faces[0]]
        extra = {name: np.asarray(getattr(sweep, name), float) for name in SHEAR_ARRAYS}
        columns = np.concatenate([sweep.rotation_rad, sweep.torque_nm], axis=1)
        extra.update({name: np.asarray(columns[:, k], float)
                      for k, name in enumerate(ROTATION_ARRAYS)})
        extra["module_bulges_m"] = {k: np.asarray(v, float) for k, v in sweep.bulges_m.items()}
        extra["module_tangents_m"] = {k: np.asarray(v, float)
                                      for k, v in sweep.tangents_m.items()}
        extra["module_outputs_v"] = {k: module_output(params, v, sweep.tangents_m[k])[2]
                                     for k, v in sweep.bulges_m.items()}
    distance, voltage, output = module_output(params, bulge_m, tangent)
    return PredictionCurve(np.asarray(indentation_m, float), np.asarray(force_n, float),
                           np.asarray(bulge_m, float), distance, voltage, output,
                           nodes, seconds, params.digest(), **extra)


def default_cache_dir() -> Path:
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "tactile_sensor"


def cache_file(cache_dir: Path | None, name: str) -> Path:
    """``name`` in ``cache_dir``, or in the folder the model node, the CLI and the studies
    share by default."""
    return (Path(cache_dir) if cache_dir is not None else default_cache_dir()) / name


@contextlib.contextmanager
def solving_lock(path: Path) -> Iterator[None]:
    """Hold ``path``'s lock file while its value is solved, so that processes missing the
    same entry at once (a model node and a CLI started together, two bring-ups) solve it once
    and the others wait for the file. Best effort: where no lock can be taken (a read-only
    cache) each solves it, as before. The kernel releases it when its holder dies."""
    handle = None
    with contextlib.suppress(OSError):
        path.parent.mkdir(parents=True, exist_ok=True)
        handle = open(path.with_name(f".{path.name}.lock"), "a")  # noqa: SIM115 (held below)
        fcntl.flock(handle, fcntl.LOCK_EX)
    try:
        yield
    finally:
        if handle is not None:
            handle.close()


def load_or_compute(path: Path, cached: Callable[[], T | None], compute: Callable[[], T],
                    store: Callable[[T], None], progress: Progress | None, miss: str) -> T:
    """The cached value at ``path``, or (announcing ``miss`` to ``progress``) computed and
    stored: the one way a curve, a grid and a wrench set are kept, so each is solved once
    per digest, by one process at a time."""
    value = cached()
    if value is not None:
        return value
    with solving_lock(path):
        value = cached()  # solved by another process while this one waited for the lock
        if value is not None:
            return value
        if progress is not None:
            progress(0.0, miss)
        value = compute()
        store(value)
    return value


def read_cache(path: Path, parse: Callable[[Any], Any]) -> Any:
    """``parse`` of the JSON at ``path``, or None when it is missing or damaged (even
    non-UTF-8): a damaged cache entry is recomputed and replaced."""
    if path.is_file():
        try:
            return parse(json.loads(path.read_text()))
        except (PhysicsError, ValueError, OSError):
            pass
    return None


def write_cache(path: Path, data: Any) -> None:
    """Write ``data`` as JSON atomically (a crashed run never leaves half a file); best effort:
    a read-only cache only costs time."""
    with contextlib.suppress(OSError):
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.stem}-", suffix=".tmp")
        try:
            with os.fdopen(fd, "w") as handle:
                json.dump(data, handle)
            os.replace(tmp, path)
        finally:
            with contextlib.suppress(OSError):
                os.unlink(tmp)


def compute_curve(params: PhysicsParams, progress: Progress | None = None) -> PredictionCurve:
    from .fem import extrapolated_sweep  # scikit-fem is only needed for a cold sweep

    if params.max_indentation <= 0:
        raise PhysicsError("A prediction curve runs along the indentation, so it needs "
                           "max_indentation > 0; give one.")
    sweep = extrapolated_sweep(params, progress)
    return curve_from_sweep(params, sweep.indentation_m, sweep.force_n, sweep.bulge_m,
                            sweep.nodes, sweep.seconds, sweep)


def cache_path(params: PhysicsParams, cache_dir: Path | None = None) -> Path:
    return cache_file(cache_dir, f"prediction-{params.digest()}.json")


def cached_curve(params: PhysicsParams, cache_dir: Path | None = None
                 ) -> PredictionCurve | None:
    """The cached curve for ``params``, or None (missing or damaged: recompute it). A
    rotating load path's entry written before the torque was stored has no rotation: it is
    stale and recomputed too."""
    curve = read_cache(cache_path(params, cache_dir), PredictionCurve.from_dict)
    if curve is not None and params.is_rotation and not curve.rotates:
        return None
    return curve


def store_curve(params: PhysicsParams, curve: PredictionCurve,
                cache_dir: Path | None = None) -> None:
    """Cache ``curve`` atomically (a crashed run never leaves half a file); best effort."""
    write_cache(cache_path(params, cache_dir), curve.to_dict())


def load_or_compute_curve(params: PhysicsParams, cache_dir: Path | None = None,
                          progress: Progress | None = None) -> PredictionCurve:
    """The cached curve for ``params``, computing and caching it on a miss."""
    return load_or_compute(
        cache_path(params, cache_dir), lambda: cached_curve(params, cache_dir),
        lambda: compute_curve(params, progress),
        lambda curve: store_curve(params, curve, cache_dir), progress,
        f"computing the FEM sweep (cache miss: {cache_path(params, cache_dir).name})")
