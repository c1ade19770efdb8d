"""The synthetic press recording the analysis tests share (conftest.py puts this folder on
``sys.path``)."""

from __future__ import annotations

from tactile_sensor.analysis.synthetic import PressProtocol

#: Four presses at 10 mm/s sampled at 200 Hz, half a second of hold and of rest: a few
#: seconds of recording, quick to write and to analyse.
FOUR_PRESSES = PressProtocol(speeds_mm_s=(10.0,), cycles=(4,), rate_hz=200.0, rest_s=0.5,
                             hold_s=0.5)
