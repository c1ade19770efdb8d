"""Errors of the signal chain a user can cause; each message names the cause and the fix."""

from __future__ import annotations


class SensingError(Exception):
    """Base of every sensing-layer error (bad configuration, bad filter parameters)."""


class CalibrationError(SensingError):
    """A calibration curve or file is missing, corrupt, or not monotone."""


class TareError(SensingError):
    """A tare was refused (sensor not at rest, or too few samples yet)."""


class ParameterConflict(SensingError):
    """Driver parameters that are each valid but contradict each other."""
