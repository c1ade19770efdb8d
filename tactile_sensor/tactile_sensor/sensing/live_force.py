"""Which readings go on the live force topic: the newest the driver has, never a backlog.

``~/wrench`` is for control: a gripper acting on a force that is seconds old squeezes what
it already let go of. ``~/reading`` is the record and carries every reading. On a busy
machine the driver can fall behind its ADC (measured: 3.7 s behind beside a CPU burner,
because it published every sample in order). Then the reader hands it the backlog as a few
blocks (hardware/adc_samples.py ``merged``), the chain runs through them (the filter must
see every sample), the record gets them all, and the live topic gets only the readings
within ``window`` of the newest sample: none of a block while newer samples wait behind
it. What the live topic skipped is counted for /diagnostics (``wrench_skipped``).

The window keeps the live topic whole while the driver keeps up: then a read of the port
brings one sample at 1 kHz (the median on the mock ADC) and now and then a few
milliseconds' worth, all of which go out as before. Beyond the window a reading is history:
the record has it, and a controller would only act on it late.
"""

from __future__ import annotations

from collections.abc import Sequence

DEFAULT_WINDOW_S = 0.01


class LiveSelector:
    """Counts what it leaves out; one per driver configuration (the reader's thread only)."""

    def __init__(self, window_s: float = DEFAULT_WINDOW_S) -> None:
        if not window_s >= 0.0:  # NaN too
            raise ValueError(f"live window must be >= 0 s, got {window_s!r}")
        self.window_ns = int(window_s * 1e9)
        self.skipped = 0

    def first_live(self, stamps_ns: Sequence[int], behind: bool) -> int:
        """Index of the first of ``stamps_ns`` (the due readings of one block, oldest
        first) that goes on the live topic; ``len(stamps_ns)`` when none does. ``behind``:
        newer samples are already waiting, so this block is not the newest."""
        n = len(stamps_ns)
        if behind or not n:
            self.skipped += n
            return n
        oldest_live = stamps_ns[-1] - self.window_ns
        first = n - 1
        while first > 0 and stamps_ns[first - 1] >= oldest_live:
            first -= 1
        self.skipped += first
        return first
