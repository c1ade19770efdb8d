"""Threaded reader of the ADC frame stream on a serial port (pyserial), unplug-proof.

The reader owns two threads. The serial thread opens the port, parses frames
(``adc_frame.FrameParser``), numbers them (sequence gaps, 64-bit device time) and queues
them; the dispatch thread hands them, in order and with the state changes between them,
to ``on_sample`` / ``on_state``. What the device says about its codes (``DeviceInfo``:
resolution, reference, channels, rate) goes to ``on_info`` before the first sample it
describes: a version-2 device's samples wait (in order, up to ``MAX_AWAITING_INFO``) for
its next info frame, sent every 0.25 s; a version-1 stream gets an info that states only
the version and channel count. The serial thread does nothing slow, so it drains the
port even when the consumer (signal chain, ROS publishing: ~100x the cost of parsing) is
starved of CPU: the device's and the OS's buffers hold only seconds, and a device whose
host buffer is full drops whole batches of frames. The queue (``SampleBacklog``) holds
a minute by default; beyond its capacity new samples are dropped and counted
(``ReaderStats.backlog_dropped``), never silently. Any port failure (cable pulled,
device reset, port missing at start) becomes state ``DISCONNECTED`` with a reason, and
the serial thread retries every ``reopen_interval_s`` until the device is back. Nothing
here raises after construction.

A ROS node uses it like this::

    reader = AdcStreamReader("/dev/ttyACM0", on_sample=queue.put_nowait,
                             on_state=lambda state, reason: ...)
    reader.start()   # on_activate
    reader.stop()    # on_deactivate / on_cleanup
"""

from __future__ import annotations

import collections
import contextlib
import enum
import errno
import threading
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from types import TracebackType
from typing import Generic, NamedTuple, TypeVar

import serial

from tactile_sensor.hardware.adc_frame import (
    MAX_CHANNELS,
    SEQ_MODULO,
    TIME_MODULO,
    DeviceInfo,
    Frame,
    FrameParser,
)
from tactile_sensor.hardware.errors import SerialPortError

DEFAULT_BAUDRATE = 1_000_000
MIN_BAUDRATE = 50
MAX_BAUDRATE = 12_000_000
DEFAULT_BACKLOG = 60_000  # samples: 1 min at 1 kHz (~16 MB); a process starved longer is mis-sized
DISPATCH_BATCH = 256  # samples handed over per lock acquisition
MAX_AWAITING_INFO = 10_000  # samples held per connection until the device's info arrives


class ConnectionState(enum.Enum):
    """Where the link stands; every change goes to ``on_state(state, reason)``."""

    CONNECTING = "connecting"  # port open (or being opened), no valid frame yet
    CONNECTED = "connected"  # valid frames are arriving
    DISCONNECTED = "disconnected"  # port missing or failed; retrying
    STOPPED = "stopped"  # stop() was called


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


@dataclass(frozen=True)
class ReaderStats:
    """Counters since construction (a snapshot; safe to read from any thread)."""

    state: ConnectionState
    reason: str
    frames: int
    crc_errors: int
    header_errors: int
    sequence_gaps: int  # gap events
    dropped_frames: int  # frames missing according to the sequence numbers
    sequence_resets: int  # sequence went backwards (device restart or reordering)
    resyncs: int
    bytes_received: int
    bytes_discarded: int
    connections: int
    last_frame_age_s: float  # inf before the first frame
    backlog: int = 0  # samples parsed but not yet handed to on_sample
    backlog_peak: int = 0  # the most ever waiting at once
    backlog_dropped: int = 0  # samples dropped because the backlog was full
    discarded_at_stop: int = 0  # samples still queued when stop() ran out of time
    device_info: DeviceInfo | None = None  # what the device last said (this connection)
    info_frames: int = 0
    info_errors: int = 0  # info frames with impossible content (firmware bug)
    last_info_error: str = ""
    awaiting_info: int = 0  # samples held now until the device's info frame arrives
    dropped_awaiting_info: int = 0  # samples thrown away: no info frame came in time
    channel_mismatches: int = 0  # data frames whose channel count contradicts the info


SampleCallback = Callable[[Sample], None]
StateCallback = Callable[[ConnectionState, str], None]
InfoCallback = Callable[[DeviceInfo], None]

T = TypeVar("T")


class SampleBacklog(Generic[T]):
    """Bounded FIFO from the serial thread to the consumer's thread (pure, testable).

    ``put`` never blocks: samples beyond ``capacity`` are refused and counted in
    ``dropped`` (the newest go, so what was delivered stays contiguous); items for which
    ``is_sample`` is False (state changes) are always taken, so the consumer sees every
    connection change in order with the data.
    """

    def __init__(self, capacity: int, is_sample: Callable[[T], bool] = lambda _: True
                 ) -> None:
        if isinstance(capacity, bool) or not isinstance(capacity, int) or capacity < 1:
            raise SerialPortError(f"backlog capacity must be a positive number of samples, "
                                  f"got {capacity!r}.")
        self.capacity = capacity
        self._is_sample = is_sample
        self._items: collections.deque[T] = collections.deque()
        self._samples = 0
        self._ready = threading.Condition(threading.Lock())
        self._closed = False
        self.dropped = 0
        self.peak = 0

    def __len__(self) -> int:
        return self._samples

    def put(self, items: Iterable[T]) -> int:
        """Queue ``items`` in order; returns how many samples were refused (backlog full)."""
        refused = 0
        with self._ready:
            for item in items:
                if self._is_sample(item):
                    if self._samples >= self.capacity:
                        refused += 1
                        continue
                    self._samples += 1
                self._items.append(item)
            self.dropped += refused
            self.peak = max(self.peak, self._samples)
            self._ready.notify()
        return refused

    def take(self, limit: int, timeout_s: float) -> list[T]:
        """Up to ``limit`` items in order, waiting up to ``timeout_s`` for the first;
        [] on timeout or once closed and empty."""
        with self._ready:
            if not self._items and not self._closed:
                self._ready.wait(timeout_s)
            n = min(limit, len(self._items))
            out = [self._items.popleft() for _ in range(n)]
            self._samples -= sum(1 for item in out if self._is_sample(item))
            return out

    def close(self) -> None:
        """Wake a waiting ``take`` (the consumer is being stopped)."""
        with self._ready:
            self._closed = True
            self._ready.notify_all()

    def reopen(self) -> None:
        with self._ready:
            self._closed = False

    def clear(self) -> int:
        """Forget every queued item; returns how many samples were thrown away."""
        with self._ready:
            n = self._samples
            self._items.clear()
            self._samples = 0
            return n


class _StateChange(NamedTuple):
    state: ConnectionState
    reason: str


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
            if len(sample.counts) == info.channels:
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
        if len(sample.counts) != info.channels:
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


class AdcStreamReader:
    """Reads ADC frames from ``port`` in its own thread and survives unplug/replug.

    ``port`` is a device path or any pyserial URL. ``channels`` (if given) rejects frames
    with another channel count. ``on_info`` (if given) receives the device's info before
    the first sample of each connection and whenever it changes. Callbacks run in the
    reader's dispatch thread, one at a time and in stream order; they may be slow (the
    serial thread keeps reading meanwhile, up to ``backlog`` samples ahead) but must not
    raise: an exception escaping a callback stops the reader (state STOPPED, reason says
    why).
    """

    def __init__(
        self,
        port: str,
        on_sample: SampleCallback,
        on_state: StateCallback | None = None,
        baudrate: int = DEFAULT_BAUDRATE,
        reopen_interval_s: float = 0.2,
        channels: int | None = None,
        read_timeout_s: float = 0.05,
        silence_timeout_s: float = 1.0,
        backlog: int = DEFAULT_BACKLOG,
        on_info: InfoCallback | None = None,
    ) -> None:
        if not isinstance(port, str) or not port:
            raise SerialPortError(f"port must be a device path such as /dev/ttyACM0, got {port!r}.")
        if isinstance(baudrate, bool) or not isinstance(baudrate, int) or not (
                MIN_BAUDRATE <= baudrate <= MAX_BAUDRATE):
            raise SerialPortError(
                f"baudrate must be an integer in {MIN_BAUDRATE}..{MAX_BAUDRATE}, got "
                f"{baudrate!r}; use the rate the firmware sets (default {DEFAULT_BAUDRATE})."
            )
        for name, value in (("reopen_interval_s", reopen_interval_s),
                            ("read_timeout_s", read_timeout_s),
                            ("silence_timeout_s", silence_timeout_s)):
            if not isinstance(value, int | float) or not 0.0 < value <= 60.0:
                raise SerialPortError(f"{name} must be in (0, 60] s, got {value!r}.")
        if channels is not None and (not isinstance(channels, int)
                                     or not 1 <= channels <= MAX_CHANNELS):
            raise SerialPortError(f"channels must be 1..{MAX_CHANNELS} or None, got {channels!r}.")
        if not callable(on_sample) or any(cb is not None and not callable(cb)
                                          for cb in (on_state, on_info)):
            raise SerialPortError("on_sample, on_state and on_info must be callables.")
        self.port = port
        self.baudrate = baudrate
        self._on_sample = on_sample
        self._on_state = on_state
        self._on_info = on_info
        self._reopen_s = float(reopen_interval_s)
        self._read_timeout_s = float(read_timeout_s)
        self._silence_s = float(silence_timeout_s)
        self._backlog: SampleBacklog[Sample | _StateChange | _InfoChange] = SampleBacklog(
            backlog, lambda item: type(item) is Sample)
        self._parser = FrameParser(channels)
        self._seq = _Sequencer()
        self._gate = _InfoGate()
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._dispatcher: threading.Thread | None = None
        self._dispatch_stop = threading.Event()
        self._abandon = False  # stop() ran out of time: deliver nothing more
        self._discarded = 0
        self._state = ConnectionState.STOPPED
        self._reason = "not started"
        self._bytes = 0
        self._connections = 0
        self._last_frame_mono = -1.0

    # -- public API ------------------------------------------------------------------------

    @property
    def state(self) -> ConnectionState:
        return self._state

    @property
    def reason(self) -> str:
        return self._reason

    @property
    def device_info(self) -> DeviceInfo | None:
        """What the connected device said about its codes (None before it said anything)."""
        return self._gate.info

    def stats(self) -> ReaderStats:
        with self._lock:
            p = self._parser
            age = (time.monotonic() - self._last_frame_mono if self._last_frame_mono >= 0
                   else float("inf"))
            return ReaderStats(
                state=self._state, reason=self._reason, frames=p.frames,
                crc_errors=p.crc_errors, header_errors=p.header_errors,
                sequence_gaps=self._seq.gaps, dropped_frames=self._seq.dropped,
                sequence_resets=self._seq.resets, resyncs=p.resyncs,
                bytes_received=self._bytes, bytes_discarded=p.bytes_discarded,
                connections=self._connections, last_frame_age_s=age,
                backlog=len(self._backlog), backlog_peak=self._backlog.peak,
                backlog_dropped=self._backlog.dropped, discarded_at_stop=self._discarded,
                device_info=self._gate.info, info_frames=p.info_frames,
                info_errors=p.info_errors, last_info_error=p.last_info_error,
                awaiting_info=len(self._gate.waiting), dropped_awaiting_info=self._gate.dropped,
                channel_mismatches=self._gate.mismatches,
            )

    def start(self) -> None:
        """Start the reader's threads (idempotent)."""
        if self._thread is not None and self._thread.is_alive():
            return
        self._stop.clear()
        self._dispatch_stop.clear()
        self._abandon = False
        self._backlog.reopen()
        self._dispatcher = threading.Thread(target=self._dispatch,
                                            name=f"adc-dispatch:{self.port}", daemon=True)
        self._dispatcher.start()
        self._set_state(ConnectionState.CONNECTING, f"opening {self.port}")
        self._thread = threading.Thread(target=self._loop, name=f"adc-reader:{self.port}",
                                        daemon=True)
        self._thread.start()

    def stop(self, timeout_s: float = 2.0) -> None:
        """Stop reading, close the port and deliver what is still queued, for at most
        about ``timeout_s``; samples not delivered by then are counted
        (``ReaderStats.discarded_at_stop``)."""
        deadline = time.monotonic() + timeout_s
        self._stop.set()
        thread, self._thread = self._thread, None
        if thread is not None and thread is not threading.current_thread():
            thread.join(timeout_s)
        dispatcher, self._dispatcher = self._dispatcher, None
        self._dispatch_stop.set()
        self._backlog.close()
        if dispatcher is not None and dispatcher is not threading.current_thread():
            dispatcher.join(max(0.0, deadline - time.monotonic()))
            if dispatcher.is_alive():
                self._abandon = True
                discarded = self._backlog.clear()
                with self._lock:
                    self._discarded += discarded
                dispatcher.join(0.5)
        with self._lock:
            changed = self._state is not ConnectionState.STOPPED
            self._state, self._reason = ConnectionState.STOPPED, "stopped"
        if changed and self._on_state is not None:
            self._on_state(ConnectionState.STOPPED, "stopped")

    def __enter__(self) -> AdcStreamReader:
        self.start()
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.stop()

    # -- thread ----------------------------------------------------------------------------

    def _set_state(self, state: ConnectionState, reason: str) -> None:
        """New state now; its callback in order with the samples (dispatch thread)."""
        if state is self._state and reason == self._reason:
            return
        with self._lock:
            if self._stop.is_set():
                # stopping: stop() or the dispatcher's error has the last word (the serial
                # thread, still inside _ingest, turned a STOPPED back into CONNECTED)
                return
            self._state, self._reason = state, reason
        if self._on_state is not None:
            self._backlog.put((_StateChange(state, reason),))

    def _dispatch(self) -> None:
        """Dispatch thread: hand queued samples and state changes to the callbacks."""
        backlog, on_sample, on_state = self._backlog, self._on_sample, self._on_state
        on_info = self._on_info
        try:
            while not self._abandon:
                items = backlog.take(DISPATCH_BATCH, 0.1)
                if not items:
                    if self._dispatch_stop.is_set():
                        return
                    continue
                for item in items:
                    if self._abandon:
                        return
                    if type(item) is Sample:
                        on_sample(item)
                    elif type(item) is _InfoChange:
                        if on_info is not None:
                            on_info(item.info)
                    elif on_state is not None:
                        on_state(*item)
        except BaseException as exc:
            # Make the dead consumer visible in the state and stop reading (nobody would
            # take the samples), then let threading.excepthook print the traceback.
            with self._lock:
                self._state = ConnectionState.STOPPED
                self._reason = f"reader stopped by an error in a callback: {exc!r}"
            self._stop.set()
            raise

    def _open(self) -> serial.SerialBase | None:
        try:
            port = serial.serial_for_url(self.port, baudrate=self.baudrate,
                                         timeout=self._read_timeout_s, do_not_open=True)
            port.open()
        except (serial.SerialException, OSError, ValueError) as exc:
            self._set_state(ConnectionState.DISCONNECTED, self._open_failure(exc))
            return None
        with self._lock:
            self._connections += 1
            self._parser.reset()
            self._seq.restart()
            self._gate.restart()
        self._set_state(ConnectionState.CONNECTING, f"{self.port} open, waiting for frames")
        return port

    def _open_failure(self, exc: BaseException) -> str:
        code = getattr(exc, "errno", None)
        retry = f"retrying every {self._reopen_s:g} s"
        if code == errno.ENOENT:
            return f"{self.port} does not exist (device unplugged?); {retry}"
        if code in (errno.EACCES, errno.EPERM):
            return (f"permission denied on {self.port}; add the user to the 'dialout' group; "
                    f"{retry}")
        if code == errno.EBUSY:
            return f"{self.port} is busy (another program has it open); {retry}"
        return f"cannot open {self.port}: {exc}; {retry}"

    def _loop(self) -> None:
        port: serial.SerialBase | None = None
        try:
            while not self._stop.is_set():
                if port is None:
                    port = self._open()
                    if port is None:
                        self._stop.wait(self._reopen_s)
                    continue
                try:
                    data = port.read(port.in_waiting or 1)
                except (serial.SerialException, OSError) as exc:
                    self._close(port)
                    port = None
                    self._set_state(
                        ConnectionState.DISCONNECTED,
                        f"{self.port} failed ({exc.__class__.__name__}: {exc}); device "
                        f"unplugged or reset? retrying every {self._reopen_s:g} s",
                    )
                    continue
                if data:
                    self._ingest(data)
                elif (self._state is ConnectionState.CONNECTED
                      and time.monotonic() - self._last_frame_mono > self._silence_s):
                    self._set_state(
                        ConnectionState.CONNECTING,
                        f"no valid frame for {self._silence_s:g} s on {self.port} "
                        "(device silent, wrong baud rate or wrong firmware?)",
                    )
        finally:
            if port is not None:
                self._close(port)

    @staticmethod
    def _close(port: serial.SerialBase) -> None:
        with contextlib.suppress(serial.SerialException, OSError):  # device already gone
            port.close()

    def _ingest(self, data: bytes) -> None:
        host_ns = time.time_ns()
        with self._lock:
            self._bytes += len(data)
            frames = self._parser.feed(data)
            if not frames:
                return
            seqr, gate = self._seq, self._gate
            epoch = self._connections
            samples: list[Sample | _InfoChange] = []
            for f in frames:
                if type(f) is Frame:
                    samples += gate.on_sample(Sample(f.seq, seqr.advance(f.seq, f.t_us),
                                                     host_ns, f.counts, epoch), f.version)
                else:
                    samples += gate.on_info(f)
            self._last_frame_mono = time.monotonic()
        if self._state is not ConnectionState.CONNECTED:
            self._set_state(ConnectionState.CONNECTED, f"receiving frames from {self.port}")
        self._backlog.put(samples)
