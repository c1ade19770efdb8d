"""Threaded reader of the ADC frame stream on a serial port (pyserial), unplug-proof.

The reader owns one thread. It opens the port, parses frames (``adc_frame.FrameParser``),
numbers them (sequence gaps, 64-bit device time) and hands each one to ``on_sample`` in
that thread. Any port failure (cable pulled, device reset, port missing at start) becomes
state ``DISCONNECTED`` with a reason, and the thread retries every ``reopen_interval_s``
until the device is back. Nothing here raises after construction.

A ROS node uses it like this::

    reader = AdcStreamReader("/dev/ttyACM0", on_sample=queue.put_nowait,
                             on_state=lambda state, reason: ...)
    reader.start()   # on_activate
    reader.stop()    # on_deactivate / on_cleanup
"""

from __future__ import annotations

import contextlib
import enum
import errno
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from types import TracebackType
from typing import NamedTuple

import serial

from tactile_sensor.hardware.adc_frame import MAX_CHANNELS, SEQ_MODULO, TIME_MODULO, FrameParser
from tactile_sensor.hardware.errors import SerialPortError

DEFAULT_BAUDRATE = 1_000_000
MIN_BAUDRATE = 50
MAX_BAUDRATE = 12_000_000


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


SampleCallback = Callable[[Sample], None]
StateCallback = Callable[[ConnectionState, str], None]


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
    with another channel count. Callbacks run in the reader thread: keep them short
    (hand samples to a queue or a ``SignalChain`` and return) and do not let them raise:
    an exception escaping a callback stops the reader (state STOPPED, reason says why).
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
        if not callable(on_sample) or (on_state is not None and not callable(on_state)):
            raise SerialPortError("on_sample and on_state must be callables.")
        self.port = port
        self.baudrate = baudrate
        self._on_sample = on_sample
        self._on_state = on_state
        self._reopen_s = float(reopen_interval_s)
        self._read_timeout_s = float(read_timeout_s)
        self._silence_s = float(silence_timeout_s)
        self._parser = FrameParser(channels)
        self._seq = _Sequencer()
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
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
            )

    def start(self) -> None:
        """Start the reader thread (idempotent)."""
        if self._thread is not None and self._thread.is_alive():
            return
        self._stop.clear()
        self._set_state(ConnectionState.CONNECTING, f"opening {self.port}")
        self._thread = threading.Thread(target=self._run, name=f"adc-reader:{self.port}",
                                        daemon=True)
        self._thread.start()

    def stop(self, timeout_s: float = 2.0) -> None:
        """Stop the thread and close the port; returns within about ``read_timeout_s``."""
        self._stop.set()
        thread, self._thread = self._thread, None
        if thread is not None and thread is not threading.current_thread():
            thread.join(timeout_s)
        self._set_state(ConnectionState.STOPPED, "stopped")

    def __enter__(self) -> AdcStreamReader:
        self.start()
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.stop()

    # -- thread ----------------------------------------------------------------------------

    def _set_state(self, state: ConnectionState, reason: str) -> None:
        if state is self._state and reason == self._reason:
            return
        with self._lock:
            self._state, self._reason = state, reason
        if self._on_state is not None:
            self._on_state(state, reason)

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

    def _run(self) -> None:
        try:
            self._loop()
        except BaseException as exc:
            # Only a callback can get here (port errors are states). Make the dead thread
            # visible in the state, then let threading.excepthook print the traceback.
            self._set_state(ConnectionState.STOPPED,
                            f"reader stopped by an error in a callback: {exc!r}")
            raise

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
            seqr = self._seq
            epoch = self._connections
            samples = [Sample(f.seq, seqr.advance(f.seq, f.t_us), host_ns, f.counts, epoch)
                       for f in frames]
            self._last_frame_mono = time.monotonic()
        if self._state is not ConnectionState.CONNECTED:
            self._set_state(ConnectionState.CONNECTED, f"receiving frames from {self.port}")
        on_sample = self._on_sample
        for sample in samples:
            on_sample(sample)
