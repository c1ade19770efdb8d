"""The mock ADC through the real reader on real pseudo-terminals, in and out of process."""

from __future__ import annotations

import itertools
import json
import math
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from tactile_sensor.hardware.adc_frame import DeviceInfo, Frame, FrameParser
from tactile_sensor.hardware.adc_reader import AdcStreamReader, ConnectionState
from tactile_sensor.physics.detector import DetectorState
from tactile_sensor.sensing.conversion import AdcConversion
from tactile_sensor.sensing.filters import make_filter
from tactile_sensor.sensing.modulation import emitter_levels
from tactile_sensor.sim import adc_device
from tactile_sensor.sim.adc_device import (
    QUIET,
    AdcNoise,
    AdcSampler,
    FixedSource,
    MockAdcDevice,
    white_noise_for_dynamic_range,
)
from tactile_sensor.sim.ambient_light import LightScene, LitSource
from tactile_sensor.sim.errors import SimError

SOURCE_DIR = Path(__file__).resolve().parents[2]


def collect(path, n, timeout_s=5.0, **reader_kw):
    got, done = [], threading.Event()

    def on_sample(s):
        got.append(s)
        if len(got) >= n:
            done.set()

    with AdcStreamReader(str(path), on_sample, **reader_kw):
        assert done.wait(timeout_s), f"only {len(got)} samples"
    return got


@pytest.mark.slow
def test_default_noise_gives_the_papers_dynamic_range(tmp_path):
    path = tmp_path / "adc"
    # the rate does not change per-sample noise; 10 kHz just keeps the test short
    with MockAdcDevice(path, lambda t: 1.98, rate_hz=10_000.0, seed=7):
        samples = collect(path, 20_000)
    volts = np.array([s.counts[0] for s in samples]) * AdcConversion().volts_per_count
    ma9 = make_filter("moving_average", 1000.0)
    filtered = np.array([ma9.update(v) for v in volts])[9:]
    resolution_n = filtered.std() / 0.07
    dynamic_range_db = 20 * math.log10(7.0 / resolution_n)
    assert dynamic_range_db == pytest.approx(31.5, abs=0.4)
    assert volts.mean() == pytest.approx(1.98, abs=0.005)


def test_noise_derivation():
    # 7 N / 10^(31.5/20) × 0.07 V/N × √9, minus a negligible quantisation share
    assert white_noise_for_dynamic_range() == pytest.approx(0.0391, abs=1e-4)
    with pytest.raises(SimError, match="quantisation"):
        white_noise_for_dynamic_range(dynamic_range_db=80.0, adc_bits=8)


def test_quiet_device_streams_the_source_exactly_at_its_rate(tmp_path):
    path = tmp_path / "adc"
    with MockAdcDevice(path, lambda t: 2.5, noise=QUIET, channels=3) as device:
        t0 = time.monotonic()
        samples = collect(path, 300)
        elapsed = time.monotonic() - t0
        assert device.stats().frames_generated >= 300
    assert {s.counts for s in samples} == {(2048, 2048, 2048)}
    assert elapsed > 0.25  # paced in real time, not as fast as possible


def raw_stream(path, frames, timeout_s=60.0):
    """Everything the device sent until ``frames`` data frames arrived, parsed (no reader in
    between). Counted in frames, the device's own time, never in wall-clock seconds: a busy
    host reads fewer frames per second, not a different stream."""
    parser, out, received = FrameParser(), [], 0
    fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_NOCTTY)
    try:
        deadline = time.monotonic() + timeout_s
        while received < frames and time.monotonic() < deadline:
            try:
                items = parser.feed(os.read(fd, 65536))
            except BlockingIOError:
                time.sleep(0.01)
                continue
            out += items
            received += sum(isinstance(i, Frame) for i in items)
    finally:
        os.close(fd)
    assert received >= frames, f"{received} of {frames} frames within {timeout_s} s"
    return out


def test_version_2_states_its_adc_four_times_a_second(tmp_path):
    path = tmp_path / "adc"
    with MockAdcDevice(path, lambda t: 1.0, noise=QUIET, adc_bits=10, vref_v=3.3,
                       channels=2, rate_hz=500.0):
        items = raw_stream(path, 550)  # 1.1 s of device time
    infos = [i for i in items if isinstance(i, DeviceInfo)]
    frames = [i for i in items if isinstance(i, Frame)]
    assert set(infos) == {DeviceInfo(2, 2, 10, 3.3, 2000, "mock")}
    # Every 0.25 s of device time = every 125th sample at 500 Hz, just before that sample,
    # whatever the host's pace.
    for before, item in itertools.pairwise(items):
        assert isinstance(before, DeviceInfo) == (isinstance(item, Frame)
                                                  and item.seq % 125 == 0), (before, item)
    assert len(infos) >= (frames[-1].seq - frames[0].seq) // 125
    assert len(infos) >= 4
    assert {f.version for f in frames} == {2}
    assert frames[-1].counts == (310, 310)  # round(1.0 V / 3.3 V * 1023)


class StepSource:
    """1 V, then 3 V from ``at_s`` on; ``step`` announces the change like ProtocolSource."""

    def __init__(self, announce: bool) -> None:
        self.at_s = math.inf
        if announce:
            self.revision = 0

    def __call__(self, t):
        return np.where(np.asarray(t, dtype=float) >= self.at_s, 3.0, 1.0)

    def step(self, at_s: float) -> None:
        self.at_s = at_s
        if hasattr(self, "revision"):
            self.revision += 1


class LateClock:
    """The device loop's clock and stop event: every wait oversleeps by ``late_s``, as a
    thread's wake-up does; ``writes`` emits, then the loop is told to stop."""

    def __init__(self, late_s: float, writes: int) -> None:
        self.now, self.late_s, self.left = 0.0, late_s, writes

    def monotonic(self) -> float:
        return self.now

    def wait(self, timeout: float) -> bool:
        self.now += timeout + self.late_s
        return False

    def is_set(self) -> bool:
        return self.left <= 0


@pytest.mark.parametrize(("rate", "per_write"), [(1000.0, 1), (500.0, 1), (10_000.0, 10)])
def test_frames_leave_when_they_fall_due_however_late_each_wake_up_is(tmp_path, monkeypatch,
                                                                       rate, per_write):
    # Each wake-up 0.1 ms late: a frame leaves at most that late, and the lateness does not
    # add up from one write to the next (it did: at 1 kHz frames left up to a period late).
    clock = LateClock(late_s=1e-4, writes=400)
    sent: list[tuple[float, int, int]] = []

    def emit(k: int, n: int) -> None:
        sent.append((clock.now, k, n))
        clock.left -= 1

    device = MockAdcDevice(tmp_path / "adc", StepSource(False), rate_hz=rate, noise=QUIET)
    try:
        monkeypatch.setattr(adc_device, "time", clock)
        monkeypatch.setattr(device, "_stop", clock)
        monkeypatch.setattr(device, "_emit", emit)
        monkeypatch.setattr(device, "_serve_link", lambda now: None)
        monkeypatch.setattr(device, "_flush", lambda: None)
        device._run()
    finally:
        monkeypatch.undo()
        device.link.close()
    lateness = [t - (k + n - 1) / rate for t, k, n in sent]
    assert max(lateness) <= 1.5e-4, max(lateness)
    # at most one write a millisecond: faster rates go in batches
    assert len(sent) <= sent[-1][0] * 1000 + 2
    assert all(n <= per_write + 1 for _, _, n in sent), sent[:5]


def read_frames_until(fd: int, parser: FrameParser, frames: list[Frame], n: int) -> None:
    """Read the device's port until ``frames`` holds ``n`` (a minute at most)."""
    deadline = time.monotonic() + 60.0
    while len(frames) < n and time.monotonic() < deadline:
        try:
            data = os.read(fd, 65536)
        except BlockingIOError:
            time.sleep(0.005)
            continue
        frames.extend(i for i in parser.feed(data) if isinstance(i, Frame))
    assert len(frames) >= n


def test_the_command_lines_fixed_profile_is_sampled_in_blocks(tmp_path):
    calls: list[int] = []

    def profile(t):
        calls.append(np.size(t))
        return np.full(np.shape(t), 1.0)

    parser, frames = FrameParser(), []
    with MockAdcDevice(tmp_path / "adc", FixedSource(profile), noise=QUIET):
        fd = os.open(tmp_path / "adc", os.O_RDONLY | os.O_NONBLOCK | os.O_NOCTTY)
        try:
            read_frames_until(fd, parser, frames, 300)
        finally:
            os.close(fd)
    streamed = [n for n in calls[1:] if n > 0]  # the first call probes for arrays
    assert sum(streamed) >= 300 and len(streamed) <= sum(streamed) / 20, streamed[:10]


@pytest.mark.parametrize("announce", [True, False])
def test_a_change_reaches_every_frame_after_it_sampled_ahead_or_not(tmp_path, announce):
    # An announcing source is sampled 50 ms ahead: frames already sampled must be sampled
    # again. One that does not announce is sampled as each frame falls due.
    path, source = tmp_path / "adc", StepSource(announce)
    parser, frames = FrameParser(), []
    with MockAdcDevice(path, source, noise=QUIET) as device:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_NOCTTY)
        try:
            read_frames_until(fd, parser, frames, 100)
            at_s = device.elapsed_s + 0.005
            source.step(at_s)
            read_frames_until(fd, parser, frames, len(frames) + 200)
        finally:
            os.close(fd)
    one_v, three_v = round(1.0 / 5.0 * 4095), round(3.0 / 5.0 * 4095)
    after = [f for f in frames if f.t_us >= at_s * 1e6]
    assert len(after) >= 100
    assert {f.counts for f in after} == {(three_v,)}
    assert {f.counts for f in frames if f.t_us < at_s * 1e6} == {(one_v,)}


def test_version_1_states_nothing(tmp_path):
    path = tmp_path / "adc"
    with MockAdcDevice(path, lambda t: 1.0, noise=QUIET, protocol=1):
        items = raw_stream(path, 600)
    assert items and all(isinstance(i, Frame) and i.version == 1 for i in items)


def test_commands_and_their_errors(tmp_path):
    device = MockAdcDevice(tmp_path / "adc", lambda t: 1.0)
    assert device.command("drop 3") == "ok drop 3 frames"
    assert device.command("garbage 10") == "ok garbage 10 bytes"
    assert device.command("unplug 0.5") == "ok unplug 0.5 s"
    assert device.busy
    assert device.command("unplug -1").startswith("error unplug duration")
    assert device.command("drop x").startswith("error")
    assert "unknown command" in device.command("explode")
    assert device.command("") == ""


@pytest.mark.parametrize(("kwargs", "match"), [
    ({"rate_hz": 0.0}, "rate"), ({"adc_bits": 20}, "adc_bits"), ({"vref_v": 0}, "vref_v"),
    ({"channels": 9}, "channels"), ({"voltage_source": 3.0}, "callable"),
    ({"protocol": 4}, "protocol"), ({"info_period_s": 0}, "info_period_s"),
    ({"protocol": 3}, "needs a source that gives emitter on/off pairs"),
    ({"noise": None, "link_path": "/nonexistent-dir/adc"}, "does not exist"),
])
def test_bad_device_settings(tmp_path, kwargs, match):
    args = {"link_path": tmp_path / "adc", "voltage_source": lambda t: 1.0, **kwargs}
    with pytest.raises(SimError, match=match):
        MockAdcDevice(**args).start()


def test_bad_noise_settings():
    with pytest.raises(SimError, match="white_v"):
        AdcNoise(white_v=-1.0)
    with pytest.raises(SimError, match="drift_tau_s"):
        AdcNoise(drift_tau_s=0.0)


def _cli(args, **kw):
    env = {**os.environ, "PYTHONPATH": str(SOURCE_DIR)}
    return subprocess.Popen([sys.executable, "-m", "tactile_sensor.sim.adc_device", *args],
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            **kw)


def _skin_table(tmp_path):
    path = tmp_path / "skin.json"
    d = np.linspace(0.0, 0.003, 7)
    path.write_text(json.dumps({"indentation_m": d.tolist(), "force_n": (d * 2333).tolist(),
                                "voltage_v": (1.98 - d * 163).tolist()}))
    return path


@pytest.mark.slow
def test_cli_streams_and_obeys_the_control_fifo(tmp_path):
    link, control = tmp_path / "adc", tmp_path / "adc.ctl"
    proc = _cli(["--link", str(link), "--skin-table", str(_skin_table(tmp_path)),
                 "--profile", "compression", "--control", str(control), "--duration", "30"])
    states, got = [], []

    def until(condition) -> bool:  # waits for the condition, bounded for a busy machine
        deadline = time.monotonic() + 30.0
        while not condition():
            if time.monotonic() > deadline:
                return False
            time.sleep(0.02)
        return True

    try:
        assert until(lambda: link.exists() and control.exists())
        reader = AdcStreamReader(str(link), got.append, lambda s, r: states.append(s))
        with reader:
            assert until(lambda: len(got) >= 100)
            with open(control, "w") as fifo:
                fifo.write("drop 5\n")
            # the gap shows once a frame after the dropped ones arrived
            assert until(lambda: reader.stats().dropped_frames >= 5)
            assert reader.stats().dropped_frames == 5
            with open(control, "w") as fifo:
                fifo.write("unplug 0.3\n")
            assert until(lambda: ConnectionState.DISCONNECTED in states)
            assert until(lambda: reader.state is ConnectionState.CONNECTED
                         and states[-1] is ConnectionState.CONNECTED)
        proc.terminate()  # SIGTERM: a clean stop, link and FIFO removed
        out, err = proc.communicate(timeout=10)
    finally:
        proc.kill()
    assert proc.returncode == 0, err
    assert "ok drop 5 frames" in out and "ok unplug 0.3 s" in out
    assert not link.exists() and not control.exists()


@pytest.mark.slow
@pytest.mark.parametrize(("args", "match"), [
    (["--profile", "squeeze"], "Unknown profile"),
    (["--skin-table", "/nonexistent.json"], "skin table"),
])
def test_cli_errors_are_one_sentence_not_a_traceback(tmp_path, args, match):
    table = ["--skin-table", str(_skin_table(tmp_path))] if "--skin-table" not in args else []
    proc = _cli(["--link", str(tmp_path / "adc"), *table, *args, "--duration", "0.1"])
    _, err = proc.communicate(timeout=20)
    assert proc.returncode == 1
    assert match in err and "Traceback" not in err


def test_sampler_drift_is_an_ornstein_uhlenbeck_process():
    sampler = AdcSampler(1000.0, AdcNoise(white_v=0.0, drift_v=0.05, drift_tau_s=0.01),
                         adc_bits=16, vref_v=5.0, rng=0)
    # in blocks, as the device calls it: the drift carries over between calls
    counts = np.concatenate([sampler.counts(np.full(n, 2.5)) for n in [1, 7, 500] * 60])
    drift = counts[:, 0] * (5.0 / 65535) - 2.5
    assert drift.std() == pytest.approx(0.05, rel=0.1)
    lag1 = np.corrcoef(drift[:-1], drift[1:])[0, 1]
    assert lag1 == pytest.approx(math.exp(-0.1), abs=0.02)


def test_a_modulated_device_sends_the_emitter_on_and_off_under_the_same_light(tmp_path):
    """Protocol 3: every channel's code with the emitter on, then off; the light of the
    scene in both, the emitter's part at the share the detector shows after each switch."""
    path = tmp_path / "adc"
    scene = LightScene(dc_ratio=0.2, sample_rate_hz=500.0)
    lit = LitSource(lambda t: np.full(np.shape(t), 2.0), scene, DetectorState(), 2.0)
    with MockAdcDevice(path, lit, noise=QUIET, adc_bits=12, rate_hz=500.0, channels=2,
                       protocol=3):
        items = raw_stream(path, 200)
    infos = {i for i in items if isinstance(i, DeviceInfo)}
    frames = [i for i in items if isinstance(i, Frame)]
    assert infos == {DeviceInfo(3, 2, 12, 5.0, 2000, "mock", True, 900, 0)}
    on_share, off_share = emitter_levels(900e-6, 2e-3)
    ambient = 0.2 * 3.0  # the ratio of the emitter's drop at rest, 3 V
    on, off = 5.0 - 3.0 * on_share - ambient, 5.0 - 3.0 * off_share - ambient
    assert {f.version for f in frames} == {3}
    assert frames[-1].counts == tuple(round(v / 5.0 * 4095) for v in (on, on, off, off))


def test_a_modulated_device_needs_time_to_settle(tmp_path):
    lit = LitSource(lambda t: np.full(np.shape(t), 2.0), LightScene(), DetectorState(), 2.0)
    with pytest.raises(SimError, match="leaves no time to settle"):
        MockAdcDevice(tmp_path / "adc", lit, rate_hz=5000.0, protocol=3)


def test_the_command_line_runs_a_modulated_device_in_the_dark_room(tmp_path):
    from tactile_sensor.sim.modulated_adc import dark_room_pairs

    class World:
        def module_voltages(self, t):
            return np.full(np.shape(t), 1.99)

    on, off = dark_room_pairs(World()).pair(np.zeros(3), 900e-6, 2e-3)
    on_share, off_share = emitter_levels(900e-6, 2e-3)
    assert on == pytest.approx(5.0 - 3.01 * on_share) and off == pytest.approx(
        5.0 - 3.01 * off_share)
