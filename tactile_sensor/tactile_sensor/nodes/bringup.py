"""``tactile-sensor bringup CONFIGURATION`` (bench, gripper, gripper_shear, array, wrench,
bend): a launch file's job without launch.

Composes the configuration's nodes in one process and one executor (as ros2/demos composes
nodes), loads the same config files as ``launch/*.launch.py`` (both read
:mod:`tactile_sensor.configurations`), drives the lifecycle transitions, optionally records
a bag, runs the selected protocol, and shuts down cleanly at its end or on Ctrl-C.
"""

from __future__ import annotations

import argparse
import math
import signal
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import yaml

from tactile_sensor.configurations import CONFIGURATIONS, Configuration, config_dir


class BringupError(Exception):
    """A bringup option a user gave cannot work; the message says which and how to fix it."""


def parse_args(argv: Sequence[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog="tactile-sensor bringup",
        description="Run the bench, gripper, gripper_shear, array, wrench or bend "
                    "configuration in one process (no launch needed).")
    parser.add_argument("configuration", choices=sorted(CONFIGURATIONS))
    parser.add_argument("--duration", type=float, default=None,
                        help="stop after this many seconds (default: end of the protocol; "
                             "run until Ctrl-C when the protocol has no end)")
    parser.add_argument("--record", type=Path, default=None,
                        help="record the configuration's topics to this rosbag2 (MCAP) folder")
    parser.add_argument("--protocol", default=None,
                        help="; ".join(f"{name}: {' | '.join(protocols)}" for name, protocols
                                       in _protocol_table().items())
                             + " (config/protocols.yaml; the first is the default); "
                             "gripper idle stays up for 'tactile-sensor grasp' and "
                             "'release' from another shell; "
                             "NAME:key=value,... overrides its fields, e.g. "
                             "repeatability:cycles=5 or speeds:cycles=1,rest=0.5; "
                             "ambient:scenario=dark|office|sunlight|shadow sets its light")
    parser.add_argument("--namespace", default="", help="ROS namespace of every node")
    parser.add_argument("--no-mock", action="store_true",
                        help="use real devices at the given ports instead of mock hardware")
    parser.add_argument("--port", action="append", default=[], metavar="NAME=PATH",
                        help="device path, e.g. adc_port=/dev/ttyACM0 (repeatable)")
    parser.add_argument("--config", type=Path, default=None,
                        help="extra ROS parameter file applied after the defaults")
    return parser.parse_args(list(argv))


def _protocol_table() -> dict[str, Any]:
    return yaml.safe_load((config_dir() / "protocols.yaml").read_text()) or {}


def protocol_parameters(configuration: str, protocol: str | None) -> dict[str, Any]:
    """The parameter set a protocol name stands for (config/protocols.yaml), with the
    overrides of ``NAME:key=value,...`` (keys without ``protocol.``, values in the YAML's
    units, several speeds joined by '/'), e.g. ``speeds:cycles=1`` for a short run."""
    protocols = _protocol_table().get(configuration, {})
    if protocol is None:
        protocol = next(iter(protocols), None)
        if protocol is None:
            return {}
    name, _, overrides = protocol.partition(":")
    if name not in protocols:
        raise BringupError(
            f"Unknown {configuration} protocol '{name}'; choose one of "
            f"{', '.join(protocols) or 'none'} (config/protocols.yaml).")
    params = {"protocol.name": name, **(protocols[name] or {})}
    for item in filter(None, (i.strip() for i in overrides.split(","))):
        params.update(_override(params, item, protocol))
    return params


def _override(params: dict[str, Any], item: str, spec: str) -> dict[str, Any]:
    """One ``key=value`` of a protocol spec, typed like the value it replaces."""
    key, sep, text = item.partition("=")
    name = f"protocol.{key.strip()}"
    if not sep or name not in params or name == "protocol.name":
        keys = ", ".join(k.removeprefix("protocol.") for k in params if k != "protocol.name")
        raise BringupError(f"Cannot read '{item}' in --protocol {spec!r}; use key=value with "
                           f"keys {keys or '(none for this protocol)'}.")
    old = params[name]
    try:
        if isinstance(old, list):
            value: Any = [float(v) for v in text.split("/")]
        elif isinstance(old, bool) or not isinstance(old, int | float):
            value = text
        elif isinstance(old, int):
            value = int(text)
        else:
            value = float(text)
    except ValueError:
        raise BringupError(f"--protocol value '{item}' is not a number of the kind "
                           f"'{key.strip()}' takes (as in config/protocols.yaml).") from None
    return {name: value}


def resolve_ports(configuration: Configuration, given: list[str],
                  use_mock: bool = True) -> dict[str, str]:
    """Device paths by port name: the mock's defaults, or with real devices every one
    given (a mock's path would only time out)."""
    ports = {name: default for name, (default, _) in configuration.ports.items()}
    named: set[str] = set()
    for item in given:
        name, sep, path = item.partition("=")
        if not sep or name not in ports or not path:
            raise BringupError(
                f"--port {item!r} is not NAME=PATH with NAME one of {', '.join(ports)}.")
        ports[name] = path
        named.add(name)
    missing = [name for name in ports if name not in named]
    if not use_mock and missing:
        raise BringupError(
            "--no-mock needs the device path of every port: add "
            + " ".join(f"--port {name}=/dev/..." for name in missing)
            + f" (e.g. --port {missing[0]}={_EXAMPLE_DEVICE.get(missing[0], '/dev/ttyUSB0')}).")
    return ports


_EXAMPLE_DEVICE = {"adc_port": "/dev/ttyACM0", "servo_port": "/dev/ttyUSB0"}


def check_duration(duration: float | None) -> None:
    if duration is not None and not (math.isfinite(duration) and duration > 0.0):
        raise BringupError(f"--duration {duration:g} is not a positive number of seconds; "
                           "give e.g. --duration 30, or leave it out.")


#: What the gripper protocols' own fields accept (the bringup's action sequence reads them;
#: the mock rig's protocol fields are checked against the rig's parameters).
_GRIPPER_FIELDS = {
    "protocol.target_force": (0.0, True, "N"), "protocol.closing_speed": (0.0, True, "m/s"),
    "protocol.timeout": (0.0, True, "s"), "protocol.hold": (0.0, False, "s"),
}


def check_protocol(params: dict[str, Any], spec_text: str | None) -> None:
    """Every field of the protocol as its user gave it, before any node starts: one
    sentence naming the field, never the traceback of a node refusing it."""
    from tactile_sensor.nodes.mock_hardware import SPECS as RIG_SPECS
    from tactile_sensor.nodes.parameters import ParameterError

    rig = {spec.name: spec for spec in RIG_SPECS}
    given = f" in --protocol {spec_text!r}" if spec_text else ""
    for name, value in params.items():
        field = name.removeprefix("protocol.")
        if name == "protocol.speeds":
            if not value or not all(isinstance(v, int | float) and math.isfinite(v) and v > 0
                                    for v in value):
                raise BringupError(f"speeds{given} must be positive numbers of m/s joined "
                                   f"by '/', e.g. speeds=0.001/0.01; got {value!r}.")
        elif name in _GRIPPER_FIELDS:
            low, exclusive, unit = _GRIPPER_FIELDS[name]
            if (isinstance(value, bool) or not isinstance(value, int | float)
                    or not math.isfinite(value) or value < low or (exclusive and value == low)):
                bound = f"{'>' if exclusive else '>='} {low:g}"
                raise BringupError(f"{field}{given} must be a number {bound} {unit}; got "
                                   f"{value!r}.")
        elif name in rig:
            try:
                rig[name].validate(value)
            except ParameterError as exc:
                reason = str(exc).partition(" is invalid: ")[2]
                raise BringupError(f"{field} = {value!r}{given} is invalid: {reason}"
                                   ) from None


def main(argv: Sequence[str] | None = None) -> int:
    options = parse_args(sys.argv[1:] if argv is None else argv)
    configuration = CONFIGURATIONS[options.configuration]
    try:
        check_duration(options.duration)
        ports = resolve_ports(configuration, options.port, not options.no_mock)
        protocol = protocol_parameters(configuration.name, options.protocol)
        check_protocol(protocol, options.protocol)
        if options.config is not None and not options.config.is_file():
            raise BringupError(f"--config {options.config} does not exist; give a ROS "
                               "parameter YAML file.")
        if options.record is not None and options.record.exists():
            raise BringupError(f"--record {options.record} already exists; choose a new "
                               "folder (bags are never overwritten).")
    except BringupError as exc:
        print(f"tactile-sensor bringup: {exc}", file=sys.stderr)
        return 2
    if options.config is not None:
        from tactile_sensor.nodes.parameter_files import ParameterFileError, check_parameter_file

        try:
            check_parameter_file(options.config, configuration)
        except ParameterFileError as exc:
            print(f"tactile-sensor bringup: {exc}", file=sys.stderr)
            return 2
    with tempfile.TemporaryDirectory(prefix="tactile_sensor-") as run_dir:
        if not options.no_mock:
            ports = per_run_ports(ports, options.port, Path(run_dir))
            for path in ports.values():
                Path(path).parent.mkdir(parents=True, exist_ok=True)
        # Imported late: argument errors above must not pay for rclpy.
        from tactile_sensor.nodes.bringup_runner import BringupRunner

        runner = BringupRunner(configuration, ports=ports, protocol=protocol,
                               namespace=options.namespace, use_mock=not options.no_mock,
                               extra_config=options.config, record=options.record)
        previous = signal.getsignal(signal.SIGTERM)
        signal.signal(signal.SIGTERM, lambda *_: runner.request_stop("SIGTERM"))
        try:
            return runner.run(options.duration)
        finally:
            signal.signal(signal.SIGTERM, previous)


def per_run_ports(ports: dict[str, str], given: list[str], run_dir: Path) -> dict[str, str]:
    """The mock's devices in this run's own folder, unless a ``--port`` named the path: two
    bringups on one machine (in other domains) never open each other's devices."""
    named = {item.partition("=")[0] for item in given}
    return {name: path if name in named else str(run_dir / Path(path).name)
            for name, path in ports.items()}
