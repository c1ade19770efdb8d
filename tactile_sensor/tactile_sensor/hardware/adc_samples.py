"""What the ADC stream carries from the port to its consumer, and the pure bookkeeping on
the way: samples and their column batches, the bounded backlog between the drain thread and
the consumer, and per connection the sequence and device clock and the device's info.

Kept apart from the threaded reader (``adc_reader``) so the rules are easy to test without
a port, and so the signal chain can name what it consumes without the reader's threads.
"""

from __future__ import annotations

import collections
import threading
from collections.abc import Callable, Iterable, Iterator
from typing import Generic, NamedTuple, TypeVar

from tactile_sensor.hardware.adc_frame import SEQ_MODULO, TIME_MODULO, DeviceInfo
from tactile_sensor.hardware.errors import SerialPortError

MAX_AWAITING_INFO = 10_000  # samples held per connection until the device's info arrives


class Sample(NamedTuple):
    """One frame as the signal chain sees it.

    ``device_time_us`` is the device clock unwrapped past 2^32 within one connection;
    ``epoch`` counts connections (it changes when the device may have rebooted, so a
    consumer re-anchors its device→host clock mapping). ``host_time_ns`` is
    ``time.time_ns()`` when the chunk holding the frame was read.
    """

    seq: int
    device_time_us: int
    host_time_ns: int
    counts: tuple[int, ...]
    epoch: int


T = TypeVar("T")


class SampleBatch:
    """Consecutive samples of one connection, as columns (what one read of the port held).

    Columns rather than ``Sample`` objects: one list append per field and frame, where a
    consumer that keeps only a few fields would otherwise pay for an object per sample.
    ``host_time_ns`` is per sample because samples held for the device's info frame join
    the batch of the chunk that brought the info.
    """

    __slots__ = ("counts", "device_time_us", "epoch", "host_time_ns", "seq")

    def __init__(self, epoch: int) -> None:
        self.epoch = epoch
        self.seq: list[int] = []
        self.device_time_us: list[int] = []
        self.host_time_ns: list[int] = []
        self.counts: list[tuple[int, ...]] = []

    def __len__(self) -> int:
        return len(self.seq)

    def __iter__(self) -> Iterator[Sample]:
        epoch = self.epoch
        for seq, t_us, host_ns, counts in zip(self.seq, self.device_time_us,
                                              self.host_time_ns, self.counts, strict=True):
            yield Sample(seq, t_us, host_ns, counts, epoch)

    def append(self, seq: int, device_time_us: int, host_time_ns: int,
               counts: tuple[int, ...]) -> None:
        self.seq.append(seq)
        self.device_time_us.append(device_time_us)
        self.host_time_ns.append(host_time_ns)
        self.counts.append(counts)

    def extend(self, other: SampleBatch) -> None:
        """Append ``other``'s samples (the next ones of the same connection)."""
        self.seq += other.seq
        self.device_time_us += other.device_time_us
        self.host_time_ns += other.host_time_ns
        self.counts += other.counts

    def head(self, n: int) -> SampleBatch:
        """The first ``n`` samples (a full backlog keeps what fits)."""
        out = SampleBatch(self.epoch)
        out.seq, out.device_time_us = self.seq[:n], self.device_time_us[:n]
        out.host_time_ns, out.counts = self.host_time_ns[:n], self.counts[:n]
        return out

    @classmethod
    def of(cls, samples: Iterable[Sample]) -> SampleBatch:
        """A batch of ``samples`` (all of one epoch, the first one's)."""
        batch: SampleBatch | None = None
        for s in samples:
            if batch is None:
                batch = cls(s.epoch)
            batch.append(s.seq, s.device_time_us, s.host_time_ns, s.counts)
        return batch if batch is not None else cls(0)

    def __repr__(self) -> str:
        return f"SampleBatch({len(self)} samples, epoch {self.epoch})"


def merged(items: Iterable[T]) -> list[T]:
    """``items`` with each run of consecutive batches of one connection joined into one
    block: a backlog worked off as a few blocks, not as the hundreds of chunks the drain
    thread read (one pass of the signal chain and one look at what is newest per block)."""
    out: list[T] = []
    block: SampleBatch | None = None
    for item in items:
        if type(item) is SampleBatch:
            if block is not None and block.epoch == item.epoch:
                block.extend(item)
                continue
            block = SampleBatch(item.epoch)
            block.extend(item)
            out.append(block)  # type: ignore[arg-type]
            continue
        block = None
        out.append(item)
    return out


def _one(_: object) -> int:
    return 1


class SampleBacklog(Generic[T]):
    """Bounded FIFO from the drain thread to the consumer's thread (pure, testable).

    An item holds ``size_of(item)`` samples (a batch holds many; a state change none).
    ``put`` never blocks: samples beyond ``capacity`` are refused and counted in
    ``dropped`` (the newest go, so what was delivered stays contiguous; a batch that fits
    only in part is cut to its first samples by ``head``); items without samples (state
    changes) are always taken, so the consumer sees every connection change in order with
    the data. ``held`` is set by the consumer: samples it took but has not passed on yet
    (a batch delivered one sample at a time); they count in ``len``, the peak and against
    the capacity, and ``clear`` throws them away too.
    """

    def __init__(self, capacity: int, size_of: Callable[[T], int] = _one,
                 head: Callable[[T, int], T] | None = None) -> None:
        if isinstance(capacity, bool) or not isinstance(capacity, int) or capacity < 1:
            raise SerialPortError(f"backlog capacity must be a positive number of samples, "
                                  f"got {capacity!r}.")
        self.capacity = capacity
        self._size_of = size_of
        self._head = head
        self._items: collections.deque[T] = collections.deque()
        self._samples = 0
        self._ready = threading.Condition(threading.Lock())
        self._closed = False
        self.held = 0
        self.dropped = 0
        self.peak = 0

    def __len__(self) -> int:
        return self._samples + self.held

    def put(self, items: Iterable[T]) -> int:
        """Queue ``items`` in order; returns how many samples were refused (backlog full)."""
        refused = 0
        size_of = self._size_of
        with self._ready:
            for item in items:
                n = size_of(item)
                if n:
                    room = self.capacity - self._samples - self.held
                    if n > room:
                        refused += n - max(room, 0)
                        if room <= 0 or self._head is None:
                            continue
                        item, n = self._head(item, room), room
                    self._samples += n
                self._items.append(item)
            self.dropped += refused
            self.peak = max(self.peak, self._samples + self.held)
            self._ready.notify()
        return refused

    def take(self, limit: int, timeout_s: float) -> list[T]:
        """Up to ``limit`` items in order, waiting up to ``timeout_s`` for the first;
        [] on timeout or once closed and empty."""
        with self._ready:
            if not self._items and not self._closed and timeout_s > 0:
                self._ready.wait(timeout_s)
            items = self._items
            n = min(limit, len(items))
            if not n:
                return []
            out = [items.popleft() for _ in range(n)]
            self._samples -= sum(map(self._size_of, out))
            return out

    def close(self) -> None:
        """Wake a waiting ``take`` (the consumer is being stopped)."""
        with self._ready:
            self._closed = True
            self._ready.notify_all()

    def reopen(self) -> None:
        with self._ready:
            self._closed = False

    @property
    def empty(self) -> bool:
        """Nothing queued or held: no item, not even a state change."""
        return not self._items and not self.held

    def clear(self) -> int:
        """Forget every queued item; returns how many samples were thrown away."""
        with self._ready:
            n = self._samples + self.held
            self._items.clear()
            self._samples = self.held = 0
            return n


class _InfoChange(NamedTuple):
    info: DeviceInfo


class _InfoGate:
    """Per-connection: which info describes the samples, and the samples waiting for it.

    Pure (no threads, no I/O) so the rules are easy to test: a version-2 sample is
    released only after an info frame of this connection; a version-1 sample describes
    itself (version and channel count); a sample whose channel count contradicts the
    stated one is refused.
    """

    def __init__(self, max_waiting: int = MAX_AWAITING_INFO) -> None:
        self.info: DeviceInfo | None = None
        self.waiting: collections.deque[Sample] = collections.deque()
        self.max_waiting = max_waiting
        self.dropped = 0
        self.mismatches = 0

    def restart(self) -> None:
        self.dropped += len(self.waiting)
        self.waiting.clear()
        self.info = None

    def on_info(self, info: DeviceInfo) -> list[Sample | _InfoChange]:
        out: list[Sample | _InfoChange] = []
        if info != self.info:
            self.info = info
            out.append(_InfoChange(info))
        waiting, self.waiting = self.waiting, collections.deque()
        for sample in waiting:
            if len(sample.counts) == info.codes:
                out.append(sample)
            else:
                self.mismatches += 1
        return out

    def on_sample(self, sample: Sample, version: int) -> list[Sample | _InfoChange]:
        info = self.info
        if version == 1:
            if info is None or info.version != 1 or info.channels != len(sample.counts):
                return [*self.on_info(DeviceInfo(1, len(sample.counts))), sample]
            return [sample]
        if info is None or info.version != version:
            if len(self.waiting) >= self.max_waiting:
                self.waiting.popleft()
                self.dropped += 1
            self.waiting.append(sample)
            return []
        if len(sample.counts) != info.codes:
            self.mismatches += 1
            return []
        return [sample]


class _Sequencer:
    """Per-connection sequence and clock bookkeeping (pure, so it is easy to test)."""

    def __init__(self) -> None:
        self.last_seq: int | None = None
        self.last_t: int | None = None
        self.time_us = 0
        self.gaps = 0
        self.dropped = 0
        self.resets = 0

    def restart(self) -> None:
        self.last_seq = None
        self.last_t = None

    def advance(self, seq: int, t_us: int) -> int:
        """Account for one frame; returns its unwrapped device time [µs]."""
        if self.last_seq is not None:
            gap = (seq - self.last_seq - 1) % SEQ_MODULO
            if gap >= SEQ_MODULO // 2:
                self.resets += 1
            elif gap:
                self.gaps += 1
                self.dropped += gap
        self.last_seq = seq
        if self.last_t is None:
            self.time_us = t_us
        else:
            delta = (t_us - self.last_t) % TIME_MODULO
            if delta >= TIME_MODULO // 2:  # clock stepped back: keep it monotone-ish, honest
                delta -= TIME_MODULO
            self.time_us += delta
        self.last_t = t_us
        return self.time_us
