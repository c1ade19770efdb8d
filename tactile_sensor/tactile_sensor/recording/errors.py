"""The recording layer's one exception type."""

from __future__ import annotations


class RecordingError(Exception):
    """A bag cannot be written as asked; the message names the cause and the fix."""
