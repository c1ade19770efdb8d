"""Reference firmware benchmark: codes -> volts error per build, and the size on AVR boards.

1. Codes -> volts: the unmodified sketch, compiled for this computer as an Uno (10 bit,
   5 V) and a Pico (12 bit, 3.3 V) (``sim/firmware_host.py``), is swept over ``--steps``
   stimulus voltages from 1 % to 99 % of its reference. The host turns counts into volts
   with what the device states in its info frame (nothing configured), exactly as the
   driver does; the error against the stimulus is reported in mV and in codes (LSB), with
   what a fixed setting of 12 bit, 5 V (the info frame ignored) makes of the Uno's codes.
2. Size: ``firmware/build-avr.sh`` (``make firmware``) when avr-g++ is installed.

Run from the repository root after ``. scripts/env.sh``: ``python benchmarks/bench_firmware.py
[--plot errors.png]``.
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tactile_sensor"))

from results import Figure, write_results  # noqa: E402

from tactile_sensor.hardware.adc_frame import DeviceInfo  # noqa: E402
from tactile_sensor.hardware.adc_reader import AdcStreamReader  # noqa: E402
from tactile_sensor.hardware.adc_samples import Sample  # noqa: E402
from tactile_sensor.sensing.adc_settings import resolve_adc  # noqa: E402
from tactile_sensor.sensing.conversion import AdcConversion  # noqa: E402
from tactile_sensor.sim.firmware_host import PICO, UNO, Board, HostFirmware, build  # noqa: E402


def sweep(board: Board, exe: Path, link: Path, steps: int
          ) -> tuple[DeviceInfo, np.ndarray, np.ndarray]:
    """Stimulus voltages and the counts of the last frame sampled at each."""
    infos: list[DeviceInfo] = []
    last: list[Sample] = []
    changed = threading.Condition()

    def on_sample(sample: Sample) -> None:
        with changed:
            last[:] = [sample]
            changed.notify_all()

    stimulus = np.linspace(0.01, 0.99, steps) * board.vref_v
    counts = np.empty(steps, dtype=int)
    with HostFirmware(exe, link, board) as device, \
            AdcStreamReader(str(link), on_sample, on_info=infos.append):
        for i, volts in enumerate(stimulus):
            device.set_voltage(float(volts))
            time.sleep(0.01)  # the command reaches the sketch within a few loop() calls
            with changed:
                start = last[0].seq if last else -1
                changed.wait_for(lambda s=start: last and (last[0].seq - s) % 65536 > 3, 5.0)
                counts[i] = last[0].counts[0]
            if (i + 1) % 25 == 0 or i + 1 == steps:
                print(f"  {board.name}: {i + 1}/{steps} voltages", flush=True)
    return infos[0], stimulus, counts


def report(board: Board, info: DeviceInfo, stimulus: np.ndarray, counts: np.ndarray
           ) -> np.ndarray:
    adc = resolve_adc(info)
    assert adc.conversion is not None, adc.problem
    errors = counts * adc.conversion.volts_per_count - stimulus
    lsb = info.vref_v / (1 << info.adc_bits)
    print(f"{board.name}: device states {info.summary()}")
    print(f"  codes -> volts error over {len(stimulus)} voltages: worst "
          f"{np.max(np.abs(errors)) * 1e3:.2f} mV ({np.max(np.abs(errors)) / lsb:.2f} LSB), "
          f"RMS {np.sqrt(np.mean(errors ** 2)) * 1e3:.2f} mV, mean {np.mean(errors) * 1e3:+.2f} "
          f"mV; 1 LSB = {lsb * 1e3:.2f} mV")
    if board is UNO:
        old = counts * AdcConversion(12, 5.0).volts_per_count - stimulus
        print(f"  the same codes read as a fixed 12 bit, 5 V: worst error "
              f"{np.max(np.abs(old)):.2f} V (volts x {np.median(1 + old / stimulus):.3f})")
    return errors


def plot(path: Path, results: dict[str, tuple[np.ndarray, np.ndarray, float]]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4))
    for name, (stimulus, errors, lsb) in results.items():
        ax.plot(stimulus, errors * 1e3, ".", label=f"{name} (1 LSB = {lsb * 1e3:.2f} mV)")
    ax.set_xlabel("stimulus [V]")
    ax.set_ylabel("driver volts - stimulus [mV]")
    ax.set_title("Reference firmware, codes -> volts from the device's info frame")
    ax.legend()
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    print(f"plot: {path}")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=200, help="stimulus voltages per build")
    parser.add_argument("--plot", type=Path, default=None, help="write the error plot here")
    args = parser.parse_args()
    figures: list[Figure] = []
    with tempfile.TemporaryDirectory() as tmp:
        results = {}
        for board in (UNO, PICO):
            started = time.monotonic()
            exe = build(board, Path(tmp))
            print(f"{board.name}: host build of the sketch in {time.monotonic() - started:.1f} s")
            info, stimulus, counts = sweep(board, exe, Path(tmp) / f"{board.name}.pty",
                                           args.steps)
            errors = report(board, info, stimulus, counts)
            lsb = info.vref_v / (1 << info.adc_bits)
            results[board.name] = (stimulus, errors, lsb)
            worst = float(np.max(np.abs(errors)))
            figures += [Figure(f"{board.name}: worst codes -> volts error", worst * 1e3, "mV"),
                        Figure(f"{board.name}: worst error in codes", worst / lsb, "LSB"),
                        Figure(f"{board.name}: RMS error",
                               float(np.sqrt(np.mean(errors ** 2))) * 1e3, "mV")]
    if args.plot is not None:
        plot(args.plot, results)
    notes = f"{args.steps} stimulus voltages per build, from 1 % to 99 % of the reference."
    if shutil.which("avr-g++") is None:
        print("size: avr-g++ not installed (apt-get install gcc-avr avr-libc arduino-core-avr)")
        write_results("firmware", figures, notes=f"{notes} AVR sizes not measured (no avr-g++).")
        return 0
    started = time.monotonic()
    subprocess.run(["bash", str(ROOT / "firmware" / "build-avr.sh")], check=True,
                   env={"FIRMWARE_OUT": str(Path(tempfile.gettempdir()) / "tactile-firmware"),
                        "PATH": "/usr/bin:/bin"})
    print(f"make firmware took {time.monotonic() - started:.1f} s")
    write_results("firmware", figures, notes=f"{notes} AVR sizes: see `make firmware`.")
    return 0


if __name__ == "__main__":
    sys.exit(main())
