"""Errors a user can cause in the analysis layer, each with one sentence naming cause and fix.

The CLI prints ``str(err)`` and exits non-zero; nothing here should ever surface as a traceback.
"""

from __future__ import annotations


class AnalysisError(Exception):
    """Base of every analysis error; its message is one sentence for the user."""


class BagError(AnalysisError):
    """The recording cannot be opened or read (missing, truncated, corrupt, unknown format)."""


class TopicError(AnalysisError):
    """A topic the analysis needs is absent, empty or of a type without the needed field."""


class SegmentError(AnalysisError):
    """The recording holds no usable press: no overlap, no loading cycle, an empty segment."""


class CalibrationFileError(AnalysisError):
    """A calibration file is unreadable or violates the format in docs/CONTRACTS.md."""


class PredictionFileError(AnalysisError):
    """A model prediction file is unreadable or lacks indentation_m/output_v arrays."""


class RateFitError(AnalysisError):
    """The recording cannot give rate terms: one speed only, or times it cannot resolve."""
