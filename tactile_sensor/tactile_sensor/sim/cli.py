"""``tactile-sensor mock adc|xm430``: run one mock device on a pseudo-terminal."""

from __future__ import annotations

import importlib
import sys

DEVICES: dict[str, tuple[str, str]] = {
    "adc": ("tactile_sensor.sim.adc_device", "photoreflector ADC streaming framed samples"),
    "xm430": ("tactile_sensor.sim.xm430_emulator", "Dynamixel XM430-W210 on Protocol 2.0"),
}


def main(argv: list[str]) -> int:
    if not argv or argv[0] in ("-h", "--help"):
        print("usage: tactile-sensor mock {adc,xm430} --link PATH [options]\n")
        for name, (_, help_) in DEVICES.items():
            print(f"  {name:<6} {help_}")
        return 0 if argv else 2
    if argv[0] not in DEVICES:
        print(f"tactile-sensor mock: unknown device '{argv[0]}'; choose adc or xm430.",
              file=sys.stderr)
        return 2
    module = importlib.import_module(DEVICES[argv[0]][0])
    return int(module.main(argv[1:]) or 0)
