"""A design study's SPEC file: what to vary, how to pick designs, what to measure.

YAML (``config/studies/*.yaml``)::

    name: window and band placement       # free text, titles the report
    fixed: {mesh_nx: 6}                   # physics parameters every design shares (SI)
    vary:                                 # physics parameters that change between designs
      module_height: {from: 0.006, to: 0.014, count: 3}   # a range [m] ...
      window_center_z: [0.003, 0.007]                     # ... or a list of values
    design: grid                          # every combination, or a quasi-random sample:
    # design: {sample: sobol, points: 16, seed: 1}        # (sobol or halton, seeded)
    # design: zip                         # or the i-th value of every list together
    metrics: [sensitivity, full_scale, linearity, dynamic_range, sensitivity_matrix]
    # (or wrench_observability: which of Fx, Fy, Fz, Tx, Ty, Tz the layout resolves)
    noise_v: 0.013                        # [V] output noise: dynamic range, wrench threshold
    # bandwidth_hz: 10                    # [Hz] or the noise a 2nd-order low-pass at this
    # sample_noise_v: 0.039               # cutoff leaves of white samples of this sigma [V]
    # sample_rate_hz: 1000                # at this rate (physics/output_noise.py)
    # board: nano                         # analog inputs: uno 6, nano 8, leonardo 12, mega 16
                                          # (also in vary: a list of boards)
    objectives: {sensitivity_v_per_n: max, full_scale_n: max}   # for the Pareto front

The paper's design is the defaults with ``fixed`` applied; every study solves it too, as the
reference its designs are compared with. Parsing is pure: a bad spec raises one
:class:`StudySpecError` sentence naming the key and the fix.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
import warnings
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from tactile_sensor.physics.errors import PhysicsError
from tactile_sensor.physics.output_noise import SAMPLE_NOISE_V, SAMPLE_RATE_HZ, noise_at_bandwidth
from tactile_sensor.physics.params import FACES, PhysicsParams
from tactile_sensor.physics.yaml_file import read_yaml

from .metrics import WRENCH_COLUMNS

#: Metric name in a spec -> the table columns it adds (units in the names).
SINGLE_METRICS = {"sensitivity": "sensitivity_v_per_n", "full_scale": "full_scale_n",
                  "linearity": "linearity_pct_fs", "dynamic_range": "dynamic_range_db"}
MATRIX_METRIC = "sensitivity_matrix"
MATRIX_COLUMNS = ("condition_number", "crosstalk", "shear_sensitivity_v_per_n",
                  "singular_value_1_v_per_n", "singular_value_2_v_per_n",
                  "singular_value_3_v_per_n",
                  *(f"s_{face}_{axis}_v_per_n" for face in FACES for axis in ("fx", "fy", "fz")))
#: Which of the six wrench components a layout resolves (physics/wrench.py).
WRENCH_METRIC = "wrench_observability"
METRICS = (*SINGLE_METRICS, MATRIX_METRIC, WRENCH_METRIC)
SAMPLERS = ("grid", "zip", "sobol", "halton")
#: The paper's resolution after its 9-point mean (0.186 N x 0.07 V/N): 31.5 dB at 7 N.
DEFAULT_NOISE_V = 0.013
#: A study larger than this is a typo more often than a plan (each design costs seconds).
MAX_DESIGNS = 5000
KEYS = ("name", "fixed", "vary", "design", "metrics", "noise_v", "bandwidth_hz",
        "sample_noise_v", "sample_rate_hz", "board", "objectives")
#: Arduino boards and their analog input channels (Uno A0-A5, Nano A0-A7, Leonardo A0-A5
#: plus A6-A11 on digital pins, Mega 2560 A0-A15): one module per channel.
BOARDS = {"uno": 6, "nano": 8, "leonardo": 12, "mega": 16}
#: A varied name that is not a physics parameter: the board the modules are wired to.
BOARD = "board"


class StudySpecError(PhysicsError):
    """A SPEC file that cannot describe a study (unknown key or parameter, empty range...)."""


@dataclass(frozen=True)
class Range:
    """``count`` evenly spaced values from ``start`` to ``stop`` (for a sample: the span)."""

    start: float
    stop: float
    count: int | None

    def values(self) -> list[float]:
        n = self.count or 1
        if n == 1:
            return [self.start]
        return [self.start + (self.stop - self.start) * i / (n - 1) for i in range(n)]


@dataclass(frozen=True)
class StudySpec:
    """A parsed SPEC; ``designs()`` lists the varied values of every design."""

    name: str
    vary: dict[str, Range | tuple[Any, ...]]
    sampler: str = "grid"
    points: int = 0
    seed: int = 0
    fixed: dict[str, Any] = dataclasses.field(default_factory=dict)
    metrics: tuple[str, ...] = tuple(SINGLE_METRICS)
    noise_v: float = DEFAULT_NOISE_V
    objectives: dict[str, str] = dataclasses.field(default_factory=dict)
    bandwidth_hz: float | None = None
    sample_noise_v: float = SAMPLE_NOISE_V
    sample_rate_hz: float = SAMPLE_RATE_HZ
    board: str | None = None

    @property
    def output_noise_v(self) -> float:
        """The module noise the metrics use [V]: ``noise_v``, or with ``bandwidth_hz`` what
        the driver's low-pass leaves of the sample noise at that bandwidth."""
        if self.bandwidth_hz is None:
            return self.noise_v
        return noise_at_bandwidth(self.bandwidth_hz, self.sample_noise_v, self.sample_rate_hz)

    @property
    def varied(self) -> tuple[str, ...]:
        return tuple(self.vary)

    @property
    def columns(self) -> tuple[str, ...]:
        """Metric columns of the table, in spec order."""
        out = [SINGLE_METRICS[m] for m in self.metrics if m in SINGLE_METRICS]
        out += list(MATRIX_COLUMNS) if MATRIX_METRIC in self.metrics else []
        return tuple(out + (list(WRENCH_COLUMNS) if WRENCH_METRIC in self.metrics else []))

    def reference(self) -> dict[str, Any]:
        """The paper's design: the defaults with ``fixed`` applied."""
        return dict(self.fixed)

    def designs(self) -> list[dict[str, Any]]:
        """Each design's varied values (grid: every combination; sample: ``points``)."""
        names = self.varied
        if self.sampler == "zip":
            axes = [v.values() if isinstance(v, Range) else list(v) for v in self.vary.values()]
            return [_typed(dict(zip(names, combo, strict=True)))
                    for combo in zip(*axes, strict=True)]
        if self.sampler == "grid":
            axes = [v.values() if isinstance(v, Range) else list(v) for v in self.vary.values()]
            return [_typed(dict(zip(names, combo, strict=True)))
                    for combo in itertools.product(*axes)]
        from scipy.stats import qmc

        engine = (qmc.Sobol(len(names), scramble=True, seed=self.seed) if self.sampler ==
                  "sobol" else qmc.Halton(len(names), scramble=True, seed=self.seed))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")   # Sobol prefers 2^m points; any count is fine
            units = engine.random(self.points)
        designs = []
        for row in units:
            values: dict[str, Any] = {}
            for name, u in zip(names, row, strict=True):
                axis = self.vary[name]
                if isinstance(axis, Range):
                    values[name] = axis.start + (axis.stop - axis.start) * float(u)
                else:
                    values[name] = axis[min(len(axis) - 1, int(u * len(axis)))]
            designs.append(_typed(values))
        return designs


_FIELDS = {f.name: f for f in dataclasses.fields(PhysicsParams)}


def _typed(values: dict[str, Any]) -> dict[str, Any]:
    """Integer parameters (mesh, steps) rounded; floats rounded to 12 digits, so a range's
    0.1 + 0.2 does not give a design (and a cache entry) of its own."""
    out = {}
    for name, v in values.items():
        if name == BOARD:
            out[name] = v
            continue
        default = _FIELDS[name].default
        if isinstance(default, int) and not isinstance(default, bool) and \
                isinstance(v, int | float):
            v = round(v)
        elif isinstance(v, float):
            v = float(f"{v:.12g}")
        out[name] = v
    return out


def load_spec(path: Path) -> StudySpec:
    """Read and parse a SPEC file (one sentence on any problem)."""
    data = read_yaml(path, "the study spec", StudySpecError,
                     ", e.g. config/studies/window_placement.yaml")
    return parse_spec(data, name=path.stem)


def parse_spec(data: Any, name: str = "study") -> StudySpec:
    """A spec from its YAML data (mapping); see the module docstring for the keys."""
    if not isinstance(data, Mapping):
        raise StudySpecError("a study spec must be a YAML mapping with at least 'vary'; see "
                             "config/studies/ for examples.")
    unknown = [str(k) for k in data if k not in KEYS]
    if unknown:
        raise StudySpecError(f"the study spec has unknown key {unknown[0]!r}; use "
                             f"{', '.join(KEYS)}.")
    fixed = _parameters(data.get("fixed") or {}, "fixed")
    vary_data = data.get("vary")
    if not isinstance(vary_data, Mapping) or not vary_data:
        raise StudySpecError("the study spec needs 'vary': a mapping of physics parameters "
                             "to lists of values or ranges {from, to, count}.")
    sampler, points, seed = _sampler(data.get("design", "grid"))
    vary = {str(k): _axis(str(k), v, sampler) for k, v in _parameters(vary_data,
                                                                      "vary").items()}
    both = sorted(set(vary) & set(fixed))
    if both:
        raise StudySpecError(f"parameter {both[0]!r} is both fixed and varied; drop it from "
                             "one of them.")
    metrics = data.get("metrics", list(SINGLE_METRICS))
    if isinstance(metrics, str):
        metrics = [metrics]
    if not isinstance(metrics, list) or not metrics or any(m not in METRICS for m in metrics):
        bad = next((m for m in metrics if m not in METRICS), metrics) \
            if isinstance(metrics, list) and metrics else metrics
        raise StudySpecError(f"the study spec's metric {bad!r} is unknown; choose from "
                             f"{', '.join(METRICS)}.")
    noise = data.get("noise_v", DEFAULT_NOISE_V)
    if isinstance(noise, bool) or not isinstance(noise, int | float) or not \
            math.isfinite(noise) or noise <= 0:
        raise StudySpecError(f"'noise_v' is {noise!r}; give the output noise as a positive "
                             "number of volts, e.g. 0.013.")
    extra = _noise_keys(data)
    board = data.get("board")
    if board is not None:
        _board(board, "board")
        if BOARD in vary:
            raise StudySpecError("'board' is both given and varied; drop it from one of "
                                 "them.")
    try:
        PhysicsParams.from_mapping(fixed)
    except PhysicsError as err:
        raise StudySpecError(f"the study's fixed parameters are rejected ({err}); fix "
                             "'fixed'.") from None
    spec = StudySpec(name=str(data.get("name") or name), vary=vary, sampler=sampler,
                     points=points, seed=seed, fixed=fixed,
                     metrics=tuple(dict.fromkeys(metrics)), noise_v=float(noise),
                     board=board, **extra)
    objectives = _objectives(data.get("objectives"), spec.columns)
    spec = dataclasses.replace(spec, objectives=objectives)
    lengths = [len(v.values()) if isinstance(v, Range) else len(v) for v in vary.values()]
    if sampler == "zip" and len(set(lengths)) > 1:
        raise StudySpecError(f"'design: zip' takes the i-th value of every list together, "
                             f"but 'vary' holds lists of {sorted(set(lengths))} values; give "
                             "every list (or range count) the same length.")
    count = points if sampler not in ("grid", "zip") else lengths[0] if sampler == "zip" \
        else math.prod(lengths)
    if count > MAX_DESIGNS:
        raise StudySpecError(f"the study has {count} designs, more than {MAX_DESIGNS}; "
                             "narrow 'vary' or sample fewer points.")
    return spec


def _noise_keys(data: Mapping[str, Any]) -> dict[str, float]:
    """``bandwidth_hz``, ``sample_noise_v`` and ``sample_rate_hz`` where given, checked."""
    out: dict[str, float] = {}
    for key, unit in (("bandwidth_hz", "Hz"), ("sample_noise_v", "V"),
                      ("sample_rate_hz", "Hz")):
        value = data.get(key)
        if value is None:
            continue
        if isinstance(value, bool) or not isinstance(value, int | float) or not \
                math.isfinite(value) or value <= 0:
            raise StudySpecError(f"'{key}' is {value!r}; give a positive number of {unit}.")
        out[key] = float(value)
    if "bandwidth_hz" in out:
        try:
            noise_at_bandwidth(out["bandwidth_hz"], out.get("sample_noise_v", SAMPLE_NOISE_V),
                               out.get("sample_rate_hz", SAMPLE_RATE_HZ))
        except PhysicsError as err:
            raise StudySpecError(f"'bandwidth_hz' is rejected: {err}") from None
    return out


def _board(value: Any, key: str) -> int:
    """The analog channel count of a board name (one sentence on an unknown board)."""
    if not isinstance(value, str) or value.lower() not in BOARDS:
        raise StudySpecError(f"'{key}' is {value!r}; name a board out of "
                             f"{', '.join(f'{b} ({n} channels)' for b, n in BOARDS.items())}.")
    return BOARDS[value.lower()]


def board_refusal(board: str | None, params: PhysicsParams) -> str:
    """Why ``params``' layout cannot be wired to ``board`` (empty when it can)."""
    if board is None:
        return ""
    channels = _board(board, "board")
    needed = len(params.module_faces)
    if needed <= channels:
        return ""
    return (f"The layout needs {needed} modules but board {board!r} has {channels} analog "
            f"channels; use fewer modules or a board with at least {needed}.")


def _parameters(section: Any, key: str) -> dict[str, Any]:
    if not isinstance(section, Mapping):
        raise StudySpecError(f"'{key}' must map physics parameter names to values.")
    for name in section:
        if key == "vary" and name == BOARD:
            continue
        if name not in _FIELDS:
            raise StudySpecError(f"'{key}' names an unknown physics parameter {name!r}; "
                                 f"known ones are {', '.join(_FIELDS)}.")
    return {str(k): v for k, v in section.items()}


def _sampler(design: Any) -> tuple[str, int, int]:
    if design in ("grid", "zip"):
        return str(design), 0, 0
    if not isinstance(design, Mapping) or set(design) - {"sample", "points", "seed"} or \
            design.get("sample") not in SAMPLERS[2:]:
        raise StudySpecError(f"'design' is {design!r}; use 'grid', 'zip' or {{sample: "
                             "sobol|halton, points: N, seed: S}.")
    points, seed = design.get("points"), design.get("seed", 0)
    if isinstance(points, bool) or not isinstance(points, int) or points < 1:
        raise StudySpecError(f"'design: points' is {points!r}; give the number of designs "
                             "to sample, a whole number >= 1.")
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise StudySpecError(f"'design: seed' is {seed!r}; give a whole number >= 0 so the "
                             "sample repeats.")
    return str(design["sample"]), points, seed


def _axis(name: str, value: Any, sampler: str) -> Range | tuple[Any, ...]:
    """A list of values or a range {from, to, count}; each value checked alone."""
    if isinstance(value, list):
        if not value:
            raise StudySpecError(f"'vary: {name}' is an empty list; give at least one "
                                 "value.")
        values = tuple(value)
    elif isinstance(value, Mapping):
        if set(value) - {"from", "to", "count"} or "from" not in value or "to" not in value:
            raise StudySpecError(f"'vary: {name}' must be a list or {{from, to, count}}; fix "
                                 "its keys.")
        start, stop, count = value["from"], value["to"], value.get("count")
        if any(isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v)
               for v in (start, stop)):
            raise StudySpecError(f"'vary: {name}' needs numbers for 'from' and 'to'; give "
                                 "them in SI units.")
        if count is None and sampler in ("grid", "zip"):
            raise StudySpecError(f"'vary: {name}' needs 'count' for a grid; give how many "
                                 "values the range holds.")
        if count is not None and (isinstance(count, bool) or not isinstance(count, int)
                                  or count < 1):
            raise StudySpecError(f"'vary: {name}' has count {count!r}, an empty range; give "
                                 "a whole number >= 1.")
        if count is not None and count > 1 and start == stop:
            raise StudySpecError(f"'vary: {name}' runs from {start} to the same value; "
                                 "widen it or list the one value.")
        axis: Range | tuple[Any, ...] = Range(float(start), float(stop), count)
        values = (float(start), float(stop))
    else:
        raise StudySpecError(f"'vary: {name}' must be a list of values or a range {{from, to, "
                             "count}}.")
    if name == BOARD:
        for v in values:
            _board(v, "vary: board")
        return values
    for v in values:
        try:
            PhysicsParams.from_mapping({name: v})
        except PhysicsError as err:
            if "must be" in str(err) and ("finite" in str(err) or "give a value" in str(err)):
                raise StudySpecError(f"'vary: {name}' holds {v!r}: {err}") from None
    return axis if isinstance(value, Mapping) else values


def _objectives(data: Any, columns: tuple[str, ...]) -> dict[str, str]:
    """Metric column -> 'max' or 'min'; default: sensitivity and full scale, both max."""
    if data is None:
        default = {"sensitivity_v_per_n": "max", "full_scale_n": "max"}
        picked = {k: v for k, v in default.items() if k in columns}
        return picked or {columns[0]: "max"}
    if not isinstance(data, Mapping) or not data:
        raise StudySpecError("'objectives' must map metric columns to max or min, e.g. "
                             "{sensitivity_v_per_n: max}.")
    for k, v in data.items():
        if k not in columns:
            raise StudySpecError(f"objective {k!r} is not a metric column of this study; "
                                 f"choose from {', '.join(columns)}.")
        if v not in ("max", "min"):
            raise StudySpecError(f"objective {k!r} is {v!r}; say max or min.")
    return {str(k): str(v) for k, v in data.items()}
