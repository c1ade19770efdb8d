"""The one user-facing command, ``tactile-sensor``, dispatching to each layer's entry point.

Subcommands import their layer lazily so ``tactile-sensor analyze`` does not pay for rclpy
and ``tactile-sensor mock`` does not pay for scikit-fem.
"""

from __future__ import annotations

import importlib
import sys

SUBCOMMANDS: dict[str, tuple[str, str]] = {
    # name: (module, help)
    "mock": ("tactile_sensor.sim.cli", "run a mock device on a pseudo-terminal (adc, xm430)"),
    "model": ("tactile_sensor.studies.cli", "finite-element prediction of the module (sweep)"),
    "analyze": ("tactile_sensor.analysis.cli", "characterise a rosbag2 recording"),
    "bringup": ("tactile_sensor.nodes.bringup", "run the bench or gripper configuration"),
    "bag": ("tactile_sensor.recording.cli", "recover a bag a killed recorder left (recover)"),
    "grasp": ("tactile_sensor.nodes.hand_commands:grasp",
              "grasp with a force on the running gripper, e.g. 'grasp 1.5'"),
    "release": ("tactile_sensor.nodes.hand_commands:release", "open the running gripper"),
    "tare": ("tactile_sensor.nodes.hand_commands:tare", "tare the running driver"),
    "self-check": ("tactile_sensor.nodes.hand_commands:self_check",
                   "fit the module's gain and the skin's stiffness on the rod"),
}


def usage() -> str:
    lines = ["usage: tactile-sensor <command> [options]", "", "commands:"]
    lines += [f"  {name:<10} {help_}" for name, (_, help_) in SUBCOMMANDS.items()]
    lines += ["", "Run 'tactile-sensor <command> --help' for a command's options."]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    if not args or args[0] in ("-h", "--help"):
        print(usage())
        return 0 if args else 2
    name, rest = args[0], args[1:]
    if name not in SUBCOMMANDS:
        print(f"tactile-sensor: unknown command '{name}'; choose one of "
              f"{', '.join(SUBCOMMANDS)}.", file=sys.stderr)
        return 2
    module_name, _, function = SUBCOMMANDS[name][0].partition(":")
    module = importlib.import_module(module_name)
    return int(getattr(module, function or "main")(rest) or 0)


if __name__ == "__main__":
    sys.exit(main())
