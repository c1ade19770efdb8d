"""What a filter of the signal chain is: the filters and the stages placed ahead of them
(the mains notch) both speak it, so neither has to import the other."""

from __future__ import annotations

from typing import Protocol


class Filter(Protocol):
    """A causal scalar filter: one sample in, one sample out."""

    def update(self, x: float) -> float: ...

    def reset(self) -> None: ...
