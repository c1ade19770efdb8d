"""Module output [V] → force [N] by linear interpolation in a monotone curve.

The curve comes either from the model node (the FEM prediction, latched) or from a JSON
file written by the analysis tools (format in docs/CONTRACTS.md). ``source`` says which,
so the driver can report it. Outputs beyond the last point clamp to the last force and
are flagged ``saturated``; outputs below the first clamp to the first force (noise around
zero must not become negative force).
"""

from __future__ import annotations

import bisect
import itertools
import json
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, Protocol

from tactile_sensor.sensing.errors import CalibrationError

FILE_FORMAT = "tactile_sensor/calibration"
FILE_VERSION = 3  # the newest version this reader takes: 2 adds ``rate_terms``, 3 ``play``
STATIC_FILE_VERSION = 1  # a curve without rate terms is written as 1: older readers take it
RATE_FILE_VERSION = 2  # rate terms without play: version-2 readers take it


class CurveLike(Protocol):
    """What ``from_prediction_curve`` needs of physics' ``PredictionCurve``."""

    digest: str

    def calibration(self) -> tuple[Any, Any]: ...


class Calibration:
    """An immutable, validated output→force curve."""

    def __init__(self, output_v: Sequence[float], force_n: Sequence[float], source: str) -> None:
        out = [float(v) for v in output_v]
        force = [float(f) for f in force_n]
        where = source or "the calibration"
        if len(out) != len(force):
            raise CalibrationError(f"{where}: output_v has {len(out)} points but force_n has "
                                   f"{len(force)}; they must pair up.")
        if len(out) < 2:
            raise CalibrationError(f"{where}: a calibration needs at least 2 points, got "
                                   f"{len(out)}.")
        if not all(math.isfinite(v) for v in out + force):
            raise CalibrationError(f"{where}: contains NaN or infinite values; refit it.")
        if any(b <= a for a, b in itertools.pairwise(out)):
            raise CalibrationError(f"{where}: output_v must be strictly increasing; refit the "
                                   "curve or drop repeated points.")
        if any(b < a for a, b in itertools.pairwise(force)):
            raise CalibrationError(f"{where}: force_n must be non-decreasing; refit the curve.")
        self._out = out
        self._force = force
        self.source = str(source)

    @property
    def output_v(self) -> tuple[float, ...]:
        return tuple(self._out)

    @property
    def force_n(self) -> tuple[float, ...]:
        return tuple(self._force)

    @property
    def max_output_v(self) -> float:
        return self._out[-1]

    @property
    def full_scale_force_n(self) -> float:
        """The most force this curve can report [N]: its last point, since every output
        beyond it clamps there (a gripper must not ask for more than it can see)."""
        return self._force[-1]

    def evaluate(self, output_v: float) -> tuple[float, bool]:
        """(force [N], saturated); saturated means the output is beyond the curve's end."""
        out, force = self._out, self._force
        if output_v >= out[-1]:
            return force[-1], output_v > out[-1]
        if output_v <= out[0]:
            return force[0], False
        if output_v != output_v:  # NaN in, NaN out
            return output_v, False
        k = bisect.bisect_right(out, output_v)
        x0, x1 = out[k - 1], out[k]
        f0, f1 = force[k - 1], force[k]
        return f0 + (f1 - f0) * (output_v - x0) / (x1 - x0), False

    def force(self, output_v: float) -> float:
        return self.evaluate(output_v)[0]

    # -- construction ----------------------------------------------------------------------

    @classmethod
    def from_curve(cls, output_v: Sequence[float], force_n: Sequence[float],
                   source: str) -> Calibration:
        """From arrays, e.g. the model node's latched CalibrationCurve message."""
        return cls(output_v, force_n, source)

    @classmethod
    def from_prediction_curve(cls, curve: CurveLike) -> Calibration:
        """From physics' PredictionCurve; the source names the parameter digest."""
        output_v, force_n = curve.calibration()
        return cls(list(output_v), list(force_n), f"fem:{curve.digest}")

    @classmethod
    def from_mapping(cls, data: Mapping[str, Any], source: str) -> Calibration:
        if not isinstance(data, Mapping):
            raise CalibrationError(f"{source}: expected a JSON object, got {type(data).__name__}.")
        if data.get("format") != FILE_FORMAT:
            raise CalibrationError(f"{source}: 'format' must be \"{FILE_FORMAT}\"; this is not "
                                   "a calibration file.")
        check_version(data, source)
        if data.get("rate_terms") or data.get("play"):
            raise CalibrationError(f"{source}: holds rate terms or play, which a static curve "
                                   "would drop; load it with sensing.rate_calibration.load_file.")
        missing = [k for k in ("output_v", "force_n") if not isinstance(data.get(k), list)]
        if missing:
            raise CalibrationError(f"{source}: missing array(s) {', '.join(missing)}.")
        try:
            return cls(data["output_v"], data["force_n"], source)
        except (TypeError, ValueError):
            raise CalibrationError(f"{source}: output_v and force_n must hold numbers.") from None

    @classmethod
    def from_file(cls, path: Path | str) -> Calibration:
        """Load a calibration JSON; the source is ``file:<path>`` plus the file's own note."""
        path = Path(path)
        data = read_json_file(path, "Calibration file", "run the analysis to write one",
                              "rewrite it with the analysis tools")
        cal = cls.from_mapping(data, f"file:{path}")
        cal.source = file_source(path, data)
        return cal

    def to_dict(self, fit: Mapping[str, Any] | None = None) -> dict[str, Any]:
        out: dict[str, Any] = {"format": FILE_FORMAT, "version": STATIC_FILE_VERSION,
                               "output_v": list(self._out), "force_n": list(self._force),
                               "source": self.source}
        if fit is not None:
            out["fit"] = dict(fit)
        return out

    def to_file(self, path: Path | str, fit: Mapping[str, Any] | None = None) -> None:
        Path(path).write_text(json.dumps(self.to_dict(fit), indent=1) + "\n", encoding="utf-8")

    def __repr__(self) -> str:
        return (f"Calibration({len(self._out)} points, output 0..{self._out[-1]:.3f} V, "
                f"source={self.source!r})")


def check_version(data: Mapping[str, Any], source: str) -> int:
    """The file's version if this reader takes it (1 to 3), else one sentence: a newer file
    needs a newer tactile_sensor, refitting would not help."""
    version = data.get("version")
    if isinstance(version, bool) or not isinstance(version, int) or version < 1:
        raise CalibrationError(f"{source}: calibration file version {version!r} is not a "
                               f"version (1..{FILE_VERSION}); refit it.")
    if version > FILE_VERSION:
        raise CalibrationError(f"{source}: calibration file version {version} is newer than "
                               f"this tactile_sensor reads (up to {FILE_VERSION}); update "
                               "tactile_sensor.")
    return version


def read_json_file(path: Path, label: str, write_hint: str, rewrite_hint: str) -> Any:
    """A calibration file's JSON, or a CalibrationError naming the file and the fix."""
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise CalibrationError(f"{label} {path} does not exist; fix the path or "
                               f"{write_hint}.") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise CalibrationError(f"Cannot read {label[0].lower()}{label[1:]} {path} ({exc}); "
                               "check the file's permissions.") from None
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise CalibrationError(f"{label} {path} is not valid JSON (line {exc.lineno}); "
                               f"{rewrite_hint}.") from None


def file_source(path: Path, data: Any) -> str:
    """``file:<path>``, plus the file's own ``source`` note when it has one."""
    note = data.get("source") if isinstance(data, Mapping) else None
    return f"file:{path} ({note})" if isinstance(note, str) and note else f"file:{path}"
