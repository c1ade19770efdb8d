"""Make the source tree importable so tests exercise the code under review."""

from __future__ import annotations

import sys
from pathlib import Path

SOURCE = Path(__file__).resolve().parent / "tactile_sensor"
if str(SOURCE) not in sys.path:
    sys.path.insert(0, str(SOURCE))

# Import the real package now: pytest's importlib mode would otherwise register an empty
# namespace module 'tactile_sensor' (named after the folder holding the tests) first.
import tactile_sensor  # noqa: E402, F401
