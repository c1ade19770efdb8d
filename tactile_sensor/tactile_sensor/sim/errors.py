"""Faults of the mock devices that a user can cause (bad link path, bad option)."""

from __future__ import annotations


class SimError(Exception):
    """Base of every mock-hardware error; the message names the cause and the fix."""
