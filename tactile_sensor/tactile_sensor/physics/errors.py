"""Errors a user of the physics layer can cause, each with one sentence naming cause and fix."""

from __future__ import annotations


class PhysicsError(Exception):
    """Base of every physics-layer error a user can cause (bad parameter, bad file, ...)."""


class OutOfRangeError(PhysicsError, ValueError):
    """A query outside the range the prediction curve was computed for."""


class ConvergenceError(PhysicsError):
    """The finite-element Newton solve did not converge (usually a too-coarse load step)."""
