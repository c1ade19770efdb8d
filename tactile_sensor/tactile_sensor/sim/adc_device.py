"""Mock photoreflector ADC: streams framed samples on a pseudo-terminal in real time.

The device samples ``voltage_source(t)`` (t = seconds since ``start()``), adds white noise
and a slow ambient drift, quantises like a ``adc_bits`` ADC referenced to ``vref_v`` and
writes frames (``hardware.adc_frame``) at ``rate_hz``, paced by the monotonic clock and
written in batches of at most ~1 ms so it holds 1 kHz and reaches tens of kHz.

It speaks protocol version 2 like the reference firmware: an info frame stating its
``adc_bits``, ``vref_v``, channels and rate at start and every ``info_period_s`` (0.25 s,
as the firmware); ``protocol=1`` makes it a version-1 device that states nothing, and
``protocol=3`` a modulated one: each frame holds every channel's code with the emitter on,
then off, from a source with a ``pair`` (``sim.ambient_light.LitSource``).

Like the firmware it never blocks on a slow host. A pseudo-terminal buffers only ~18 KB,
a real USB serial port (ttyACM, tty flip buffers) about 64 KB more, so the device keeps
up to ``host_buffer_bytes`` of backlog that it hands to the pseudo-terminal as the host
drains it; whole batches that do not fit are lost (the reader sees the sequence gap).
Faults on command: ``unplug`` (the link disappears, the device keeps its clock and
sequence running, the link returns), ``inject_garbage`` (random bytes spliced into the
stream, possibly mid-frame) and ``drop_frames``.
"""

from __future__ import annotations

import argparse
import math
import signal
import struct
import sys
import threading
import time
from binascii import crc_hqx
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType
from typing import Any

import numpy as np

from tactile_sensor.hardware.adc_frame import (
    CRC_INIT,
    MAX_CHANNELS,
    PROTOCOL_VERSION,
    SUPPORTED_VERSIONS,
    SYNC,
    encode_info,
)
from tactile_sensor.sim.adc_control import ControlFifo
from tactile_sensor.sim.errors import SimError
from tactile_sensor.sim.modulated_adc import dark_room_pairs, modulation_timing
from tactile_sensor.sim.pty_link import PtyLink

VoltageSource = Callable[[float], float]

# The paper's figures behind the default noise (Sec. III-B): full scale 7 N at 3 mm,
# sensitivity 0.07 V/N, dynamic range 31.49 dB with a 9-point moving average at 1 kHz.
PAPER_FULL_SCALE_N = 7.0
PAPER_SENSITIVITY_V_PER_N = 0.07
PAPER_DYNAMIC_RANGE_DB = 31.5
PAPER_AVERAGE_POINTS = 9


def white_noise_for_dynamic_range(
    dynamic_range_db: float = PAPER_DYNAMIC_RANGE_DB,
    full_scale_n: float = PAPER_FULL_SCALE_N,
    sensitivity_v_per_n: float = PAPER_SENSITIVITY_V_PER_N,
    average_points: int = PAPER_AVERAGE_POINTS,
    adc_bits: int = 12,
    vref_v: float = 5.0,
) -> float:
    """White-noise σ [V] at the ADC input that yields ``dynamic_range_db``.

    Derivation (resolution = 1σ of the output after the N-point average):

    - DR = 20·log10(FS / resolution) → resolution = 7 N / 10^(31.5/20) = 0.186 N,
      i.e. 0.186 N × 0.07 V/N = 13.0 mV of module output.
    - An N-point average of white noise divides σ by √N, so the raw σ is
      √9 × 13.0 mV = 39.1 mV in total.
    - Quantisation contributes LSB/√12 (5 V / 4095 / √12 = 0.35 mV, white because the
      noise dithers it); the analogue white noise is the rest:
      σ_white = √(39.1² − 0.35²) mV ≈ 39.1 mV.

    The slow drift (``AdcNoise.drift_v``) is excluded: over the short windows in which a
    noise floor is measured it is a constant offset, which the tare removes.
    """
    resolution_v = full_scale_n / 10.0 ** (dynamic_range_db / 20.0) * sensitivity_v_per_n
    raw_v = resolution_v * math.sqrt(average_points)
    quantisation_v = vref_v / ((1 << adc_bits) - 1) / math.sqrt(12.0)
    if raw_v <= quantisation_v:
        raise SimError("The requested dynamic range is finer than the ADC's quantisation; "
                       "use more ADC bits or a smaller dynamic range.")
    return math.sqrt(raw_v**2 - quantisation_v**2)


@dataclass(frozen=True)
class AdcNoise:
    """Analogue imperfections added before quantisation.

    ``white_v``: white Gaussian σ [V] (default: the paper's 31.5 dB, see
    ``white_noise_for_dynamic_range``). ``drift_v``/``drift_tau_s``: ambient-light drift
    as an Ornstein–Uhlenbeck process (stationary σ, correlation time); 1 mV over minutes
    is well under the 13 mV resolution, matching the paper's "no drift over 100 cycles".
    """

    white_v: float = white_noise_for_dynamic_range()
    drift_v: float = 0.001
    drift_tau_s: float = 120.0

    def __post_init__(self) -> None:
        for name, value in (("white_v", self.white_v), ("drift_v", self.drift_v)):
            if not isinstance(value, int | float) or not 0.0 <= value <= 10.0:
                raise SimError(f"Noise {name} must be in [0, 10] V, got {value!r}.")
        if not isinstance(self.drift_tau_s, int | float) or not self.drift_tau_s > 0:
            raise SimError(f"Noise drift_tau_s must be > 0 s, got {self.drift_tau_s!r}.")


QUIET = AdcNoise(white_v=0.0, drift_v=0.0)


class AdcSampler:
    """The analogue front end and converter: voltages in, noisy quantised counts out.

    Stateful (the drift carries over between calls), so feed consecutive blocks of one
    stream. The mock device uses it per batch; benchmarks use it offline on whole runs.
    """

    def __init__(self, rate_hz: float, noise: AdcNoise | None = None, adc_bits: int = 12,
                 vref_v: float = 5.0, channels: int = 1,
                 rng: np.random.Generator | int | None = None) -> None:
        self.noise = noise if noise is not None else AdcNoise()
        self.channels = channels
        self._rng = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
        self._scale = ((1 << adc_bits) - 1) / vref_v
        self._full_scale = (1 << adc_bits) - 1
        self._a = math.exp(-1.0 / (rate_hz * self.noise.drift_tau_s))
        self._drift = np.zeros(channels)

    def counts(self, voltages_v: np.ndarray) -> np.ndarray:
        """Codes (shape ``(n, channels)``) for noise-free voltages of shape ``(n,)`` (the
        same voltage on every channel) or ``(n, channels)`` (one per channel: an array)."""
        v = np.asarray(voltages_v, dtype=float)
        v = v if v.ndim == 2 else v.reshape(-1, 1)
        return self.quantise(v + self.noise_v(len(v)))

    def noise_v(self, n: int) -> np.ndarray:
        """The next ``n`` samples' noise [V], shape ``(n, channels)``. It does not depend on
        the signal, so a device can draw it before it knows the voltages."""
        out = np.zeros((n, self.channels))
        noise = self.noise
        if noise.white_v > 0:
            out += self._rng.normal(0.0, noise.white_v, out.shape)
        if noise.drift_v > 0:  # Ornstein–Uhlenbeck, exact AR(1) discretisation
            a = self._a
            innov = self._rng.normal(0.0, noise.drift_v * math.sqrt(1 - a * a), out.shape)
            drift = _ar1(a, self._drift, innov)
            self._drift = drift[-1].copy()
            out += drift
        return out

    def quantise(self, voltages_v: np.ndarray) -> np.ndarray:
        """Codes for voltages that already carry their noise."""
        return np.clip(np.rint(voltages_v * self._scale), 0, self._full_scale).astype(np.int64)


def _ar1(a: float, start: np.ndarray, innov: np.ndarray) -> np.ndarray:
    """d_i = a·d_{i−1} + e_i, vectorised in blocks: d_i = a^i·(a·d_{−1} + Σ_{j≤i} a^{−j}·e_j).

    Blocks keep a^{−j} ≤ 1e6, so the sums stay accurate for any 0 < a < 1.
    """
    out = np.empty_like(innov)
    block = max(1, int(math.log(1e6) / -math.log(a))) if a < 1.0 else len(innov)
    d = start
    for s in range(0, len(innov), block):
        e = innov[s:s + block]
        j = np.arange(len(e))[:, None]
        out[s:s + block] = a**j * (a * d + np.cumsum(e * a ** (-j), axis=0))
        d = out[s + len(e) - 1]
    return out


@dataclass(frozen=True)
class DeviceStats:
    frames_generated: int
    frames_written: int  # accepted into the host buffer (not lost to an overflow)
    frames_dropped: int  # by drop_frames()
    frames_unplugged: int  # generated while the cable was out
    bytes_lost: int  # host buffer overflowed (host not reading fast enough)
    garbage_bytes: int
    unplugs: int
    plugged: bool


class MockAdcDevice:
    """A microcontroller ADC streaming frames on a pseudo-terminal at ``link_path``."""

    GARBAGE_CHUNK = 1024  # bytes of injected garbage per batch (~1 MB/s at most)
    #: How far ahead [s] a source that announces its changes is sampled, in one call.
    LOOKAHEAD_S = 0.05

    def __init__(
        self,
        link_path: Path | str,
        voltage_source: VoltageSource,
        rate_hz: float = 1000.0,
        noise: AdcNoise | None = None,
        adc_bits: int = 12,
        vref_v: float = 5.0,
        channels: int = 1,
        clock_offset_us: int = 0,
        seed: int | None = None,
        host_buffer_bytes: int = 65536,
        protocol: int = PROTOCOL_VERSION,
        info_period_s: float = 0.25,
        board: str = "mock",
    ) -> None:
        if not isinstance(rate_hz, int | float) or not 1.0 <= rate_hz <= 200_000.0:
            raise SimError(f"The ADC rate must be in [1, 200000] Hz, got {rate_hz!r}.")
        if isinstance(adc_bits, bool) or not isinstance(adc_bits, int) or not (
                1 <= adc_bits <= 16):
            raise SimError(f"adc_bits must be an integer 1..16, got {adc_bits!r}.")
        if not isinstance(vref_v, int | float) or not 0.0 < vref_v <= 100.0:
            raise SimError(f"vref_v must be a positive voltage, got {vref_v!r}.")
        if isinstance(channels, bool) or not isinstance(channels, int) or not (
                1 <= channels <= MAX_CHANNELS):
            raise SimError(f"channels must be 1..{MAX_CHANNELS}, got {channels!r}.")
        if isinstance(host_buffer_bytes, bool) or not isinstance(host_buffer_bytes, int) or \
                not 0 <= host_buffer_bytes <= 1 << 26:
            raise SimError(f"host_buffer_bytes must be 0..64 MiB, got {host_buffer_bytes!r}.")
        if protocol not in SUPPORTED_VERSIONS:
            raise SimError(f"protocol must be one of {SUPPORTED_VERSIONS}, got {protocol!r}.")
        if not isinstance(info_period_s, int | float) or not 0.0 < info_period_s <= 60.0:
            raise SimError(f"info_period_s must be in (0, 60] s, got {info_period_s!r}.")
        if not callable(voltage_source):
            raise SimError("voltage_source must be a callable t [s] -> V.")
        self._modulation = modulation_timing(protocol, rate_hz, voltage_source)
        codes = 2 * channels if self._modulation else channels
        self.link = PtyLink(link_path)
        self.rate_hz = float(rate_hz)
        self.noise = noise if noise is not None else AdcNoise()
        self.adc_bits = adc_bits
        self.vref_v = float(vref_v)
        self.channels = channels
        self.clock_offset_us = int(clock_offset_us)
        self._source = voltage_source
        self._vectorised = _is_vectorised(voltage_source)
        self._rng = np.random.default_rng(seed)
        self._backlog = bytearray()
        self._backlog_limit = host_buffer_bytes
        self._sampler = AdcSampler(rate_hz, self.noise, adc_bits, vref_v, codes, self._rng)
        self._frame = struct.Struct(f"<2sBHI{codes}H")
        self.protocol = protocol
        self._header = (protocol << 4) | channels
        # The firmware's info frame: every info_every-th frame is preceded by it.
        self._info = (encode_info(adc_bits, channels, vref_v, round(1e6 / rate_hz), board,
                                  self._modulation and (self._modulation[0], 0))
                      if protocol >= 2 else b"")
        self._info_every = max(1, round(info_period_s * rate_hz))
        # Frames sampled ahead of their time (see _frames): from sample _ahead_k on.
        self._ahead: list[bytes] = []
        self._ahead_noise = np.zeros((0, codes))
        self._noise_pool = np.zeros((0, codes))  # drawn, not yet given to a frame
        self._ahead_k = 0
        self._ahead_revision: Any = None
        self._ahead_n = max(1, int(self.rate_hz * self.LOOKAHEAD_S))
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._t0 = 0.0
        # fault requests (set from any thread, served by the writer thread)
        self._unplug_s: float | None = None
        self._replug_at: float | None = None
        self._garbage_pending = 0
        self._drop_pending = 0
        # counters
        self._generated = self._written = self._dropped = self._unplugged = 0
        self._bytes_lost = self._garbage = self._unplugs = 0

    # -- lifecycle -------------------------------------------------------------------------

    def start(self) -> None:
        """Create the link and start streaming (raises ``SimError`` if the link cannot be)."""
        if self._thread is not None:
            return
        self.link.open()
        self._stop.clear()
        self._t0 = time.monotonic()
        self._thread = threading.Thread(target=self._run, name="mock-adc", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        thread, self._thread = self._thread, None
        if thread is not None:
            thread.join(2.0)
        self.link.close()

    def __enter__(self) -> MockAdcDevice:
        self.start()
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.stop()

    @property
    def elapsed_s(self) -> float:
        """Device time [s] since start (the argument the voltage source receives)."""
        return time.monotonic() - self._t0

    # -- faults ----------------------------------------------------------------------------

    def unplug(self, duration_s: float = 1.0) -> None:
        """Pull the cable for ``duration_s``: the link disappears, then comes back."""
        if not isinstance(duration_s, int | float) or not 0.0 <= duration_s <= 3600.0:
            raise SimError(f"unplug duration must be in [0, 3600] s, got {duration_s!r}.")
        with self._lock:
            self._unplug_s = float(duration_s)

    def inject_garbage(self, n_bytes: int) -> None:
        """Splice ``n_bytes`` random bytes into the stream (spread over ~1 KB per batch)."""
        if isinstance(n_bytes, bool) or not isinstance(n_bytes, int) or not (
                0 <= n_bytes <= 100_000_000):
            raise SimError(f"garbage size must be 0..1e8 bytes, got {n_bytes!r}.")
        with self._lock:
            self._garbage_pending += n_bytes

    def drop_frames(self, n: int) -> None:
        """Skip the next ``n`` frames (their sequence numbers are never sent)."""
        if isinstance(n, bool) or not isinstance(n, int) or not 0 <= n <= 10_000_000:
            raise SimError(f"frames to drop must be 0..1e7, got {n!r}.")
        with self._lock:
            self._drop_pending += n

    @property
    def backlog_bytes(self) -> int:
        """Bytes generated but not yet taken by the host (waiting in the device)."""
        return len(self._backlog)

    @property
    def busy(self) -> bool:
        """True while an injected fault is still being served."""
        with self._lock:
            return bool(self._garbage_pending or self._drop_pending
                        or self._unplug_s is not None or self._replug_at is not None)

    def stats(self) -> DeviceStats:
        with self._lock:
            return DeviceStats(self._generated, self._written, self._dropped, self._unplugged,
                               self._bytes_lost, self._garbage, self._unplugs,
                               self.link.is_open)

    def command(self, line: str) -> str:
        """Run one control command (see ``--help``); returns a one-line answer."""
        words = line.split()
        if not words:
            return ""
        name, args = words[0].lower(), words[1:]
        try:
            if name == "unplug" and len(args) <= 1:
                seconds = float(args[0]) if args else 1.0
                self.unplug(seconds)
                return f"ok unplug {seconds:g} s"
            if name == "garbage" and len(args) == 1:
                self.inject_garbage(int(args[0]))
                return f"ok garbage {int(args[0])} bytes"
            if name == "drop" and len(args) == 1:
                self.drop_frames(int(args[0]))
                return f"ok drop {int(args[0])} frames"
            if name == "stats" and not args:
                return f"ok {self.stats()}"
        except (ValueError, SimError) as exc:
            return f"error {exc}"
        return (f"error unknown command '{line.strip()}'; use: unplug [SECONDS], garbage N, "
                "drop N, stats")

    # -- writer thread ---------------------------------------------------------------------

    def _run(self) -> None:
        rate = self.rate_hz
        max_batch = max(1, int(rate * 0.05))
        min_gap_s = 0.001  # at most ~1000 writes/s; higher rates go in batches
        k = 0
        last_write = -math.inf
        while not self._stop.is_set():
            now = time.monotonic()
            self._serve_link(now)
            self._flush()
            due = int((now - self._t0) * rate) + 1 - k
            if due <= 0:
                wake = max(self._t0 + k / rate, last_write + min_gap_s)
                self._stop.wait(max(0.0, wake - now))
                continue
            n = min(due, max_batch)
            self._emit(k, n)
            # The gap counts from when this write was due, not from when it went out:
            # counted from the write, each wake-up's lateness would add to the next, and at
            # 1 kHz frames would leave up to a period late (a sawtooth).
            last_write = max(self._t0 + k / rate, last_write + min_gap_s)
            k += n

    def _serve_link(self, now: float) -> None:
        with self._lock:
            unplug_s, self._unplug_s = self._unplug_s, None
            replug_at = self._replug_at
        if unplug_s is not None:
            self._backlog.clear()  # the host's buffers go with the cable
            if self.link.is_open:
                self.link.close()
                with self._lock:
                    self._unplugs += 1
            with self._lock:
                self._replug_at = now + unplug_s
            return
        if replug_at is not None and now >= replug_at:
            try:
                self.link.open()
            except (SimError, OSError):
                return  # e.g. the folder vanished; retry on the next batch
            with self._lock:
                self._replug_at = None

    def _voltages(self, times: np.ndarray) -> np.ndarray:
        if self._modulation:  # the on codes of every channel, then the off codes
            settle_us, period_s = self._modulation
            pair = self._source.pair(times, settle_us * 1e-6, period_s)  # type: ignore[attr-defined]
            shape = (len(times), self.channels)  # one voltage for all or one per channel
            return np.hstack([np.broadcast_to(np.asarray(v, dtype=float).reshape(len(times), -1),
                                              shape) for v in pair])
        if self._vectorised:
            v = np.asarray(self._source(times), dtype=float)
            if v.ndim == 2 and v.shape == (len(times), self.channels):
                return v  # one voltage per channel (a module array)
            if v.size != len(times):
                raise SimError(f"The voltage source gave shape {v.shape} for {len(times)} "
                               f"times; give (n,) or (n, {self.channels}) voltages.")
            return v.reshape(-1)
        return np.fromiter((self._source(float(t)) for t in times), float, len(times))

    def _frames(self, k: int, n: int) -> list[bytes]:
        """Frames ``k .. k+n-1``. Per-call numpy costs dominate at one frame a millisecond,
        so a source with a ``revision`` (bumped whenever what it will output changes, as
        ``ProtocolSource`` does when its protocol starts) is sampled up to ``LOOKAHEAD_S``
        ahead in one call, and sampled again when its revision moves. Any other source
        is sampled as its frames fall due: it may follow a world in motion (the gripper)."""
        if k != self._ahead_k:
            self._ahead, self._ahead_noise, self._ahead_k = [], self._ahead_noise[:0], k
        revision = getattr(self._source, "revision", None)
        changed = revision != self._ahead_revision
        if changed and self._ahead:
            self._ahead = self._pack(k, self._ahead_noise)
        self._ahead_revision = revision
        missing = n - len(self._ahead)
        if missing > 0:
            # ahead only once the source held still since the last call: a world in motion
            # (its revision moving each millisecond) is sampled as its frames fall due
            m = missing if revision is None or changed else max(missing, self._ahead_n)
            noise = self._next_noise(m)
            self._ahead += self._pack(k + len(self._ahead), noise)
            self._ahead_noise = np.concatenate([self._ahead_noise, noise])
        frames = self._ahead[:n]
        del self._ahead[:n]
        self._ahead_noise = self._ahead_noise[n:]
        self._ahead_k = k + n
        return frames

    def _next_noise(self, n: int) -> np.ndarray:
        """The next ``n`` samples' noise, drawn ``LOOKAHEAD_S`` at a time: the noise does not
        depend on the signal, and one draw per frame of a world in motion (the gripper's)
        was a third of the mock's CPU at 1 kHz."""
        pool = self._noise_pool
        if len(pool) < n:
            pool = np.concatenate([pool, self._sampler.noise_v(max(n, self._ahead_n))])
        self._noise_pool = pool[n:]
        return pool[:n]

    def _pack(self, k: int, noise: np.ndarray) -> list[bytes]:
        """Frames for samples ``k ..`` carrying ``noise`` (one row per sample)."""
        n = len(noise)
        times = (k + np.arange(n)) / self.rate_hz
        v = self._voltages(times)
        counts = self._sampler.quantise((v if v.ndim == 2 else v[:, None]) + noise)
        t_us = (np.rint(times * 1e6).astype(np.int64) + self.clock_offset_us) % (1 << 32)
        pack, sync, header = self._frame.pack, SYNC, self._header
        frames = []
        for i, (t, row) in enumerate(zip(t_us.tolist(), counts.tolist(), strict=True)):
            body = pack(sync, header, (k + i) & 0xFFFF, t, *row)
            frames.append(body + crc_hqx(body[2:], CRC_INIT).to_bytes(2, "little"))
        return frames

    def _emit(self, k: int, n: int) -> None:
        frames = self._frames(k, n)
        with self._lock:
            drop = min(self._drop_pending, n)
            self._drop_pending -= drop
            garbage = min(self._garbage_pending, self.GARBAGE_CHUNK)
            self._garbage_pending -= garbage
            self._generated += n
            self._dropped += drop
        parts = []
        info, every = self._info, self._info_every
        for i in range(n):
            if info and (k + i) % every == 0:
                parts.append(info)  # the info is sent even when frames are dropped
            if i >= drop:
                parts.append(frames[i])
        data = b"".join(parts)
        if garbage:
            cut = int(self._rng.integers(0, len(data) + 1))
            data = data[:cut] + self._rng.bytes(garbage) + data[cut:]
        if not self.link.is_open:
            with self._lock:
                self._unplugged += n - drop
                self._garbage += garbage
            return
        fits = len(self._backlog) + len(data) <= self._backlog_limit or not self._backlog
        with self._lock:
            self._garbage += garbage
            if fits:
                self._written += n - drop
            else:
                self._bytes_lost += len(data)
        if fits:
            self._backlog += data
            self._flush()

    def _flush(self) -> None:
        if self._backlog and self.link.is_open:
            written = self.link.write(bytes(self._backlog[:65536]))
            del self._backlog[:written]


class FixedSource:
    """A source whose output never changes once the device streams it, such as the
    command line's profile: its ``revision`` never moves, so the device samples it ahead in
    blocks (``MockAdcDevice._frames``) instead of as each frame falls due."""

    revision = 0

    def __init__(self, source: VoltageSource) -> None:
        self._source = source

    def __call__(self, t: Any) -> Any:
        return self._source(t)


def _is_vectorised(source: VoltageSource) -> bool:
    """Whether ``source`` maps an array of times to an array of voltages (much faster)."""
    probe = np.array([0.0, 1e-3])
    try:
        out = np.asarray(source(probe), dtype=float)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return False
    return out.shape == probe.shape or (out.ndim == 2 and out.shape[0] == probe.size)


# -- command line --------------------------------------------------------------------------

CONTROL_HELP = """\
control commands (one per line, written to the --control FIFO, e.g.
  echo 'unplug 1.5' > /tmp/adc.ctl):
  unplug [SECONDS]   remove the link for SECONDS (default 1), then bring it back
  garbage N          splice N random bytes into the stream
  drop N             skip the next N frames (sequence gap)
  stats              print the device's counters
"""


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="tactile-sensor mock adc",
        description="Mock photoreflector ADC: streams framed samples (docs/serial-frame.md) "
                    "on a pseudo-terminal whose symlink is --link, following the physics "
                    "chain for an indentation profile.",
        epilog=CONTROL_HELP, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--link", required=True, type=Path,
                        help="symlink to create for the device, e.g. /tmp/tactile_adc")
    parser.add_argument("--rate", type=float, default=1000.0, help="frames per second "
                        "(default 1000)")
    parser.add_argument("--profile", default="compression",
                        help="indentation profile: compression, repeatability, speeds, rest, "
                             "NAME:key=value,... or ramp:depth=0.003,speed=0.001,cycles=2,"
                             "hold=1 (SI units; default compression)")
    parser.add_argument("--loop", action="store_true", help="repeat the profile forever")
    parser.add_argument("--skin-table", type=Path, default=None,
                        help="JSON with arrays indentation_m, force_n, voltage_v to use "
                             "instead of the FEM prediction")
    parser.add_argument("--channels", type=int, default=1, help="channels per frame (1..8)")
    parser.add_argument("--adc-bits", type=int, default=12)
    parser.add_argument("--vref", type=float, default=5.0, help="ADC reference [V]")
    parser.add_argument("--protocol", type=int, default=PROTOCOL_VERSION,
                        choices=SUPPORTED_VERSIONS, help="serial protocol version: 2 states "
                        "bits, reference, channels and rate; 1 states nothing; 3 is a "
                        "modulated module (emitter on/off pairs; use --rate 500) (default "
                        "%(default)s)")
    parser.add_argument("--noise", type=float, default=AdcNoise().white_v,
                        help="white noise sigma [V] (default: the paper's 31.5 dB, %(default).4f)")
    parser.add_argument("--drift", type=float, default=AdcNoise().drift_v,
                        help="ambient drift sigma [V] (default %(default)g)")
    parser.add_argument("--drift-tau", type=float, default=AdcNoise().drift_tau_s,
                        help="ambient drift correlation time [s] (default %(default)g)")
    parser.add_argument("--seed", type=int, default=None, help="noise seed (reproducible runs)")
    parser.add_argument("--duration", type=float, default=None,
                        help="stop after this many seconds (default: until Ctrl-C)")
    parser.add_argument("--control", type=Path, default=None,
                        help="create a FIFO here that accepts control commands (below)")
    return parser


def _load_skin(path: Path | None) -> Any:
    from tactile_sensor.sim.skin_response import TabulatedSkin, default_skin

    if path is None:
        def progress(fraction: float, message: str) -> None:
            print(f"mock adc: FEM prediction {fraction * 100:5.1f} % {message}",
                  file=sys.stderr, flush=True)

        return default_skin(progress)
    import json

    try:
        data = json.loads(path.read_text(encoding="utf-8"))
        return TabulatedSkin(data["indentation_m"], data["force_n"], data["voltage_v"],
                             source=f"file:{path}")
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise SimError(f"Cannot use skin table {path} ({exc.__class__.__name__}: {exc}); it "
                       "must be JSON with arrays indentation_m, force_n, voltage_v.") from None


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        from tactile_sensor.sim.bench_world import BenchWorld
        from tactile_sensor.sim.profiles import parse_profile

        profile = parse_profile(args.profile)
        noise = AdcNoise(white_v=args.noise, drift_v=args.drift, drift_tau_s=args.drift_tau)
        skin = _load_skin(args.skin_table)
        world = BenchWorld(profile, skin, loop=args.loop)
        source = (dark_room_pairs(world) if args.protocol == 3
                  else FixedSource(world.module_voltages))
        device = MockAdcDevice(args.link, source,
                               rate_hz=args.rate,
                               noise=noise, adc_bits=args.adc_bits, vref_v=args.vref,
                               channels=args.channels, seed=args.seed,
                               protocol=args.protocol)
        device.start()
    except SimError as exc:
        print(f"tactile-sensor mock adc: {exc}", file=sys.stderr)
        return 1
    control = None
    stop = threading.Event()
    if threading.current_thread() is threading.main_thread():
        for sig in (signal.SIGINT, signal.SIGTERM):
            signal.signal(sig, lambda *_: stop.set())
    try:
        if args.control is not None:
            control = ControlFifo(args.control, device)
        print(f"mock adc: {device.rate_hz:g} Hz on {args.link} -> {device.link.slave_name}; "
              f"profile {args.profile} ({profile.duration_s:g} s{', looping' if args.loop else ''})"
              f"; skin {skin.source}"
              + (f"; control FIFO {args.control}" if control else ""), flush=True)
        stop.wait(args.duration)
    except SimError as exc:
        print(f"tactile-sensor mock adc: {exc}", file=sys.stderr)
        return 1
    finally:
        if control is not None:
            control.close()
        device.stop()
    print(f"mock adc: stopped; {device.stats()}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
