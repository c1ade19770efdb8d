"""Threaded reader of the ADC frame stream on a serial port (pyserial), unplug-proof.

The reader's thread waits for the port, reads everything it holds in one chunk, parses
every frame of the chunk (``adc_frame.FrameParser``), numbers them (sequence gaps, 64-bit
device time) and hands them to the consumer in the same thread: one ``SampleBatch`` (the
chunk's samples as columns) to ``on_batch``, or one ``Sample`` at a time to
``on_sample``, in stream order and with the state changes between them (``on_state``). No
thread sits between the port and the consumer: at 1 kHz the port delivers about one frame
per read, and a hand-off per chunk to another thread (a condition variable, a context
switch and the GIL changing hands) cost more CPU than parsing and publishing the frame.

What the device says about its codes (``DeviceInfo``: resolution, reference, channels,
rate) goes to ``on_info`` before the first sample it describes: a version-2 device's
samples wait (in order, up to ``adc_samples.MAX_AWAITING_INFO``) for its next info frame,
sent every 0.25 s; a version-1 stream gets an info that states only the version and channel
count.

A consumer starved of CPU or stuck in a callback must not lose frames: the device's and
the OS's buffers hold only seconds (the pseudo-terminal ~1.4 s of frames, a USB serial
port less), and a device whose host buffer is full drops whole batches of frames. So a
second thread, the drain thread, wakes every ``drain_after_s`` and, when the consumer
has been inside its callbacks that long, reads the port itself into a queue
(``SampleBacklog``); the reader's thread empties that queue, in order and joined into
blocks (``adc_samples.merged``), before it reads the port again, and ``samples_waiting``
tells its consumer whether newer samples wait behind the block at hand (the driver then
keeps the block off its live topic: sensing/live_force.py). A read that finds the port
full takes everything the port holds at once, so the newest sample is in that chunk.
The queue holds a minute by default; beyond its capacity new samples are
dropped and counted (``ReaderStats.backlog_dropped``), never silently. Any port failure
(cable pulled, device reset, port missing at start) becomes state ``DISCONNECTED`` with a
reason, and the reader retries every ``reopen_interval_s`` until the device is back.
Nothing here raises after construction.

A ROS node uses it like this::

    reader = AdcStreamReader("/dev/ttyACM0", on_batch=process_and_publish,
                             on_state=lambda state, reason: ...)
    reader.start()   # on_activate
    reader.stop()    # on_deactivate / on_cleanup
"""

from __future__ import annotations

import contextlib
import enum
import errno
import os
import select
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from types import TracebackType
from typing import NamedTuple

import serial

from tactile_sensor.hardware.adc_frame import MAX_CHANNELS, DeviceInfo, Frame, FrameParser
from tactile_sensor.hardware.adc_samples import (
    Sample,
    SampleBacklog,
    SampleBatch,
    _InfoChange,
    _InfoGate,
    _Sequencer,
    merged,
)
from tactile_sensor.hardware.errors import SerialPortError

DEFAULT_BAUDRATE = 1_000_000
MIN_BAUDRATE = 50
MAX_BAUDRATE = 12_000_000
DEFAULT_BACKLOG = 60_000  # samples: 1 min at 1 kHz (~16 MB); a process starved longer is mis-sized
DISPATCH_BATCH = 256  # queued items (batches, state changes) taken per lock acquisition
READ_CHUNK = 1 << 16  # bytes per read: 5,000 one-channel frames, whatever the port holds
MORE_WAITING = 1 << 10  # a read this long (~80 frames) is followed by more reads at once
DRAIN_AFTER_S = 0.05  # a consumer busy this long has the drain thread read the port


class ConnectionState(enum.Enum):
    """Where the link stands; every change goes to ``on_state(state, reason)``."""

    CONNECTING = "connecting"  # port open (or being opened), no valid frame yet
    CONNECTED = "connected"  # valid frames are arriving
    DISCONNECTED = "disconnected"  # port missing or failed; retrying
    STOPPED = "stopped"  # stop() was called


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
    #: Data frames with a valid CRC but a code over the full scale the device's info states:
    #: garbage whose CRC-16 matched by chance (1 in 65,536 candidates), dropped
    over_full_scale: int = 0


SampleCallback = Callable[[Sample], None]
StateCallback = Callable[[ConnectionState, str], None]
InfoCallback = Callable[[DeviceInfo], None]
BatchCallback = Callable[[SampleBatch], None]


class _StateChange(NamedTuple):
    state: ConnectionState
    reason: str


class AdcStreamReader:
    """Reads ADC frames from ``port`` in its own thread and survives unplug/replug.

    ``port`` is a device path or any pyserial URL. ``channels`` (if given) rejects frames
    with another channel count. ``on_info`` (if given) receives the device's info before
    the first sample of each connection and whenever it changes. Give ``on_batch`` (a
    ``SampleBatch`` per chunk read) or ``on_sample`` (one ``Sample`` at a time). Callbacks
    run in the reader's thread, one at a time and in stream order; they may be slow (the
    drain thread keeps reading meanwhile, up to ``backlog`` samples ahead) but must not
    raise: an exception escaping a callback stops the reader (state STOPPED, reason says
    why). ``read_period_s`` > 0 reads the port at most once a period: a 1 kHz stream then
    comes a few samples a read, for one wake-up of this thread instead of one per sample.
    """

    def __init__(
        self,
        port: str,
        on_sample: SampleCallback | None = None,
        on_state: StateCallback | None = None,
        baudrate: int = DEFAULT_BAUDRATE,
        reopen_interval_s: float = 0.2,
        channels: int | None = None,
        read_timeout_s: float = 0.05,
        silence_timeout_s: float = 1.0,
        backlog: int = DEFAULT_BACKLOG,
        on_info: InfoCallback | None = None,
        on_batch: BatchCallback | None = None,
        drain_after_s: float = DRAIN_AFTER_S,
        read_period_s: float = 0.0,
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
                            ("silence_timeout_s", silence_timeout_s),
                            ("drain_after_s", drain_after_s)):
            if not isinstance(value, int | float) or not 0.0 < value <= 60.0:
                raise SerialPortError(f"{name} must be in (0, 60] s, got {value!r}.")
        if not isinstance(read_period_s, int | float) or not 0.0 <= read_period_s <= 0.1:
            raise SerialPortError(f"read_period_s must be in [0, 0.1] s, got {read_period_s!r}.")
        if channels is not None and (not isinstance(channels, int)
                                     or not 1 <= channels <= MAX_CHANNELS):
            raise SerialPortError(f"channels must be 1..{MAX_CHANNELS} or None, got {channels!r}.")
        if (on_sample is None) == (on_batch is None):
            raise SerialPortError("give one of on_sample (a Sample at a time) and on_batch (a "
                                  "SampleBatch per chunk read), as a callable.")
        if any(cb is not None and not callable(cb)
               for cb in (on_sample, on_batch, on_state, on_info)):
            raise SerialPortError("on_sample, on_batch, on_state and on_info must be "
                                  "callables.")
        self.port = port
        self.baudrate = baudrate
        self._on_sample = on_sample
        self._on_batch = on_batch
        self._on_state = on_state
        self._on_info = on_info
        self._reopen_s = float(reopen_interval_s)
        self._read_timeout_ms = max(1, round(float(read_timeout_s) * 1000))
        self._read_timeout_s = float(read_timeout_s)
        self._silence_s = float(silence_timeout_s)
        self._drain_after_s = float(drain_after_s)
        self._read_period_s = float(read_period_s)
        self._backlog: SampleBacklog[SampleBatch | _StateChange | _InfoChange] = SampleBacklog(
            backlog, _samples_in, SampleBatch.head)  # type: ignore[arg-type]
        self._parser = FrameParser(channels)
        self._seq = _Sequencer()
        self._over_full_scale = 0
        self._gate = _InfoGate()
        self._lock = threading.Lock()  # counters, state
        self._port_lock = threading.Lock()  # the port, the parser: reads stay in order
        self._port: serial.SerialBase | None = None
        self._fd: int | None = None  # a POSIX port's descriptor, read without pyserial
        self._poll: select.poll | None = None
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._drainer: threading.Thread | None = None
        self._generation = 0  # a thread of an earlier start() delivers nothing more
        self._busy_since: float | None = None  # the consumer is in a callback since then
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

    @property
    def samples_waiting(self) -> int:
        """Samples read from the port and queued behind the one being delivered: more than
        0 while the consumer works off a backlog (its batch is not the newest)."""
        return len(self._backlog)

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
                channel_mismatches=self._gate.mismatches, over_full_scale=self._over_full_scale,
            )

    def start(self) -> None:
        """Start the reader's threads (idempotent)."""
        if self._thread is not None and self._thread.is_alive():
            return
        self._stop.clear()
        self._generation += 1
        self._backlog.reopen()
        self._set_state(ConnectionState.CONNECTING, f"opening {self.port}")
        self._thread = threading.Thread(target=self._run, args=(self._generation,),
                                        name=f"adc-reader:{self.port}", daemon=True)
        self._drainer = threading.Thread(target=self._drain, args=(self._generation,),
                                         name=f"adc-drain:{self.port}", daemon=True)
        self._thread.start()
        self._drainer.start()

    def stop(self, timeout_s: float = 2.0) -> None:
        """Stop reading, close the port and deliver what is still queued, for at most
        about ``timeout_s``; samples not delivered by then are counted
        (``ReaderStats.discarded_at_stop``)."""
        deadline = time.monotonic() + timeout_s
        self._stop.set()
        me = threading.current_thread()
        drainer, self._drainer = self._drainer, None
        if drainer is not None and drainer is not me:
            drainer.join(timeout_s)
        thread, self._thread = self._thread, None
        if thread is not None and thread is not me:
            thread.join(max(0.0, deadline - time.monotonic()))
            if thread.is_alive():  # stuck in a callback: give up what it has not delivered
                self._generation += 1
                discarded = self._backlog.clear()
                with self._lock:
                    self._discarded += discarded
                thread.join(0.5)
        self._backlog.close()
        with self._port_lock:
            self._close()
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

    # -- the reader's thread ---------------------------------------------------------------

    def _set_state(self, state: ConnectionState, reason: str) -> None:
        """New state now; its callback in order with the samples (the reader's thread)."""
        if state is self._state and reason == self._reason:
            return
        with self._lock:
            if self._stop.is_set():
                # stopping: stop() or the callback's error has the last word (the drain
                # thread, still inside _ingest, would turn a STOPPED back into CONNECTED)
                return
            self._state, self._reason = state, reason
        if self._on_state is not None:
            self._backlog.put((_StateChange(state, reason),))

    def _run(self, generation: int) -> None:
        """The reader's thread: read the port, parse, deliver; then what is left queued."""
        try:
            period, read_at = self._read_period_s, 0.0
            while not self._stop.is_set() and generation == self._generation:
                if period:  # the samples of a period in one read: one wake-up, not several
                    wait = read_at + period - time.monotonic()
                    if wait > 0.0 and self._stop.wait(wait):
                        break
                    read_at = time.monotonic()
                items = self._read_port()
                self._busy_since = time.monotonic()
                try:
                    if items:
                        self._deliver(items, generation, queued=False)
                    while queued := self._backlog.take(DISPATCH_BATCH, 0.0):
                        self._deliver(merged(queued), generation)
                finally:
                    self._busy_since = None
            while queued := self._backlog.take(DISPATCH_BATCH, 0.0):
                self._deliver(merged(queued), generation)
        except BaseException as exc:
            # Make the dead consumer visible in the state and stop reading (nobody would
            # take the samples), then let threading.excepthook print the traceback.
            with self._lock:
                self._state = ConnectionState.STOPPED
                self._reason = f"reader stopped by an error in a callback: {exc!r}"
            self._stop.set()
            raise
        finally:
            if generation == self._generation:
                with self._port_lock:
                    self._close()

    def _deliver(self, items: list[SampleBatch | _StateChange | _InfoChange],
                 generation: int, queued: bool = True) -> None:
        """Hand ``items`` to the callbacks, in order (nothing once ``stop`` gave up);
        ``queued``: they came from the backlog, whose count keeps their samples until
        each is handed over."""
        backlog = self._backlog
        for item in items:
            if generation != self._generation:
                return
            kind = type(item)
            if kind is SampleBatch:
                if self._on_batch is not None:
                    self._on_batch(item)
                    continue
                on_sample = self._on_sample
                if queued:
                    backlog.held = len(item)  # still counted until handed over
                for sample in item:
                    if generation != self._generation:
                        return
                    if queued:
                        backlog.held -= 1
                    on_sample(sample)  # type: ignore[misc]
            elif kind is _InfoChange:
                if self._on_info is not None:
                    self._on_info(item.info)  # type: ignore[union-attr]
            elif self._on_state is not None:
                self._on_state(*item)  # type: ignore[misc]

    def _read_port(self) -> list[SampleBatch | _InfoChange] | None:
        """Open the port if needed, else wait up to ``read_timeout_s`` for data and parse
        what it brings. Returns the items to deliver at once when nothing is queued before
        them (the usual case: no hand-off through the backlog), else queues them."""
        if self._port is None:
            with self._port_lock:
                opened = self._open()
            if not opened:
                self._stop.wait(self._reopen_s)
            return None
        with self._port_lock:
            port = self._port
            if port is None:  # the drain thread lost it meanwhile
                return None
            try:
                data = self._read(port, self._read_timeout_ms)
            except (serial.SerialException, OSError) as exc:
                self._lost(exc)
                return None
            if data:
                items = self._ingest(data, queue=False)
                if not items or self._backlog.empty:
                    return items
                self._backlog.put(items)
                return None
        if (self._state is ConnectionState.CONNECTED
                and time.monotonic() - self._last_frame_mono > self._silence_s):
            self._set_state(
                ConnectionState.CONNECTING,
                f"no valid frame for {self._silence_s:g} s on {self.port} "
                "(device silent, wrong baud rate or wrong firmware?)",
            )
        return None

    def _read(self, port: serial.SerialBase, wait_ms: int) -> bytes:
        """What the port holds, up to ``READ_CHUNK`` bytes, after waiting up to
        ``wait_ms`` for the first byte (0: do not wait). A POSIX port is read by its
        descriptor: one poll and one read per chunk, where pyserial's ``read`` asks the
        size first and loops over ``select``."""
        fd = self._fd
        if fd is not None and self._poll is not None:
            if not self._poll.poll(wait_ms):
                return b""
            try:
                data = os.read(fd, READ_CHUNK)
            except BlockingIOError:
                return b""
            except InterruptedError:
                return b""
            if not data:  # Linux: a vanished device is readable and reads nothing
                raise serial.SerialException("device reports readiness to read but returned "
                                             "no data (device disconnected?)")
            if len(data) < MORE_WAITING:
                return data
            # A long read means the consumer fell behind and the port holds more (a
            # pseudo-terminal hands out 4 KiB, ~300 frames, per read): take everything it
            # holds now, so the newest sample is in this chunk, not seconds of reads away.
            parts, size = [data], len(data)
            while size < READ_CHUNK and self._poll.poll(0):
                try:
                    more = os.read(fd, READ_CHUNK - size)
                except (BlockingIOError, InterruptedError):
                    break
                if not more:
                    break
                parts.append(more)
                size += len(more)
            return b"".join(parts)
        waiting = port.in_waiting
        if not waiting and not wait_ms:
            return b""
        data = port.read(min(waiting, READ_CHUNK) or 1)
        more = port.in_waiting if data else 0
        return data + port.read(min(more, READ_CHUNK)) if more else data

    def _drain(self, generation: int) -> None:
        """The drain thread: read the port into the backlog while the consumer is busy."""
        while not self._stop.wait(self._drain_after_s) and generation == self._generation:
            since = self._busy_since
            if since is None or time.monotonic() - since < self._drain_after_s:
                continue
            with self._port_lock:
                port = self._port
                if port is None:
                    continue
                try:
                    while data := self._read(port, 0):
                        self._ingest(data)
                        if len(data) < READ_CHUNK:
                            break
                except (serial.SerialException, OSError) as exc:
                    self._lost(exc)

    def _open(self) -> bool:
        """Open the port (call with the port lock held); False with the state saying why."""
        try:
            port = serial.serial_for_url(self.port, baudrate=self.baudrate,
                                         timeout=self._read_timeout_s, do_not_open=True)
            port.open()
        except (serial.SerialException, OSError, ValueError) as exc:
            self._set_state(ConnectionState.DISCONNECTED, self._open_failure(exc))
            return False
        fd = getattr(port, "fd", None)
        if isinstance(port, serial.Serial) and isinstance(fd, int):
            self._fd, self._poll = fd, select.poll()
            self._poll.register(fd, select.POLLIN)
        else:
            self._fd = self._poll = None
        self._port = port
        with self._lock:
            self._connections += 1
            self._parser.reset()
            self._seq.restart()
            self._gate.restart()
        self._set_state(ConnectionState.CONNECTING, f"{self.port} open, waiting for frames")
        return True

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

    def _lost(self, exc: BaseException) -> None:
        """The port failed while reading (call with the port lock held)."""
        self._close()
        self._set_state(
            ConnectionState.DISCONNECTED,
            f"{self.port} failed ({exc.__class__.__name__}: {exc}); device "
            f"unplugged or reset? retrying every {self._reopen_s:g} s",
        )

    def _close(self) -> None:
        """Close the port if open (call with the port lock held)."""
        port, self._port = self._port, None
        self._fd = self._poll = None
        if port is not None:
            with contextlib.suppress(serial.SerialException, OSError):  # device already gone
                port.close()

    def _ingest(self, data: bytes, queue: bool = True) -> list[SampleBatch | _InfoChange]:
        """Parse a chunk into batches (call with the port lock held); queue them, or with
        ``queue`` False return them (a state change it causes is queued first)."""
        host_ns = time.time_ns()
        with self._lock:
            self._bytes += len(data)
            frames = self._parser.feed(data)
            if not frames:
                return []
            items = self._batches(frames, host_ns)
            self._last_frame_mono = time.monotonic()
        if self._state is not ConnectionState.CONNECTED:
            self._set_state(ConnectionState.CONNECTED, f"receiving frames from {self.port}")
        if queue and items:
            self._backlog.put(items)
            return []
        return items

    def _batches(self, frames: list[Frame | DeviceInfo], host_ns: int
                 ) -> list[SampleBatch | _InfoChange]:
        """Frames -> batches of samples and info changes, in stream order. A frame that
        its connection's info describes goes straight into the batch; the rest pass the
        info gate (the first frames, a version-1 stream, a contradicting channel count)."""
        seqr, gate, epoch = self._seq, self._gate, self._connections
        out: list[SampleBatch | _InfoChange] = []
        batch: SampleBatch | None = None
        info = gate.info
        top = _full_scale(info)
        for f in frames:
            if type(f) is Frame:
                if max(f.counts) > top:
                    # no converter of the stated resolution outputs it: garbage that passed
                    # the CRC, whose seq and clock would also skew the stream's timing
                    self._over_full_scale += 1
                    continue
                t_us = seqr.advance(f.seq, f.t_us)
                if (info is not None and f.version == info.version
                        and len(f.counts) == info.codes):
                    if batch is None:
                        batch = SampleBatch(epoch)
                        out.append(batch)
                    batch.append(f.seq, t_us, host_ns, f.counts)
                    continue
                released = gate.on_sample(Sample(f.seq, t_us, host_ns, f.counts, epoch),
                                          f.version)
            else:
                released = gate.on_info(f)
            info = gate.info
            top = _full_scale(info)
            for item in released:
                if type(item) is Sample:
                    if batch is None:
                        batch = SampleBatch(epoch)
                        out.append(batch)
                    batch.append(item.seq, item.device_time_us, item.host_time_ns,
                                 item.counts)
                else:
                    out.append(item)
                    batch = None
        return out


def _full_scale(info: DeviceInfo | None) -> int:
    """The largest code the device says it outputs (any 16-bit code before it says)."""
    return (1 << info.adc_bits) - 1 if info is not None and info.adc_bits else 0xFFFF


def _samples_in(item: object) -> int:
    """Samples an item of the reader's backlog holds (0 for state and info changes)."""
    return len(item) if type(item) is SampleBatch else 0
