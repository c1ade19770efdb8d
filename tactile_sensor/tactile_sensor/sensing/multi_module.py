"""What the chains of several modules on one ADC stream share (an array, a bending finger).

Each module gets the single chain's filter and tare window (``sensing.chain``), built from
one ``ChainConfig``; the baselines are one tuple, set all at once, so what a calibration
sees always shares one rest state. A tare is refused naming the first module not at rest.
What differs between the layouts (what the outputs mean, the reading) stays in their own
chains (``array_chain``, ``bend_chain``).

Threading as ``SignalChain``: ``process`` and ``process_batch`` in the reader's thread;
``tare``, ``set_calibration`` and the properties from any other; one lock guards the state.
"""

from __future__ import annotations

import contextlib
import threading
from collections.abc import Sequence
from typing import ClassVar, NamedTuple, TypeVar

from tactile_sensor.sensing.blind import BLIND_MESSAGE
from tactile_sensor.sensing.chain import ChainConfig, SampleSteps, _Parts
from tactile_sensor.sensing.contact import ContactDetector
from tactile_sensor.sensing.errors import SensingError, TareError
from tactile_sensor.sensing.filters import Filter, make_filter
from tactile_sensor.sensing.tare import TareWindow

NAN = float("nan")
#: The highest ADC channel a module can sit on (the firmware sends up to eight).
MAX_CHANNEL = 7


class ModulesTareResult(NamedTuple):
    baselines_v: tuple[float, ...]
    spread_v: float  # the largest of the modules' spreads
    samples: int
    faces: tuple[str, ...]  # the modules' labels, in the baselines' order

    def describe(self) -> str:
        each = ", ".join(f"{face} {b:.4f} V" for face, b in zip(self.faces, self.baselines_v,
                                                                 strict=True))
        return f"baselines {each} (largest spread {self.spread_v * 1e3:.1f} mV)"


V = TypeVar("V")
R = TypeVar("R")


class MultiModuleChain(SampleSteps[V, R]):
    """Per-module filters and tare windows, the baselines of all of them, their tare and
    auto-tare; a layout's chain adds its step, calibration and reading."""

    #: Who reads the channels, in the sentence naming a channel the sample lacks.
    CHANNELS_OWNER: ClassVar[str] = "the modules"

    config: ChainConfig
    faces: tuple[str, ...]
    channels: tuple[int, ...]
    _filters: list[Filter]
    _tares: list[TareWindow]
    _contact: ContactDetector
    _baselines: tuple[float, ...] | None
    _detector_v: float
    _auto_tare_every: int
    _auto_tare_countdown: int

    def _start(self, config: ChainConfig, faces: Sequence[str],
               channels: Sequence[int]) -> _Parts:
        """The state every layout holds, from a validated ``config``; the parts built for
        it (call first in ``__init__``)."""
        self.config = config
        self.config.validate()
        self.faces = tuple(faces)
        self.channels = tuple(channels)
        self._lock = threading.Lock()
        parts = _Parts(config)
        self._conversion = parts.adc
        self._volts_per_count = parts.adc.volts_per_count
        self._filters = [parts.filter] + [self._new_filter() for _ in self.channels[1:]]
        self._tares = [parts.tare] + [self._new_tare() for _ in self.channels[1:]]
        self._contact = parts.contact
        self._blind = parts.blind
        self._detector_v = NAN  # the lowest detector voltage of the last sample
        self._baselines = None
        # A refused auto-tare is retried every tenth of a window, not on every sample.
        self._auto_tare_every = max(1, self._tares[0].size // 10)
        self._auto_tare_countdown = 0
        self.last = None
        return parts

    def _new_filter(self) -> Filter:
        c = self.config
        return make_filter(c.filter_name, c.rate_hz, c.filter_params)

    def _new_tare(self) -> TareWindow:
        c = self.config
        return TareWindow(c.rate_hz, c.tare_window_s, c.tare_max_spread_v)

    # -- state others read or set ----------------------------------------------------------

    @property
    def baselines_v(self) -> tuple[float, ...] | None:
        return self._baselines

    @property
    def baseline_v(self) -> float | None:
        """The first module's baseline (as ``SignalChain.baseline_v``)."""
        return None if self._baselines is None else self._baselines[0]

    @property
    def top_channel(self) -> int:
        """The highest ADC channel read (the device must send at least one more)."""
        return max(self.channels)

    @property
    def tared(self) -> bool:
        return self._baselines is not None

    def _detector_level_v(self) -> float:
        """The most lit module's detector voltage in the last sample."""
        return self._detector_v

    def tare(self) -> ModulesTareResult:
        """Baselines of every module from the last window, all or none: ``TareError``
        naming the first module that is not at rest."""
        with self._lock:
            if self._blind.blind:
                raise TareError(f"Cannot tare: {BLIND_MESSAGE}.")
            results = []
            for face, channel, window in zip(self.faces, self.channels, self._tares,
                                             strict=True):
                try:
                    results.append(window.evaluate())
                except TareError as exc:
                    raise TareError(f"Module {face} (channel {channel}): {exc}") from None
            self._baselines = tuple(r.baseline_v for r in results)
            self._contact.reset()
            self._baselines_set()
            return ModulesTareResult(self._baselines, max(r.spread_v for r in results),
                                     results[0].samples, self.faces)

    def _baselines_set(self) -> None:
        """What a layout restarts once the baselines are new (call with the lock held)."""

    def reset(self) -> None:
        """Forget filters, tare windows and contact state (after a reconnect); keep the
        baselines."""
        with self._lock:
            self._forget()
            self._contact.reset()

    def _forget(self) -> None:
        """Forget what the samples built up (call with the lock held)."""
        self._blind.reset()
        for f in self._filters:
            f.reset()
        for t in self._tares:
            t.clear()

    def _conversion_changed(self) -> None:
        self._forget()

    # -- per sample ------------------------------------------------------------------------

    def _missing_channel(self, channels: int) -> SensingError:
        return SensingError(
            f"The sample has {channels} channel(s) but {self.CHANNELS_OWNER} use channel "
            f"{max(self.channels)}; wire fewer modules or raise CHANNELS in the firmware.")

    def _auto_tare(self) -> None:
        """Before the first tare, with ``auto_tare`` on: the baselines from the windows
        once every module is at rest, tried every tenth of a window (call with the lock
        held, after the sample went into the windows)."""
        if self.config.auto_tare and self._tares[0].ready:
            self._auto_tare_countdown -= 1
            if self._auto_tare_countdown <= 0:
                self._auto_tare_countdown = self._auto_tare_every
                with contextlib.suppress(TareError):  # not all at rest yet: retry later
                    self._baselines = tuple(w.evaluate().baseline_v for w in self._tares)
                    self._baselines_set()
