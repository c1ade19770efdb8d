"""The real firmware sketch, compiled for this computer, read by the real reader and chain.

Builds of the unmodified ``firmware/tactile_adc/tactile_adc.ino``, chosen by the boards'
own macros: an Uno (10 bit, 5 V), a Pico (12 bit, 3.3 V) and an 8-channel Nano (the Uno's
MCU with A0-A7), and the modulated Uno and Nano (emitter on/off pairs, protocol 3).
Nothing is configured by hand:
counts become volts with what each device states. Skipped only where there is no g++.
"""

from __future__ import annotations

import os
import shutil
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from tactile_sensor.hardware.adc_frame import DeviceInfo, Frame, FrameParser
from tactile_sensor.hardware.adc_reader import AdcStreamReader
from tactile_sensor.hardware.adc_samples import Sample
from tactile_sensor.sensing.adc_settings import Source, resolve_adc
from tactile_sensor.sensing.calibration import Calibration
from tactile_sensor.sensing.chain import ChainConfig, SignalChain
from tactile_sensor.sensing.modulation import modulation_of
from tactile_sensor.sim import firmware_host
from tactile_sensor.sim.errors import SimError
from tactile_sensor.sim.firmware_host import NANO, PICO, UNO, Board, HostFirmware, build

pytestmark = [pytest.mark.skipif(firmware_host.compiler() is None,
                                 reason="no g++ on this computer (apt-get install g++)"),
              pytest.mark.slow]  # compiles the sketch and runs it as a process


@pytest.fixture(scope="session")
def build_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.getbasetemp() / "firmware-build"


class Stream:
    """The reader's output, collected; ``wait`` wakes on every sample and info."""

    def __init__(self) -> None:
        self.samples: list[Sample] = []
        self.infos: list[DeviceInfo] = []
        self.changed = threading.Condition()

    def on_sample(self, sample: Sample) -> None:
        with self.changed:
            self.samples.append(sample)
            self.changed.notify_all()

    def on_info(self, info: DeviceInfo) -> None:
        with self.changed:
            self.infos.append(info)
            self.changed.notify_all()

    def wait(self, predicate, timeout_s: float = 30.0) -> bool:
        with self.changed:
            return self.changed.wait_for(predicate, timeout_s)

    def count(self) -> int:
        with self.changed:
            return len(self.samples)

    def since(self, start: int) -> list[Sample]:
        with self.changed:
            return self.samples[start:]


def settled_counts(device: HostFirmware, stream: Stream, volts: float,
                   channel: int | None = None) -> list[tuple[int, ...]]:
    """Counts of ~50 frames sampled once the stimulus change reached the samples (the first
    within 2 codes of the new voltage; a busy host may take a while to get there)."""
    board = device.board
    expected = min(round(volts / board.vref_v * (1 << board.adc_bits)),
                   (1 << board.adc_bits) - 1)
    column = channel or 0
    begin = stream.count()
    device.set_voltage(volts, channel)

    def arrived() -> int | None:
        for k, sample in enumerate(stream.samples[begin:]):
            if abs(sample.counts[column] - expected) <= 2:
                return begin + k
        return None

    assert stream.wait(lambda: arrived() is not None), (volts, expected)
    start = arrived()
    assert start is not None
    assert stream.wait(lambda: len(stream.samples) > start + 50)
    return [s.counts for s in stream.since(start)]


@pytest.mark.parametrize("board", [UNO, PICO], ids=lambda b: b.name)
def test_each_board_states_what_it_sends(build_dir, tmp_path, board: Board):
    exe = build(board, build_dir)
    stream = Stream()
    with HostFirmware(exe, tmp_path / "adc", board), \
            AdcStreamReader(str(tmp_path / "adc"), stream.on_sample, on_info=stream.on_info):
        assert stream.wait(lambda: len(stream.samples) > 20)
    assert stream.infos[0] == DeviceInfo(2, 1, board.adc_bits, board.vref_v, 1000,
                                         "avr" if board is UNO else "rp2040")
    assert len(stream.infos) == 1  # repeated, unchanged: handed on once
    assert max(s.counts[0] for s in stream.samples) < 1 << board.adc_bits


@pytest.mark.parametrize("board", [UNO, PICO], ids=lambda b: b.name)
def test_volts_match_the_stimulus_within_one_code(build_dir, tmp_path, board: Board):
    exe = build(board, build_dir)
    stream = Stream()
    errors = []
    with HostFirmware(exe, tmp_path / "adc", board) as device, \
            AdcStreamReader(str(tmp_path / "adc"), stream.on_sample, on_info=stream.on_info):
        assert stream.wait(lambda: stream.infos)
        adc = resolve_adc(stream.infos[0])  # nothing configured: from the device
        assert adc.source is Source.DEVICE and adc.conversion is not None
        for volts in np.linspace(0.05, 3.25, 9):
            counts = settled_counts(device, stream, float(volts))
            errors += [adc.conversion.volts(c[0]) - volts for c in counts]
    lsb = board.vref_v / (1 << board.adc_bits)
    worst = float(np.max(np.abs(errors)))
    print(f"{board.name}: {board.adc_bits} bit, codes -> volts error worst {worst * 1e3:.2f} mV "
          f"(1 LSB = {lsb * 1e3:.2f} mV), mean {np.mean(errors) * 1e3:+.2f} mV")
    assert worst < lsb


def force_after_a_step(exe: Path, link: Path, board: Board, rest_v: float,
                       pressed_v: float, calibration: Calibration) -> float:
    """Rest (auto-tare), then a press: the force the chain reports, configured by nobody."""
    stream = Stream()
    chain = SignalChain(ChainConfig(), calibration)

    def on_info(info: DeviceInfo) -> None:
        stream.on_info(info)
        adc = resolve_adc(info)
        assert adc.conversion is not None, adc.problem
        chain.set_conversion(adc.conversion)

    def on_sample(sample: Sample) -> None:
        chain.process(sample)
        stream.on_sample(sample)

    with HostFirmware(exe, link, board) as device, \
            AdcStreamReader(str(link), on_sample, on_info=on_info):
        device.set_voltage(rest_v)
        assert stream.wait(lambda: chain.tared, 5.0)
        assert chain.baseline_v == pytest.approx(rest_v, abs=board.vref_v / (1 << board.adc_bits))
        settled_counts(device, stream, pressed_v)  # 50 samples past the step: the savgol
        assert chain.last is not None               # window (40 samples) is past it too
        return chain.last.force_n


def test_a_10_and_a_12_bit_board_give_the_same_force(build_dir, tmp_path):
    output = np.linspace(0.0, 0.5, 11)
    calibration = Calibration.from_curve(output.tolist(), (14.0 * output).tolist(), "test")
    forces = {board.name: force_after_a_step(build(board, build_dir), tmp_path / board.name,
                                             board, 3.0, 2.5, calibration)
              for board in (UNO, PICO)}
    print(f"force for a 0.5 V press: {forces}")
    # 1 LSB of the 10-bit board is 4.9 mV = 0.068 N here; both agree with the truth (7 N)
    assert forces["uno"] == pytest.approx(7.0, abs=2 * 14.0 * 5.0 / 1024)
    assert forces["pico"] == pytest.approx(7.0, abs=2 * 14.0 * 3.3 / 4096)
    assert abs(forces["uno"] - forces["pico"]) < 14.0 * 5.0 / 1024 * 2


def test_three_channels_parse_and_each_is_its_own_pin(build_dir, tmp_path):
    exe = build(UNO, build_dir, channels=3)
    stream = Stream()
    with HostFirmware(exe, tmp_path / "adc", UNO) as device, \
            AdcStreamReader(str(tmp_path / "adc"), stream.on_sample, on_info=stream.on_info):
        for channel, volts in enumerate((1.0, 2.0, 4.0)):
            device.set_voltage(volts, channel)
        assert stream.wait(lambda: stream.infos)
        counts = settled_counts(device, stream, 4.0, 2)
    assert stream.infos[0].channels == 3
    assert counts[-1] == (204, 409, 819)  # floor(V / 5 V * 1024)
    adc = resolve_adc(stream.infos[0], channel=2)
    assert adc.conversion is not None and adc.conversion.volts(counts[-1][2]) == \
        pytest.approx(4.0, abs=5.0 / 1024)
    assert "channel 3" in resolve_adc(stream.infos[0], channel=3).problem


def test_a_nano_streams_eight_channels_each_its_own_pin_on_the_fast_adc_clock(build_dir,
                                                                              tmp_path):
    exe = build(NANO, build_dir, channels=8)
    stream = Stream()
    volts = [0.5 * (c + 1) for c in range(8)]  # 0.5 .. 4.0 V, a different code per pin
    with HostFirmware(exe, tmp_path / "adc", NANO) as device, \
            AdcStreamReader(str(tmp_path / "adc"), stream.on_sample, on_info=stream.on_info):
        for channel, v in enumerate(volts[:-1]):
            device.set_voltage(v, channel)
        assert stream.wait(lambda: stream.infos)
        counts = settled_counts(device, stream, volts[-1], 7)
        stats = device.stats()
    assert stream.infos[0] == DeviceInfo(2, 8, 10, 5.0, 1000, "avr")
    assert counts[-1] == tuple(int(v / 5.0 * 1024) for v in volts)  # floor(V / 5 V * 1024)
    assert stats["adc_prescaler"] == 32  # 8 reads at F_CPU / 128 would fill the period


def test_more_channels_than_the_board_has_pins_do_not_compile(tmp_path):
    with pytest.raises(SimError, match="exceeds this board's analog inputs"):
        build(UNO, tmp_path / "out", channels=8)


def read_frames(fd: int, parser: FrameParser, seconds: float) -> list[Frame]:
    frames: list[Frame] = []
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        try:
            data = os.read(fd, 65536)
        except BlockingIOError:
            time.sleep(0.005)
            continue
        frames += [f for f in parser.feed(data) if isinstance(f, Frame)]
    return frames


def test_a_host_that_stops_reading_sees_gaps_the_sketch_never_blocks(build_dir, tmp_path):
    link = tmp_path / "adc"
    parser = FrameParser()
    with HostFirmware(build(UNO, build_dir), link, UNO) as device:
        fd = os.open(link, os.O_RDONLY | os.O_NONBLOCK | os.O_NOCTTY)
        try:
            before = read_frames(fd, parser, 0.3)
            time.sleep(3.0)  # the port's buffer (a few KB) fills in well under a second
            after = read_frames(fd, parser, 0.5)
        finally:
            os.close(fd)
        stats = device.stats()
    frames = before + after
    seqs = np.array([f.seq for f in frames])
    times = np.array([f.t_us for f in frames], dtype=np.int64)
    steps = np.diff(seqs) % 65536
    gaps = np.flatnonzero(steps > 1)
    assert len(gaps) >= 1, "no frame was dropped: did the sketch block on the host?"
    # The sketch kept sampling through the stall: the clock advanced with the sequence.
    # (A loaded host delays loop() now and then, and the sketch catches up with frames
    # stamped when they were taken, so the stamps stray from seq x 1 ms by that delay.)
    for g in gaps:
        expected = steps[g] * 1000
        assert times[g + 1] - times[g] == pytest.approx(expected, abs=0.05 * expected + 1e5)
    assert int(steps.sum()) >= 3000  # ~3.8 s of sampling went by
    assert stats["blocked_us"] == 0  # it never waited in Serial.write
    assert stats["adc_prescaler"] == 128  # one channel keeps the core's full-accuracy clock


def test_the_device_clock_wraps_and_is_unwrapped(build_dir, tmp_path):
    stream = Stream()
    with HostFirmware(build(UNO, build_dir), tmp_path / "adc", UNO,
                      micros_offset=(1 << 32) - 300_000), \
            AdcStreamReader(str(tmp_path / "adc"), stream.on_sample):
        assert stream.wait(lambda: len(stream.samples) > 800, 5.0)
    times = np.array([s.device_time_us for s in stream.samples])
    assert times[-1] > 1 << 32
    assert np.all(np.diff(times) > 0)


# -- error paths ------------------------------------------------------------------------------


def test_a_sketch_that_does_not_compile_is_one_clear_error(build_dir, tmp_path):
    folder = tmp_path / "firmware"
    shutil.copytree(firmware_host.firmware_dir(), folder)
    sketch = folder / "tactile_adc" / "tactile_adc.ino"
    sketch.write_text(sketch.read_text() + "\nint unused_and_wrong = ;\n")
    with pytest.raises(SimError, match="does not compile for uno"):
        build(UNO, tmp_path / "out", folder=folder)


def test_a_sketch_for_an_unknown_board_says_which_macros_to_define(tmp_path):
    with pytest.raises(SimError, match="define TACTILE_ADC_BITS"):
        build(Board("esp32", "ARDUINO_ARCH_ESP32", 3.3, 12), tmp_path / "out")


def test_a_missing_firmware_folder_names_the_override(tmp_path, monkeypatch):
    monkeypatch.setenv("TACTILE_FIRMWARE_DIR", str(tmp_path))
    with pytest.raises(SimError, match="TACTILE_FIRMWARE_DIR"):
        firmware_host.firmware_dir()


def test_no_compiler_is_one_clear_error(tmp_path, monkeypatch):
    monkeypatch.setenv("CXX", "no-such-compiler")
    with pytest.raises(SimError, match="install g\\+\\+"):
        build(UNO, tmp_path / "out")


def test_a_missing_build_and_a_stopped_device_are_clear_errors(build_dir, tmp_path):
    with pytest.raises(SimError, match="build it first"):
        HostFirmware(tmp_path / "nope", tmp_path / "adc", UNO).start()
    device = HostFirmware(build(UNO, build_dir), tmp_path / "adc", UNO)
    with pytest.raises(SimError, match="not running"):
        device.set_voltage(1.0)


def test_a_modulated_uno_sends_on_off_pairs_that_the_chain_reads_as_the_emitters_light(
        build_dir, tmp_path):
    exe = build(UNO, build_dir, modulated=True)
    stream = Stream()
    chain = SignalChain(ChainConfig(rate_hz=500.0, adc_bits=10, vref_v=5.0, auto_tare=False))
    with HostFirmware(exe, tmp_path / "adc", UNO) as device, \
            AdcStreamReader(str(tmp_path / "adc"), stream.on_sample, on_info=stream.on_info):
        device.set_off_voltage(4.0)  # the room's light alone, emitter off
        counts = settled_counts(device, stream, 1.0)  # the emitter's light on top of it
        stats = device.stats()
    info = stream.infos[0]
    # 500 Hz; each half period waits 1000 - 112 (one read at F_CPU/128) - 100 us
    assert info == DeviceInfo(3, 1, 10, 5.0, 2000, "avr", True, 788, 112)
    assert {c[1] for c in counts[5:]} == {int(4.0 / 5.0 * 1024)}  # the off code, every frame
    assert stats["emitter_pins"] == 1 and stats["emitter_switches"] >= len(counts)
    chain.set_modulation(modulation_of(info, 0))
    signal = [chain.process(s).voltage_v for s in stream.since(stream.count() - 20)]
    share = modulation_of(info, 0).share  # type: ignore[union-attr]
    expected = 5.0 - (int(4.0 / 5.0 * 1024) - int(1.0 / 5.0 * 1024)) * 5.0 / 1023 / share
    assert signal[-1] == pytest.approx(expected)


def test_a_modulated_nano_reads_eight_channels_on_and_off(build_dir, tmp_path):
    exe = build(NANO, build_dir, channels=8, modulated=True)
    stream = Stream()
    on = [0.25 * (c + 1) for c in range(8)]
    with HostFirmware(exe, tmp_path / "adc", NANO) as device, \
            AdcStreamReader(str(tmp_path / "adc"), stream.on_sample, on_info=stream.on_info):
        for channel, v in enumerate(on[:-1]):
            device.set_voltage(v, channel)
        device.set_off_voltage(4.5)
        counts = settled_counts(device, stream, on[-1], 7)
    assert stream.infos[0] == DeviceInfo(3, 8, 10, 5.0, 2000, "avr", True, 676, 28)
    assert counts[-1] == tuple(int(v / 5.0 * 1024) for v in [*on, *[4.5] * 8])


def test_a_host_that_knows_only_version_2_still_reads_the_plain_build(build_dir, tmp_path):
    """The plain build's bytes are version 2's: nothing a version-2 parser would refuse."""
    exe = build(UNO, build_dir)
    with HostFirmware(exe, tmp_path / "adc", UNO):
        fd = os.open(tmp_path / "adc", os.O_RDONLY | os.O_NONBLOCK)
        try:
            parser = FrameParser()
            frames = read_frames(fd, parser, 0.3)
        finally:
            os.close(fd)
    assert frames and {f.version for f in frames} == {2}
    assert parser.header_errors == 0 and parser.info_frames >= 1


def test_a_modulated_build_with_too_few_pins_does_not_compile(tmp_path):
    with pytest.raises(SimError, match="this board has too few pins for TACTILE_CHANNELS"):
        build(UNO, tmp_path / "out", modulated=True, defines=("TACTILE_EMITTER_PINS=13",))
