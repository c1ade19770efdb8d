"""The reader against the mock ADC on real pseudo-terminals (no mocks of our own code)."""

from __future__ import annotations

import errno
import threading
import time

import numpy as np
import pytest
from waiting import wait_until

from tactile_sensor.hardware.adc_frame import DeviceInfo, crc16, encode_frame, encode_info
from tactile_sensor.hardware.adc_reader import AdcStreamReader, ConnectionState
from tactile_sensor.hardware.adc_samples import Sample, _InfoChange, _InfoGate
from tactile_sensor.hardware.errors import SerialPortError
from tactile_sensor.sim.adc_device import QUIET, MockAdcDevice
from tactile_sensor.sim.pty_link import PtyLink

RATE = 1000.0
# Upper bound of every wait on a condition: generous, because a wait ends as soon as its
# condition holds and a busy machine may be slow to get there (never a fixed sleep).
PATIENCE_S = 30.0


def code_ramp(t):
    """Voltage whose 12-bit code is the frame index mod 4096: every frame is checkable."""
    return (np.rint(np.asarray(t) * RATE) % 4096) * (5.0 / 4095)


class Recorder:
    def __init__(self) -> None:
        self.samples: list[Sample] = []
        self.states: list[tuple[float, ConnectionState, str]] = []
        self.lock = threading.Lock()

    def on_sample(self, sample: Sample) -> None:
        with self.lock:
            self.samples.append(sample)

    def on_state(self, state: ConnectionState, reason: str) -> None:
        with self.lock:
            self.states.append((time.monotonic(), state, reason))

    def count(self) -> int:
        with self.lock:
            return len(self.samples)

    def first_state_after(self, t0: float, state: ConnectionState) -> float | None:
        with self.lock:
            return next((t for t, s, _ in self.states if t >= t0 and s is state), None)


def reader_for(path, rec: Recorder, **kw) -> AdcStreamReader:
    return AdcStreamReader(str(path), rec.on_sample, rec.on_state, **kw)


def port_opened(reader: AdcStreamReader) -> bool:
    """The reader has opened the port (opening flushes its input: write only after)."""
    return reader.stats().connections >= 1


def test_missing_port_is_a_state_and_the_reader_connects_when_it_appears(tmp_path):
    path = tmp_path / "adc"
    rec = Recorder()
    with reader_for(path, rec) as reader:
        assert wait_until(lambda: reader.state is ConnectionState.DISCONNECTED)
        assert "does not exist" in reader.reason
        with MockAdcDevice(path, code_ramp, noise=QUIET):
            assert wait_until(lambda: rec.count() > 50)
            assert reader.state is ConnectionState.CONNECTED
    assert reader.state is ConnectionState.STOPPED


def test_unplug_is_reported_fast_and_data_resumes_without_restart(tmp_path):
    path = tmp_path / "adc"
    rec = Recorder()
    with MockAdcDevice(path, code_ramp, noise=QUIET) as device, reader_for(path, rec) as reader:
        assert wait_until(lambda: rec.count() > 100)
        t_unplug = time.monotonic()
        device.unplug(0.8)
        assert wait_until(lambda: rec.first_state_after(t_unplug, ConnectionState.DISCONNECTED))
        # Fast means: from the failed read itself, not from the 1 s silence timeout (which
        # would have gone to CONNECTING first). Not a latency bound: benchmarks/ measure it.
        with rec.lock:
            after = [(s, r) for t, s, r in rec.states if t >= t_unplug]
        assert after[0][0] is ConnectionState.DISCONNECTED, after
        assert " failed (" in after[0][1] and "unplugged" in after[0][1], after
        assert wait_until(lambda: not device.busy)  # link is back
        before = rec.count()
        assert wait_until(lambda: rec.count() > before + 50)  # resumed without a restart
        stats = reader.stats()
        assert stats.connections == 2
        assert stats.state is ConnectionState.CONNECTED
        with rec.lock:
            epochs = {s.epoch for s in rec.samples}
        assert epochs == {1, 2}


def last_frame_index(rec: Recorder) -> int:
    """Index k of the last delivered frame of ``code_ramp`` (device time k ms), or -1."""
    with rec.lock:
        return rec.samples[-1].device_time_us // 1000 if rec.samples else -1


def test_random_bytes_in_the_stream_yield_no_bad_sample(tmp_path):
    path = tmp_path / "adc"
    rec = Recorder()
    with MockAdcDevice(path, code_ramp, noise=QUIET, seed=3) as device, \
            reader_for(path, rec, channels=1) as reader:
        assert wait_until(lambda: rec.count() > 20)
        device.inject_garbage(100_000)
        assert wait_until(lambda: not device.busy)
        # Every garbage byte went out before this frame: once a sample from it (or later)
        # is delivered, the reader has read past all of the garbage.
        after_garbage = device.stats().frames_generated
        assert wait_until(lambda: last_frame_index(rec) >= after_garbage)
    # Counted once the reader has stopped and handed on what it had queued: read while it
    # runs, the parser's count and the delivered samples are taken at two moments.
    stats = reader.stats()
    assert device.stats().garbage_bytes == 100_000
    assert stats.bytes_discarded >= 90_000
    assert stats.resyncs >= 1
    with rec.lock:
        samples = list(rec.samples)
    for s in samples:  # each accepted frame is exactly what the device sent
        k, rem = divmod(s.device_time_us, 1000)
        assert rem == 0
        assert s.seq == k % 65536
        assert s.counts == (k % 4096,)
    assert stats.frames == len(samples)


def test_dropped_frames_are_counted(tmp_path):
    path = tmp_path / "adc"
    rec = Recorder()
    with MockAdcDevice(path, code_ramp, noise=QUIET) as device, reader_for(path, rec) as reader:
        assert wait_until(lambda: rec.count() > 20)
        device.drop_frames(7)
        assert wait_until(lambda: not device.busy)
        assert wait_until(lambda: reader.stats().dropped_frames == 7)
        assert reader.stats().sequence_gaps == 1


def test_device_time_is_unwrapped_past_32_bits(tmp_path):
    path = tmp_path / "adc"
    rec = Recorder()
    offset = (1 << 32) - 150_000  # the device clock wraps 0.15 s after start
    with MockAdcDevice(path, code_ramp, noise=QUIET, clock_offset_us=offset), \
            reader_for(path, rec):
        assert wait_until(lambda: rec.count() > 400)
    with rec.lock:
        times = np.array([s.device_time_us for s in rec.samples])
    assert times[-1] > 1 << 32
    assert np.all(np.diff(times) == 1000)


class Events:
    """Samples and infos in the order the reader handed them over."""

    def __init__(self) -> None:
        self.items: list[tuple[str, object]] = []
        self.lock = threading.Lock()

    def on_sample(self, sample: Sample) -> None:
        with self.lock:
            self.items.append(("sample", sample))

    def on_info(self, info: DeviceInfo) -> None:
        with self.lock:
            self.items.append(("info", info))

    def samples(self, epoch: int | None = None) -> list[Sample]:
        with self.lock:
            return [s for kind, s in self.items
                    if kind == "sample" and (epoch is None or s.epoch == epoch)]


def test_the_devices_info_comes_before_its_first_sample_on_every_connection(tmp_path):
    path = tmp_path / "adc"
    events = Events()
    with MockAdcDevice(path, code_ramp, noise=QUIET, vref_v=3.3) as device, \
            AdcStreamReader(str(path), events.on_sample, on_info=events.on_info) as reader:
        assert wait_until(lambda: len(events.samples()) > 50)
        device.unplug(0.3)
        assert wait_until(lambda: len(events.samples(2)) > 50)
        assert reader.device_info == DeviceInfo(2, 1, 12, 3.3, 1000, "mock")
    info = ("info", DeviceInfo(2, 1, 12, 3.3, 1000, "mock"))
    with events.lock:
        items = list(events.items)
    assert items[0] == info
    second = next(i for i, (kind, s) in enumerate(items) if kind == "sample" and s.epoch == 2)
    assert items[second - 1] == info
    assert sum(1 for item in items if item == info) == 2  # once per connection


def test_a_version_1_device_gets_an_info_that_states_nothing(tmp_path):
    path = tmp_path / "adc"
    events = Events()
    with MockAdcDevice(path, code_ramp, noise=QUIET, protocol=1), \
            AdcStreamReader(str(path), events.on_sample, on_info=events.on_info):
        assert wait_until(lambda: len(events.samples()) > 20)
    assert events.items[0] == ("info", DeviceInfo(1, 1))
    assert not events.items[0][1].described


def test_samples_wait_for_the_info_and_none_is_lost(tmp_path):
    path = tmp_path / "adc"
    events = Events()
    bad_info = b"\xa5\x5a\x20\x09" + bytes([0, 1, 0x88, 0x13, 0xE8, 3, 0, 0, 0])
    with PtyLink(path) as link, \
            AdcStreamReader(str(path), events.on_sample, on_info=events.on_info) as reader:
        assert wait_until(lambda: port_opened(reader))
        assert link.write_all(b"".join(encode_frame(k, k * 1000, [k]) for k in range(5)))
        assert link.write_all(bad_info + crc16(bad_info[2:]).to_bytes(2, "little"))
        # the bad info frame comes after the samples: wait until it is parsed as well
        assert wait_until(lambda: reader.stats().info_errors >= 1)
        assert events.items == []
        stats = reader.stats()
        assert stats.awaiting_info == 5
        assert stats.info_errors == 1 and "adc_bits 0" in stats.last_info_error
        assert link.write_all(encode_info(10, 1, 5.0, 1000, "avr") + encode_frame(5, 5000, [5]))
        assert wait_until(lambda: len(events.samples()) == 6)
        assert reader.stats().awaiting_info == 0
    assert events.items[0] == ("info", DeviceInfo(2, 1, 10, 5.0, 1000, "avr"))
    assert [s.seq for s in events.samples()] == list(range(6))


def test_a_code_over_the_stated_full_scale_is_dropped_and_counted(tmp_path):
    """A 10-bit device's frame with the code 1024 has a valid CRC but no converter of that
    resolution makes it: it is garbage the CRC let through (1 in 65,536). It is dropped
    before its seq and clock touch the stream's; the frames around it arrive."""
    path = tmp_path / "adc"
    events = Events()
    with PtyLink(path) as link, \
            AdcStreamReader(str(path), events.on_sample, on_info=events.on_info) as reader:
        assert wait_until(lambda: port_opened(reader))
        frames = [encode_frame(k, k * 1000, [1023 if k != 2 else 1024]) for k in range(4)]
        frames.insert(3, encode_frame(40_000, 7, [37_261]))  # random seq and clock
        assert link.write_all(encode_info(10, 1, 5.0, 1000, "avr") + b"".join(frames))
        assert wait_until(lambda: len(events.samples()) == 3
                          and reader.stats().over_full_scale == 2)
        assert link.write_all(encode_frame(4, 4000, [0]))
        assert wait_until(lambda: len(events.samples()) == 4)
        stats = reader.stats()
    assert [(s.seq, s.counts) for s in events.samples()] == [
        (0, (1023,)), (1, (1023,)), (3, (1023,)), (4, (0,))]
    assert [s.device_time_us for s in events.samples()] == [0, 1000, 3000, 4000]
    assert stats.sequence_resets == 0 and stats.dropped_frames == 1  # seq 2


def _sample(seq: int, channels: int = 1) -> Sample:
    return Sample(seq, seq * 1000, 0, (seq,) * channels, 1)


def test_the_info_gate_bounds_what_waits_and_refuses_a_contradicting_channel_count():
    gate = _InfoGate(max_waiting=3)
    assert all(gate.on_sample(_sample(k), 2) == [] for k in range(5))
    assert gate.dropped == 2
    info = DeviceInfo(2, 1, 12, 3.3, 1000)
    assert gate.on_info(info) == [_InfoChange(info), *(_sample(k) for k in (2, 3, 4))]
    assert gate.on_info(info) == []  # unchanged: not handed on again
    assert gate.on_sample(_sample(5, channels=2), 2) == []
    assert gate.mismatches == 1
    gate.on_sample(_sample(6), 1)  # a version-1 frame on the same link: the v1 rules apply
    assert gate.info == DeviceInfo(1, 1)
    gate.restart()
    assert gate.info is None and not gate.waiting


def test_silence_sends_the_state_back_to_connecting(tmp_path):
    path = tmp_path / "adc"
    rec = Recorder()
    with PtyLink(path) as link, reader_for(path, rec, silence_timeout_s=0.2) as reader:
        assert wait_until(lambda: port_opened(reader))
        assert link.write_all(b"".join(encode_frame(k, k * 1000, [k]) for k in range(5)))
        # The recorded states, not the current one: CONNECTED lasts only 0.2 s, which a
        # poll on a busy machine can miss.
        def after_connected() -> list[tuple[ConnectionState, str]]:
            with rec.lock:
                states = [(s, r) for _, s, r in rec.states]
            first = next((i for i, (s, _) in enumerate(states)
                          if s is ConnectionState.CONNECTED), None)
            return [] if first is None else states[first + 1:]

        assert wait_until(after_connected)
        state, reason = after_connected()[0]
        assert state is ConnectionState.CONNECTING and "no valid frame" in reason


@pytest.mark.parametrize(("kwargs", "match"), [
    ({"baudrate": 0}, "baudrate"),
    ({"baudrate": 115200.5}, "baudrate"),
    ({"baudrate": True}, "baudrate"),
    ({"reopen_interval_s": 0}, "reopen_interval_s"),
    ({"read_timeout_s": -1}, "read_timeout_s"),
    ({"silence_timeout_s": float("nan")}, "silence_timeout_s"),
    ({"channels": 0}, "channels"),
    ({"port": ""}, "port"),
    ({"on_sample": None}, "callable"),
    ({"on_batch": print}, "give one of on_sample .* and on_batch"),
    ({"on_sample": None, "on_batch": 3}, "must be callables"),
    ({"drain_after_s": 0.0}, "drain_after_s"),
    ({"backlog": 0}, "backlog capacity"),
    ({"read_period_s": -0.001}, "read_period_s"),
    ({"read_period_s": 1.0}, "read_period_s"),
    ({"read_period_s": float("nan")}, "read_period_s"),
])
def test_bad_configuration_is_refused_at_construction(kwargs, match):
    args = {"port": "/dev/ttyACM0", "on_sample": print, **kwargs}
    with pytest.raises(SerialPortError, match=match):
        AdcStreamReader(**args)


def test_a_raising_callback_stops_the_reader_visibly(tmp_path):
    path = tmp_path / "adc"
    states = []

    def broken(sample):
        raise ZeroDivisionError("consumer bug")

    hook, threading.excepthook = threading.excepthook, lambda args: None
    try:
        with MockAdcDevice(path, code_ramp, noise=QUIET), \
                AdcStreamReader(str(path), broken, lambda s, r: states.append((s, r))) as reader:
            assert wait_until(lambda: reader.state is ConnectionState.STOPPED)
            assert "consumer bug" in reader.reason
    finally:
        threading.excepthook = hook


class SlowSerialThread(AdcStreamReader):
    """The serial thread descheduled in the middle of its work (a busy machine)."""

    def _ingest(self, data: bytes, queue: bool = True) -> list:
        time.sleep(0.05)
        return super()._ingest(data, queue)


def test_a_reader_stopped_by_a_callback_stays_stopped(tmp_path):
    # Found beside a busy loop: the serial thread, inside _ingest when the dispatcher
    # stopped the reader, set CONNECTED again and the consumer's error was lost.
    path = tmp_path / "adc"

    def broken(sample):
        raise ZeroDivisionError("consumer bug")

    hook, threading.excepthook = threading.excepthook, lambda args: None
    try:
        with MockAdcDevice(path, code_ramp, noise=QUIET), \
                SlowSerialThread(str(path), broken, lambda s, r: None) as reader:
            assert wait_until(lambda: reader.state is ConnectionState.STOPPED)
            serial_thread = reader._thread
            assert serial_thread is not None
            serial_thread.join(PATIENCE_S)  # it has finished what it was doing
            assert reader.state is ConnectionState.STOPPED
            assert "consumer bug" in reader.reason
    finally:
        threading.excepthook = hook


class StalledConsumer(Recorder):
    """A consumer starved of CPU: its first sample blocks until ``release`` is set (or
    for at most twice the tests' patience, so a failed test leaves no thread behind)."""

    def __init__(self) -> None:
        super().__init__()
        self.release = threading.Event()

    def on_sample(self, sample: Sample) -> None:
        self.release.wait(2 * PATIENCE_S)
        super().on_sample(sample)


def test_a_stalled_consumer_loses_no_frame(tmp_path):
    # The device keeps no backlog of its own, so anything the pseudo-terminal (~18 KB,
    # 1.4 s of frames) cannot hold is lost. A reader that processed samples in its serial
    # thread lost ~1 s of frames here; the serial thread now keeps draining the port.
    path = tmp_path / "adc"
    rec = StalledConsumer()
    with MockAdcDevice(path, code_ramp, noise=QUIET, host_buffer_bytes=0) as device, \
            reader_for(path, rec) as reader:
        assert wait_until(lambda: reader.stats().frames > 0)
        # more than the pseudo-terminal holds, parsed and waiting, not lost
        assert wait_until(lambda: reader.stats().backlog > 2000)
        rec.release.set()
        assert wait_until(lambda: reader.stats().backlog == 0)
        stats = reader.stats()
    assert device.stats().bytes_lost == 0
    assert stats.dropped_frames == 0 and stats.backlog_dropped == 0
    assert stats.backlog_peak > 2000
    with rec.lock:
        seqs = np.array([s.seq for s in rec.samples])
    assert len(seqs) >= stats.frames - 1  # at most one still inside the callback
    assert np.all(np.diff(seqs) % 65536 == 1)


def test_a_full_backlog_drops_new_samples_and_counts_them(tmp_path):
    path = tmp_path / "adc"
    rec = StalledConsumer()
    with MockAdcDevice(path, code_ramp, noise=QUIET), \
            reader_for(path, rec, backlog=100) as reader:
        assert wait_until(lambda: reader.stats().backlog_dropped > 50)
        rec.release.set()
        assert wait_until(lambda: reader.stats().backlog == 0)
        stats = reader.stats()
        delivered = rec.count()
    assert stats.backlog_peak == 100
    # every parsed frame was either delivered or counted (one may be in the callback)
    assert stats.frames - 1 <= delivered + stats.backlog_dropped <= stats.frames


def test_stop_delivers_what_is_queued_or_counts_it(tmp_path):
    path = tmp_path / "adc"
    rec = StalledConsumer()
    with MockAdcDevice(path, code_ramp, noise=QUIET):
        reader = reader_for(path, rec)
        reader.start()
        assert wait_until(lambda: reader.stats().backlog > 200)
        start = time.monotonic()
        reader.stop(timeout_s=0.3)  # the consumer never gets going: give up, count
        # gave up: the consumer stays blocked for 2 * PATIENCE_S (not a latency bound;
        # stop() takes about 0.3 + 0.5 s on an idle machine)
        assert time.monotonic() - start < PATIENCE_S
        stats = reader.stats()
        assert stats.discarded_at_stop >= 200 and stats.backlog_dropped == 0
        assert reader.state is ConnectionState.STOPPED
        rec.release.set()
        assert wait_until(lambda: rec.count() == 1)  # the sample inside the callback ends
        time.sleep(0.1)
        assert rec.count() == 1  # nothing delivered after stop() returned

        rec2 = Recorder()
        reader = reader_for(path, rec2)
        reader.start()
        assert wait_until(lambda: rec2.count() > 20)
        reader.stop()
        stats = reader.stats()
    assert stats.backlog_dropped == 0
    assert rec2.count() == stats.frames  # everything parsed was delivered
    assert rec2.states[-1][1] is ConnectionState.STOPPED


def read_batches(path, frames: int, **reader_kw) -> tuple[list, list]:
    """(the batches, their samples) a batch reader of the mock got, ``frames`` at least,
    each checked to follow the last."""
    batches: list = []
    lock = threading.Lock()

    def on_batch(batch) -> None:
        with lock:
            batches.append(batch)

    with MockAdcDevice(path, code_ramp, noise=QUIET), \
            AdcStreamReader(str(path), on_batch=on_batch, **reader_kw) as reader:
        assert wait_until(lambda: reader.stats().frames > frames)
    samples = [s for b in batches for s in b]
    assert len(samples) == reader.stats().frames
    assert np.all(np.diff([s.seq for s in samples]) % 65536 == 1)
    return batches, samples


def test_batches_carry_every_frame_in_order_with_the_chunks_read_time(tmp_path):
    batches, samples = read_batches(tmp_path / "adc", 300)
    assert all(s.counts[0] == (s.device_time_us // 1000) % 4096 for s in samples)
    assert all(len(set(b.host_time_ns)) == 1 for b in batches[1:])  # one read, one time


def test_a_read_period_brings_the_samples_of_a_period_in_one_read_and_loses_none(tmp_path):
    batches, samples = read_batches(tmp_path / "adc", 1000, read_period_s=0.005)
    # at 1 kHz a 5 ms period reads about five frames at a time (a read waits for none)
    assert len(samples) / len(batches) > 3.0, (len(samples), len(batches))


def test_a_network_serial_port_url_is_read_like_a_device(tmp_path):
    """A pyserial URL (``socket://host:port``, e.g. a ser2net bridge) has no descriptor to
    poll: the reader asks pyserial what is waiting. Every frame arrives, in order."""
    import socket

    server = socket.create_server(("127.0.0.1", 0))
    host, port = server.getsockname()
    frames = 200

    opened = threading.Event()

    def serve() -> None:
        conn, _ = server.accept()
        with conn:
            opened.wait(PATIENCE_S)  # pyserial's socket open() flushes what arrived before
            conn.sendall(encode_info(12, 1, 5.0, 1000, "bridge"))
            for seq in range(frames):
                conn.sendall(encode_frame(seq, seq * 1000, [seq % 4096]))
                if seq % 20 == 0:
                    time.sleep(0.002)  # arrives in several chunks
            # keep the connection open until the reader has everything
            assert wait_until(lambda: rec.count() >= frames)

    rec = Recorder()
    sender = threading.Thread(target=serve, daemon=True)
    sender.start()
    with server, reader_for(f"socket://{host}:{port}", rec) as reader:
        assert wait_until(lambda: port_opened(reader)), reader.reason
        opened.set()
        assert wait_until(lambda: rec.count() >= frames), (rec.count(), reader.stats().frames)
        sender.join(PATIENCE_S)
        with rec.lock:
            counts = [s.counts[0] for s in rec.samples]
        assert counts == list(range(frames))
        assert reader.stats().connections == 1


@pytest.mark.parametrize(("code", "says"), [
    (errno.EACCES, "permission denied on /dev/ttyACM9; add the user to the 'dialout' group"),
    (errno.EPERM, "permission denied on /dev/ttyACM9"),
    (errno.EBUSY, "/dev/ttyACM9 is busy (another program has it open)"),
    (errno.EIO, "cannot open /dev/ttyACM9: [Errno 5] gone"),
])
def test_an_open_failure_names_its_cause_and_the_retry(code, says):
    rec = Recorder()
    reader = reader_for("/dev/ttyACM9", rec)
    reason = reader._open_failure(OSError(code, "gone"))
    assert reason.startswith(says) and reason.endswith("retrying every 0.2 s"), reason
