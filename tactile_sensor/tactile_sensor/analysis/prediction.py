"""The model's predicted output against indentation (paper Fig. 7(b)), from a file or physics.

Optional by design: the analysis runs without the physics layer, and reports null
with the reason when no prediction is available.
"""

from __future__ import annotations

import json
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import PredictionFileError


@dataclass(frozen=True)
class Prediction:
    indentation_m: np.ndarray
    output_v: np.ndarray
    source: str


def load_prediction_file(path: Path | str) -> Prediction:
    """The JSON of 'tactile-sensor model sweep --json' (keys indentation_m, output_v)."""
    path = Path(path)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except OSError as err:
        raise PredictionFileError(f"cannot read the prediction file {path} ({err.strerror}); "
                                  "pass an existing file, 'auto' or 'none'.") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as err:
        raise PredictionFileError(f"the prediction file {path} is not valid JSON ({err}); "
                                  "write it with 'tactile-sensor model sweep --json'.") from None
    arrays = []
    for key in ("indentation_m", "output_v"):
        value = data.get(key) if isinstance(data, dict) else None
        try:
            arr = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            arr = np.zeros(0)
        if arr.ndim != 1 or arr.size < 2 or not np.all(np.isfinite(arr)):
            raise PredictionFileError(f"the prediction file {path} needs \"{key}\" as a list "
                                      "of at least two finite numbers; write it with "
                                      "'tactile-sensor model sweep --json'.")
        arrays.append(arr)
    d, out = arrays
    if d.size != out.size or np.any(np.diff(d) <= 0):
        raise PredictionFileError(f"the prediction file {path} needs indentation_m strictly "
                                  "increasing and as long as output_v; regenerate it.")
    return Prediction(d, out, str(path))


def physics_prediction(verbose: bool = True) -> tuple[Prediction | None, str]:
    """Default-parameter curve from the physics layer (cached), or None and the reason."""
    try:
        from tactile_sensor.physics.params import PhysicsParams
        from tactile_sensor.physics.prediction import load_or_compute_curve
    except ImportError as err:
        return None, f"physics layer unavailable ({err})"
    try:
        from tactile_sensor.physics.errors import PhysicsError
    except ImportError:  # pragma: no cover - depends on the physics layer's state
        PhysicsError = RuntimeError

    shown = []

    def progress(fraction: float, message: str) -> None:
        if verbose:
            shown.append(fraction)
            print(f"\rmodel prediction: {100 * fraction:3.0f}% {message}"[:79],
                  end="", file=sys.stderr, flush=True)

    try:
        curve = load_or_compute_curve(PhysicsParams(), progress=progress)
    except (PhysicsError, RuntimeError, ValueError, OSError) as err:
        return None, f"physics prediction failed ({err})"
    finally:
        if shown:
            print(file=sys.stderr)
    d = np.asarray(curve.indentation_m, dtype=float)
    out = np.asarray(curve.output_v, dtype=float)
    return Prediction(d, out, f"physics default parameters ({getattr(curve, 'digest', '')})"), ""
