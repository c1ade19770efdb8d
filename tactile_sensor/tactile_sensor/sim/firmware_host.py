"""The reference firmware in the loop: the unmodified sketch, compiled for this computer.

The mock ADC (``adc_device``) is our own Python and agrees with our parser by
construction; the firmware is what users flash. So tests also compile
``firmware/tactile_adc/tactile_adc.ino`` with the system ``g++`` against our Arduino shim
(``firmware/host/``: ``micros()`` from the host clock, ``analogRead()`` from a stimulus set
here, ``Serial`` into a pseudo-terminal with the Uno's 64-byte transmit buffer) and run it
as a device the driver opens. A board is chosen by its own macro (``ARDUINO_ARCH_AVR``,
``ARDUINO_ARCH_RP2040``), exactly as the Arduino tools define it, so each build takes the
sketch's own resolution and reference for that board.

The firmware folder is found beside this source tree (``<repo>/firmware``) or at
``$TACTILE_FIRMWARE_DIR``.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import queue
import shutil
import subprocess
import threading
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType

from tactile_sensor.sim.errors import SimError

SKETCH = Path("tactile_adc") / "tactile_adc.ino"
SHIM = ("host/Arduino.h", "host/arduino_host.cpp")
CXXFLAGS = ("-std=gnu++11", "-O2", "-Wall", "-Wextra", "-Werror")


@dataclass(frozen=True)
class Board:
    """A board as the firmware sees it (its core's macro, and its variant's count of analog
    inputs, NUM_ANALOG_INPUTS, where the variant states one) and as physics does (its real
    ADC reference, which the shim's analogRead divides by)."""

    name: str
    macro: str
    vref_v: float
    adc_bits: int  # what the sketch should send on it (tests compare with the info frame)
    analog_inputs: int | None = None


UNO = Board("uno", "ARDUINO_ARCH_AVR", 5.0, 10, analog_inputs=6)   # ATmega328P DIP: A0-A5
NANO = Board("nano", "ARDUINO_ARCH_AVR", 5.0, 10, analog_inputs=8)  # TQFP: A0-A7
PICO = Board("pico", "ARDUINO_ARCH_RP2040", 3.3, 12)
BOARDS = {board.name: board for board in (UNO, NANO, PICO)}


def firmware_dir() -> Path:
    """The repository's firmware folder (``$TACTILE_FIRMWARE_DIR`` overrides)."""
    override = os.environ.get("TACTILE_FIRMWARE_DIR")
    folder = Path(override) if override else Path(__file__).resolve().parents[3] / "firmware"
    if not (folder / SKETCH).is_file():
        raise SimError(f"The firmware sketch {folder / SKETCH} does not exist; run from the "
                       "source tree or set TACTILE_FIRMWARE_DIR to the firmware folder.")
    return folder


def compiler() -> str | None:
    """The host C++ compiler (``$CXX`` or ``g++``), or None if there is none."""
    return shutil.which(os.environ.get("CXX", "g++"))


def build(board: Board, out_dir: Path, channels: int | None = None,
          folder: Path | None = None, modulated: bool = False,
          defines: tuple[str, ...] = ()) -> Path:
    """Compile the sketch for ``board`` on this computer; returns the executable.
    ``modulated`` builds the modulated image (protocol 3, emitters on pin 2); ``defines``
    are further ``NAME=VALUE`` macros.

    A build whose sources and flags are unchanged is reused (the name holds their hash),
    so a test session compiles each variant once.
    """
    cxx = compiler()
    if cxx is None:
        raise SimError("No C++ compiler found (g++ or $CXX); install g++ (apt-get install "
                       "g++) to run the firmware on this computer.")
    folder = folder or firmware_dir()
    sources = [folder / SKETCH, *(folder / s for s in SHIM)]
    flags = [*CXXFLAGS, f"-D{board.macro}", f"-I{folder / 'host'}"]
    if board.analog_inputs is not None:
        flags.append(f"-DNUM_ANALOG_INPUTS={board.analog_inputs}")
    if channels is not None:
        flags.append(f"-DTACTILE_CHANNELS={channels}")
    if modulated:
        flags.append("-DTACTILE_MODULATED=1")
    flags += [f"-D{define}" for define in defines]
    digest = hashlib.sha256(" ".join([cxx, *flags]).encode())
    for source in sources:
        digest.update(source.read_bytes())
    exe = Path(out_dir) / f"tactile_adc-{board.name}-{digest.hexdigest()[:12]}"
    if exe.is_file():
        return exe
    Path(out_dir).mkdir(parents=True, exist_ok=True)
    tmp = exe.with_suffix(f".{os.getpid()}.tmp")
    argv = [cxx, *flags, "-x", "c++", str(sources[0]), "-x", "c++", str(sources[2]),
            "-o", str(tmp), "-lutil"]
    result = subprocess.run(argv, capture_output=True, text=True, timeout=300, check=False)
    if result.returncode != 0:
        raise SimError(f"The firmware does not compile for {board.name} on this computer "
                       f"({' '.join(argv)}):\n{result.stderr.strip()}")
    os.replace(tmp, exe)
    return exe


class HostFirmware:
    """A host build of the firmware running as a serial device at ``link``.

    ``set_voltage`` is the stimulus on the board's analog pins; ``stats`` what the shim
    counted (bytes handed to the port, time the sketch spent blocked in Serial.write) and
    the AVR ADC clock divider the sketch selected (``adc_prescaler``, 0 off AVR).
    """

    def __init__(self, exe: Path, link: Path | str, board: Board,
                 micros_offset: int = 0) -> None:
        self.exe = Path(exe)
        self.link = Path(link)
        self.board = board
        self.micros_offset = micros_offset
        self._proc: subprocess.Popen[str] | None = None
        self._lines: queue.Queue[str] = queue.Queue()
        self._lock = threading.Lock()

    def start(self, timeout_s: float = 10.0) -> None:
        argv = [str(self.exe), "--link", str(self.link), "--vref", f"{self.board.vref_v:g}",
                "--micros-offset", str(self.micros_offset)]
        try:
            self._proc = subprocess.Popen(argv, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                          stderr=subprocess.PIPE, text=True, bufsize=1)
        except OSError as exc:
            raise SimError(f"Cannot run the firmware build {self.exe} ({exc.strerror}); build "
                           "it first with firmware_host.build().") from None
        threading.Thread(target=self._read_stdout, daemon=True).start()
        try:
            first = self._lines.get(timeout=timeout_s)
        except queue.Empty:
            first = ""
        if not first.startswith("pty "):
            self.stop()
            raise SimError(f"The firmware on this computer did not start ({argv}): "
                           f"{first or 'no answer'} {self._stderr()}".strip())

    def _read_stdout(self) -> None:
        proc = self._proc
        assert proc is not None and proc.stdout is not None
        for line in proc.stdout:
            self._lines.put(line.strip())

    def _stderr(self) -> str:
        proc = self._proc
        if proc is None or proc.poll() is None or proc.stderr is None:
            return ""
        return proc.stderr.read().strip()

    def _send(self, line: str) -> None:
        proc = self._proc
        if proc is None or proc.poll() is not None or proc.stdin is None:
            raise SimError(f"The firmware at {self.link} is not running; start() it first.")
        with self._lock:
            proc.stdin.write(line + "\n")
            proc.stdin.flush()

    def set_voltage(self, volts: float, channel: int | None = None) -> None:
        """Put ``volts`` on one channel's pin (A0 + channel), or on every channel."""
        self._send(f"volts {volts!r}" if channel is None else f"volts {channel} {volts!r}")

    def set_off_voltage(self, volts: float, channel: int | None = None) -> None:
        """What the pin reads while a modulated sketch has its emitters off (until set:
        the ``set_voltage`` value)."""
        self._send(f"off {volts!r}" if channel is None else f"off {channel} {volts!r}")

    def stats(self, timeout_s: float = 5.0) -> dict[str, int]:
        self._send("stats")
        try:
            line = self._lines.get(timeout=timeout_s)
        except queue.Empty:
            raise SimError("The firmware did not answer 'stats'.") from None
        if not line.startswith("stats "):
            raise SimError(f"The firmware answered {line!r} to 'stats'.")
        return {key: int(value) for key, value in (kv.split("=") for kv in line.split()[1:])}

    def stop(self) -> None:
        proc, self._proc = self._proc, None
        if proc is None:
            return
        with contextlib.suppress(OSError):
            if proc.stdin is not None:
                proc.stdin.close()  # EOF on stdin ends the firmware's loop
        try:
            proc.wait(5.0)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(5.0)

    def __enter__(self) -> HostFirmware:
        self.start()
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.stop()
