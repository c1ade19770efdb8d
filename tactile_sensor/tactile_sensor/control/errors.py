"""Requests a user can get wrong (speed, force, opening out of range)."""

from __future__ import annotations


class ControlError(Exception):
    """Base of the control layer's errors; the message names the cause and the fix."""


class InvalidRequest(ControlError):
    """A grasp or release request that cannot be executed as given."""


class InvalidConfiguration(ControlError):
    """Gripper settings that contradict each other (the message names the parameters)."""
