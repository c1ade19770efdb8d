"""Every physical parameter of the sensor model, in SI units, with the paper value or assumption.

One frozen dataclass so the FEM, the optics, the cache key and the ROS config all read the same
numbers. Field metadata carries the unit and the source; ``config/physics.yaml`` mirrors it.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from .errors import PhysicsError

#: Bump when the model code changes in a way that changes results, so old caches are ignored.
MODEL_VERSION = 2

BOUNDARIES = ("bonded", "frictionless")

#: Side faces a module can sit on -> (axis of the face's outward normal, its sign).
#: front is the paper's face (+y, the photoreflector looks at it from outside); back -y,
#: left -x, right +x.
FACES: dict[str, tuple[int, int]] = {"front": (1, 1), "back": (1, -1), "left": (0, -1),
                                     "right": (0, 1)}
OPPOSITE = {"front": "back", "back": "front", "left": "right", "right": "left"}


def _f(default: Any, unit: str, doc: str, *, curve: bool = True,
       low: float | None = None, high: float | None = None,
       low_open: bool = False, grid: bool = False) -> Any:
    """A field with its unit, its source/reason, bounds, whether it changes the curve and
    whether it shapes the array calibration grid (``grid``: part of that cache's key)."""
    meta = {"unit": unit, "doc": doc, "curve": curve, "low": low, "high": high,
            "low_open": low_open, "grid": grid}
    return field(default=default, metadata=meta)


@dataclass(frozen=True)
class PhysicsParams:
    """Geometry, material, module, optics, viscoelasticity and mesh of the sensor model.

    Axes: x across the 22 mm width, y through the depth (the photoreflector looks at the face
    y = +depth/2 from outside), z up from the fixed base to the top face the probe presses.
    """

    # --- skin geometry -------------------------------------------------------------------
    width: float = _f(0.022, "m", "skin body width (paper Sec. II-C: 22 mm)", low=0.0,
                      low_open=True)
    depth: float = _f(0.022, "m", "skin body depth (assumption: square section like the "
                      "22 mm width; the paper gives no number)", low=0.0, low_open=True)
    height: float = _f(0.030, "m", "skin body height (assumption chosen so the bonded "
                       "model gives the paper's ~7 N at 3 mm; see docs)", low=0.0,
                       low_open=True)
    # --- material (paper Table I, Mooney–Rivlin, Ecoflex 00-30) ---------------------------
    c10: float = _f(-3.335e1, "Pa", "Mooney–Rivlin C10 (paper Table I: -3.335e-5 MPa)")
    c01: float = _f(1.218e4, "Pa", "Mooney–Rivlin C01 (paper Table I: 1.218e-2 MPa)")
    bulk_ratio: float = _f(1000.0, "1", "bulk modulus / initial shear modulus (assumption: "
                           "nearly incompressible silicone, K = 1000 mu)", low=10.0)
    # --- load ------------------------------------------------------------------------------
    max_indentation: float = _f(0.003, "m", "largest probe indentation (paper Sec. III-B: "
                                "3 mm); 0 only for a pure shear load path", low=0.0)
    max_shear_x: float = _f(0.0, "m", "lateral probe displacement along +x at the end of "
                            "the load path, which runs linearly from zero to "
                            "(max_indentation, max_shear_x, max_shear_y); non-zero needs "
                            "the bonded boundary and solves the half or full model")
    max_shear_y: float = _f(0.0, "m", "the same along +y (toward the front face)")
    max_tilt_x: float = _f(0.0, "rad", "rotation of the probe about +x through its centre "
                           "(the top face's centre) at the end of the load path, right-hand "
                           "rule, growing linearly with the indentation; the probe's edge "
                           "may not lift: |tilt| x half the depth <= max_indentation; "
                           "non-zero needs the bonded boundary and spans the model in y",
                           low=-0.5, high=0.5)
    max_tilt_y: float = _f(0.0, "rad", "the same about +y (|tilt| x half the width <= "
                           "max_indentation; spans the model in x)", low=-0.5, high=0.5)
    max_twist_z: float = _f(0.0, "rad", "rotation of the probe about +z (its axis) through "
                            "its centre at the end of the load path, right-hand rule; "
                            "non-zero needs the bonded boundary and solves the full model",
                            low=-1.0, high=1.0)
    steps: int = _f(15, "1", "load steps from 0 to the end of the load path", low=1,
                    high=1000)
    boundary: str = _f("bonded", "-", "'bonded': base fixed, top bonded to the flat probe "
                       "(paper); 'frictionless': top and base slide (verification only, no "
                       "module)")
    # --- module (ABS, paper Table II E = 1.628 GPa >> skin: modelled as rigid) ---------------
    module_height: float = _f(0.006, "m", "height of the rigid ABS module band that holds "
                              "all four side faces from the base up and grips them (skin "
                              "under it does not move; a sliding grip made the skin fold "
                              "over the band edge); the low band and window near the fixed "
                              "base keep the bulge the photoreflector sees small (~0.26 mm at "
                              "3 mm), as the paper's 0.07 V/N implies; assumption; 0 = no "
                              "module", low=0.0)
    modules: str = _f("front", "-", "side faces that carry a module (a photoreflector "
                      "behind its own window), comma-separated, any of front (+y, the "
                      "paper's), back (-y), left (-x), right (+x), each optionally with the "
                      "window centre's offset along the face [m] as FACE@OFFSET (along +x "
                      "on front and back, +y on left and right; e.g. front@0.005, several "
                      "per face allowed); windows come in "
                      "opposite pairs (a module's window in one wall of the band and the "
                      "same window in the opposite wall, as the single-module model has "
                      "always assumed), so 'front' alone also opens the back wall")
    window_width: float = _f(0.009, "m", "width of the open window in a module's wall "
                             "through which the photoreflector looks (assumption; the "
                             "opposite wall is taken to have the same window, which makes the "
                             "model exactly symmetric front/back)",
                             low=0.0, low_open=True)
    window_height: float = _f(0.004, "m", "height of that window (assumption)", low=0.0,
                              low_open=True)
    window_center_z: float = _f(0.003, "m", "height of the window centre (= photoreflector "
                                "axis) above the fixed base (assumption)", low=0.0,
                                low_open=True)
    gap: float = _f(0.002, "m", "photoreflector-skin distance at rest (paper Sec. II-C: "
                    "~2 mm)", low=0.0, low_open=True)
    # --- optics (paper Sec. II-B, Fig. 3) -----------------------------------------------------
    pigment_white: float = _f(75.0, "%", "white share of the skin pigment (paper: 75 % "
                              "white / 25 % black chosen)", low=0.0, high=100.0)
    window_pigment_gradient: float = _f(0.0, "%", "change of the skin's pigment white share "
                                        "across the window's width under each window, in "
                                        "percentage points, increasing along the face's "
                                        "counter-clockwise tangent (front -x, right +y, back "
                                        "+x, left -y): skin sliding along the face then "
                                        "changes the light the photoreflector sees, so a "
                                        "twist reads at first order (docs/array.md); 0 = "
                                        "uniform pigment", low=0.0, high=100.0)
    supply_voltage: float = _f(5.0, "V", "photoreflector supply, the upper rail "
                               "(assumption: 5 V QTR-1A supply)", low=0.0, low_open=True)
    # --- viscoelastic rate term (does not change the elastic curve) ---------------------------
    prony_g: tuple[float, ...] = _f((0.05, 0.04), "1", "Prony relative moduli (assumption "
                                    "tuned to the paper's Fig. 9 speed effect)", curve=False)
    prony_tau: tuple[float, ...] = _f((0.1, 1.5), "s", "Prony relaxation times "
                                      "(assumption)", curve=False)
    output_play: float = _f(6.5e-5, "m", "indentation by which the bulge at the window "
                            "trails the probe on loading (play: the skin slides in the "
                            "module's grip first), so the output starts late by play / "
                            "speed; assumption: the paper's lags 0.005/0.062/0.706 s at "
                            "10/1/0.1 mm/s are 0.05-0.07 mm of indentation at every speed; "
                            "0.065 mm gives the analysis' onset lag ~0.06 s at 1 mm/s and "
                            "adds only ~2 % FS of hysteresis", curve=False, low=0.0,
                            high=0.001)
    # --- array calibration grid (physics/array_grid.py; not the curve) -----------------------
    array_steps: int = _f(6, "1", "indentation levels of the array calibration grid: load "
                          "steps of each of its load paths, up to max_indentation",
                          curve=False, grid=True, low=1, high=100)
    array_directions: int = _f(8, "1", "shear directions of the grid, evenly spaced from +x "
                               "toward +y (8: every 45 deg)", curve=False, grid=True, low=1,
                               high=72)
    array_shear_levels: int = _f(3, "1", "non-zero shear magnitudes per direction, evenly "
                                 "spaced up to array_shear_ratio x indentation",
                                 curve=False, grid=True, low=1, high=20)
    array_shear_ratio: float = _f(3.0, "1", "largest lateral probe displacement of the "
                                  "grid per unit indentation, where the skin starts to slide "
                                  "on the probe: static friction of silicone on a smooth "
                                  "probe mu ~ 0.5 (silicone rubber 0.25 to over 0.75, tacky "
                                  "Ecoflex ~1), and the FEM's lateral/normal force at this "
                                  "ratio is 0.43-0.57 over the indentations (docs/array.md)",
                                  curve=False, grid=True, low=0.0, low_open=True, high=10.0)
    array_mesh_scale: float = _f(0.5, "1", "elements per direction of the grid's mesh "
                                 "relative to mesh_nx/ny/nz, solved alone (a shear path on "
                                 "the full mesh took ~5 min; docs/array.md gives the error)",
                                 curve=False, grid=True, low=0.0, low_open=True, high=2.0)
    wrench_twist: float = _f(0.2, "rad", "probe twist about z of the wrench load paths "
                             "(physics/wrench.py, study metric wrench_observability); "
                             "assumption: a rotation whose edge displacement is of the "
                             "indentation's scale (0.2 rad moves the top's edge midpoints "
                             "2.2 mm) and small enough for the grid's coarse mesh",
                             curve=False, low=0.0, low_open=True, high=1.0)
    wrench_tilt: float = _f(0.1, "rad", "probe tilt about x and about y of the wrench load "
                            "paths; with max_indentation it must keep the probe's edge down "
                            "(tilt x half the width <= max_indentation: 0.1 rad lifts the "
                            "edge 1.1 mm of the 3 mm)", curve=False, low=0.0, low_open=True,
                            high=0.5)
    # --- mesh (quarter model, symmetric about x = 0 and y = 0) ------------------------------
    mesh_nx: int = _f(10, "1", "elements across the half width", low=1, high=200)
    mesh_ny: int = _f(10, "1", "elements across the half depth", low=1, high=200)
    mesh_nz: int = _f(26, "1", "elements along the height", low=2, high=400)
    mesh_grading: float = _f(6.0, "1", "ratio of largest to smallest element on each axis; "
                             "the smallest sit at the singular edges where the clamped "
                             "module meets the free window and at the band's and probe's "
                             "edges (1 = uniform; a uniform mesh left the window's bulge "
                             "11 % from converged)", low=1.0, high=20.0)
    mesh_grading_length: float = _f(0.004, "m", "distance from those edges over which "
                                    "elements grow from the smallest to the largest",
                                    low=0.0, low_open=True)
    mesh_extrapolation_order_force: float = _f(0.8, "1", "order p of the force's "
                                               "discretisation error, assumed when the sweep "
                                               "is Richardson-extrapolated from this mesh and "
                                               "one with half the elements per direction "
                                               "(benchmarks/bench_fem.py measured 0.70-0.89 "
                                               "over the sweep, from the edge singularities); "
                                               "0 = this mesh's force alone",
                                               low=0.0, high=4.0)
    mesh_extrapolation_order_bulge: float = _f(1.6, "1", "order p of the window bulge's "
                                               "discretisation error, assumed likewise "
                                               "(measured 1.56-1.65 over the sweep); 0 = this "
                                               "mesh's bulge alone (both 0: no half mesh)",
                                               low=0.0, high=4.0)

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            _check(f, getattr(self, f.name))
        if self.boundary not in BOUNDARIES:
            raise PhysicsError(f"Parameter 'boundary' is {self.boundary!r}; use one of "
                               f"{', '.join(BOUNDARIES)}.")
        if len(self.prony_g) != len(self.prony_tau):
            raise PhysicsError("Parameters 'prony_g' and 'prony_tau' have different lengths; "
                               "give one relaxation time per Prony modulus.")
        if any(t <= 0 for t in self.prony_tau) or any(g < 0 for g in self.prony_g):
            raise PhysicsError("Parameters 'prony_g' must be >= 0 and 'prony_tau' > 0; fix "
                               "the Prony series.")
        if self.c10 + self.c01 <= 0:
            raise PhysicsError("Parameters 'c10' + 'c01' must be positive (the shear "
                               "modulus 2(C10+C01) would be <= 0); fix the material.")
        modules = parse_modules(self.modules)
        # one spelling per set of modules, so equal sets compare and hash equal
        object.__setattr__(self, "modules", ",".join(label(f, c) for f, c in modules))
        shear = self.max_shear_x != 0 or self.max_shear_y != 0
        if self.max_indentation == 0 and not shear and not self.is_rotation:
            raise PhysicsError("The load path is zero (max_indentation, max_shear_x, "
                               "max_shear_y, max_tilt_x, max_tilt_y and max_twist_z all 0); "
                               "give an indentation, a shear or a rotation.")
        if shear and self.boundary != "bonded":
            raise PhysicsError("Parameters 'max_shear_x'/'max_shear_y' need the bonded "
                               "boundary (a frictionless probe cannot shear the skin); set "
                               "boundary to bonded.")
        if self.is_rotation and self.boundary != "bonded":
            raise PhysicsError("Parameters 'max_tilt_x'/'max_tilt_y'/'max_twist_z' need the "
                               "bonded boundary (a frictionless probe cannot turn the skin); "
                               "set boundary to bonded.")
        for name, half in (("max_tilt_x", self.depth / 2), ("max_tilt_y", self.width / 2)):
            lift = abs(getattr(self, name)) * half
            if lift > self.max_indentation * (1 + 1e-9):
                raise PhysicsError(f"Parameter {name!r} lifts the probe's edge {lift * 1e3:.3g}"
                                   f" mm, more than max_indentation "
                                   f"({self.max_indentation * 1e3:.3g} mm); tilt less or "
                                   "press deeper.")
        if self.max_indentation >= 0.6 * self.height:
            raise PhysicsError("Parameter 'max_indentation' exceeds 60 % of 'height'; "
                               "reduce it or make the skin taller.")
        if self.boundary == "bonded" and self.module_height > 0:
            top = self.window_center_z + self.window_height / 2
            bottom = self.window_center_z - self.window_height / 2
            if bottom <= 0 or top >= self.module_height:
                raise PhysicsError("The photoreflector window (window_center_z +- "
                                   "window_height/2) must lie inside the module band "
                                   "(0, module_height); move or shrink it.")
            if self.window_width >= min(self.width, self.depth):
                raise PhysicsError("Parameter 'window_width' must be smaller than 'width' "
                                   "and 'depth'.")
            self._check_windows()
            if self.module_height >= self.height - self.max_indentation:
                raise PhysicsError("Parameter 'module_height' reaches the probe; make it "
                                   "lower than height - max_indentation.")
        elif self.window_center_z >= self.height:
            raise PhysicsError("Parameter 'window_center_z' lies above the skin top; lower "
                               "it below 'height'.")

    def _check_windows(self) -> None:
        """Every window inside its face, and no two windows of a face overlapping."""
        ww = self.window_width
        for face, c in self.windows:
            half = self.face_half_width(face)
            if abs(c) + ww / 2 >= half:
                raise PhysicsError(f"The window of module {label(face, c)!r} reaches past its "
                                   f"face's edge (|offset| + window_width/2 must be < "
                                   f"{half * 1e3:.3g} mm); move it toward the centre or "
                                   "narrow the window.")
            for other, d in self.windows:
                if other == face and c < d < c + ww:
                    raise PhysicsError(f"The windows at {label(face, c)!r} and "
                                       f"{label(face, d)!r} overlap; space the offsets at "
                                       "least window_width apart.")

    # ------------------------------------------------------------------------------------------
    def face_half_width(self, face: str) -> float:
        """Half the face's extent along its horizontal axis (x on front/back, y on
        left/right) [m]."""
        return self.width / 2 if FACES[face][0] == 1 else self.depth / 2

    @property
    def shear_modulus(self) -> float:
        """Initial shear modulus mu = 2 (C10 + C01) [Pa]."""
        return 2.0 * (self.c10 + self.c01)

    @property
    def bulk_modulus(self) -> float:
        """Bulk modulus K = bulk_ratio * mu [Pa] of the volumetric penalty."""
        return self.bulk_ratio * self.shear_modulus

    @property
    def module_faces(self) -> tuple[str, ...]:
        """The modules' labels (a face, or FACE@OFFSET off the face's centre), in the fixed
        order front, back, left, right, then by offset."""
        return tuple(self.modules.split(","))

    @property
    def module_windows(self) -> tuple[tuple[str, float], ...]:
        """(face, offset [m]) of each module, in ``module_faces`` order."""
        return parse_modules(self.modules)

    @property
    def windows(self) -> tuple[tuple[str, float], ...]:
        """(face, offset) of every open window: the modules' and, at the same offset, their
        opposite walls', ordered by face then offset."""
        mods = self.module_windows
        found = set(mods) | {(OPPOSITE[f], c) for f, c in mods}
        return tuple(sorted(found, key=lambda w: (list(FACES).index(w[0]), w[1])))

    @property
    def window_faces(self) -> tuple[str, ...]:
        """Faces with an open window: the modules' and their opposite walls'."""
        faces = {f for f, _ in self.windows}
        return tuple(f for f in FACES if f in faces)

    @property
    def window_labels(self) -> tuple[str, ...]:
        """Labels of every open window (the modules a grid reads), as ``modules`` spells them."""
        return tuple(label(f, c) for f, c in self.windows)

    def mirror_symmetric(self, axis: int) -> bool:
        """Whether the windows are symmetric about the plane ``axis`` = 0 (x: 0, y: 1): a
        window on a face across that axis must have its mirror image at minus its offset."""
        windows = set(self.windows)
        return all((f, -c) in windows for f, c in windows if FACES[f][0] != axis)

    @property
    def is_shear(self) -> bool:
        return self.max_shear_x != 0 or self.max_shear_y != 0

    @property
    def is_rotation(self) -> bool:
        """Whether the load path turns the probe (tilt or twist)."""
        return self.max_tilt_x != 0 or self.max_tilt_y != 0 or self.max_twist_z != 0

    @classmethod
    def names(cls) -> list[str]:
        return [f.name for f in dataclasses.fields(cls)]

    @classmethod
    def describe(cls) -> dict[str, dict[str, Any]]:
        """Name -> {default, unit, doc} (for config files and --help)."""
        return {f.name: {"default": f.default, "unit": f.metadata["unit"],
                         "doc": f.metadata["doc"]} for f in dataclasses.fields(cls)}

    @classmethod
    def from_mapping(cls, values: Mapping[str, Any], *, ignore_unknown: bool = False
                     ) -> PhysicsParams:
        """Build from a name -> value mapping; unknown or invalid names raise PhysicsError."""
        known = {f.name: f for f in dataclasses.fields(cls)}
        kwargs: dict[str, Any] = {}
        for name, raw in values.items():
            if name not in known:
                if ignore_unknown:
                    continue
                raise PhysicsError(f"Unknown physics parameter {name!r}; known ones are "
                                   f"{', '.join(known)}.")
            kwargs[name] = _coerce(known[name], raw)
        return cls(**kwargs)

    def replace(self, **changes: Any) -> PhysicsParams:
        return PhysicsParams.from_mapping({**self.to_dict(), **changes})

    def to_dict(self) -> dict[str, Any]:
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}

    def digest(self) -> str:
        """Hash of every field that changes the prediction curve (plus the model version)."""
        curve = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)
                 if f.metadata["curve"]}
        if curve["boundary"] == "frictionless":
            # The module and window play no part without the module; keep one cache entry.
            for name in ("module_height", "window_width", "window_height"):
                curve.pop(name)
        for name, default in _LATER_FIELDS.items():
            # added after caches existed: at their default the curve is what it was
            if curve[name] == default:
                curve.pop(name)
        text = json.dumps({"model_version": MODEL_VERSION, **curve}, sort_keys=True)
        return hashlib.sha256(text.encode()).hexdigest()[:16]

    def grid_digest(self) -> str:
        """Hash of everything that changes the array calibration grid (curve and grid)."""
        grid = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)
                if f.metadata["grid"]}
        text = json.dumps({"curve": self.digest(), **grid}, sort_keys=True)
        return hashlib.sha256(text.encode()).hexdigest()[:16]


#: Curve fields added after prediction caches existed, with the defaults that keep them valid.
_LATER_FIELDS: dict[str, Any] = {"max_shear_x": 0.0, "max_shear_y": 0.0, "modules": "front",
                                 "max_tilt_x": 0.0, "max_tilt_y": 0.0, "max_twist_z": 0.0,
                                 "window_pigment_gradient": 0.0}


def label(face: str, offset: float) -> str:
    """A module's name: its face, with ``@offset`` [m] when off the face's centre."""
    return face if offset == 0 else f"{face}@{offset:.6g}"


def parse_modules(text: str) -> tuple[tuple[str, float], ...]:
    """(face, offset [m]) of each entry of a ``modules`` string, sorted by face then offset;
    one sentence on a bad entry."""
    out: list[tuple[str, float]] = []
    for item in (t.strip() for t in text.split(",")):
        if not item:
            continue
        face, _, offset = item.partition("@")
        try:
            c = float(offset) if offset.strip() else 0.0
        except ValueError:
            c = math.nan
        if face.strip() not in FACES or not math.isfinite(c) or (_ and not offset.strip()):
            out = []
            break
        out.append((face.strip(), c + 0.0))          # + 0.0: no -0.0
    if not out or len(set(out)) != len(out):
        raise PhysicsError(f"Parameter 'modules' is {text!r}; give distinct faces out of "
                           f"{', '.join(FACES)}, comma-separated, each optionally FACE@OFFSET "
                           "with the window's offset along the face in m (e.g. "
                           "front@0.005).")
    return tuple(sorted(out, key=lambda w: (list(FACES).index(w[0]), w[1])))


def _coerce(f: dataclasses.Field[Any], raw: Any) -> Any:
    """Convert a config/CLI value to the field's type, or raise naming the parameter."""
    name = f.name
    default = f.default
    try:
        if isinstance(default, bool):
            raise TypeError
        if isinstance(default, tuple):
            if isinstance(raw, str):
                raw = [p for p in raw.replace("[", "").replace("]", "").split(",") if p.strip()]
            return tuple(float(v) for v in raw)
        if isinstance(default, int):
            if isinstance(raw, bool):
                raise TypeError
            value = float(raw)
            if not value.is_integer():
                raise ValueError
            return int(value)
        if isinstance(default, float):
            if isinstance(raw, bool):
                raise TypeError
            return float(raw)
        if isinstance(raw, list | tuple):  # a YAML list of names, e.g. modules: [front, back]
            return ",".join(str(v) for v in raw)
        return str(raw)
    except (TypeError, ValueError):
        kind = type(default).__name__ if not isinstance(default, tuple) else "list of numbers"
        raise PhysicsError(f"Parameter {name!r} must be a {kind}, got {raw!r}; give a "
                           f"value in {f.metadata['unit']}.") from None


def _check(f: dataclasses.Field[Any], value: Any) -> None:
    """Bounds and finiteness of one field."""
    meta = f.metadata
    values = value if isinstance(value, tuple) else (value,)
    for v in values:
        if isinstance(v, str):
            continue
        if not isinstance(v, int | float) or isinstance(v, bool) or not math.isfinite(v):
            raise PhysicsError(f"Parameter {f.name!r} must be a finite number, got {v!r}.")
        low, high = meta["low"], meta["high"]
        if low is not None and (v < low or (meta["low_open"] and v <= low)):
            op = ">" if meta["low_open"] else ">="
            raise PhysicsError(f"Parameter {f.name!r} is {v!r} but must be {op} {low} "
                               f"{meta['unit']}.")
        if high is not None and v > high:
            raise PhysicsError(f"Parameter {f.name!r} is {v!r} but must be <= {high} "
                               f"{meta['unit']}.")
