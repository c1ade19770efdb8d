"""A user's ROS parameter file checked against what the configuration's nodes declare.

rclpy ignores a parameter no node declares without a word, so ``noise.whit: 0.01`` would
leave the white noise at its default and the run would look fine. The bringup and the launch
files both call :func:`check_parameter_file` before starting a node; the refusal is one
sentence naming the closest declared name (difflib), so a typo costs one try.
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import yaml

from tactile_sensor.configurations import Configuration

WILDCARDS = ("*", "**")


class ParameterFileError(ValueError):
    """A parameter file names something no node of the configuration declares."""


def declared_parameters(configuration: Configuration) -> dict[str, frozenset[str]]:
    """Node name -> every parameter name that node declares (its specs and rclpy's own)."""
    from tactile_sensor.nodes import interface_reference as ref

    by_executable = {node.executable: node for node in ref.nodes()}
    return {spec.name: frozenset(p.name for p in by_executable[spec.executable].parameters)
            | ref.STANDARD_PARAMETERS for spec in configuration.nodes}


def flatten(params: Mapping[str, Any], prefix: str = "") -> list[str]:
    """Parameter names of a ``ros__parameters`` block, nested keys joined by '.' as rcl does."""
    names = []
    for key, value in params.items():
        name = f"{prefix}{key}"
        names += flatten(value, f"{name}.") if isinstance(value, Mapping) else [name]
    return names


def _closest(name: str, candidates: Iterable[str]) -> str | None:
    match = difflib.get_close_matches(name, sorted(candidates), n=1, cutoff=0.5)
    return match[0] if match else None


def _sections(path: Path) -> dict[str, Mapping[str, Any]]:
    try:
        data = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as exc:
        reason = str(exc).splitlines()[0]
        raise ParameterFileError(f"{path} is not a readable YAML file ({reason}); give a ROS "
                                 "parameter file.") from None
    if data is None:
        return {}
    if not isinstance(data, Mapping) or not all(
            isinstance(v, Mapping) and isinstance(v.get("ros__parameters", {}), Mapping)
            for v in data.values()):
        raise ParameterFileError(f"{path} is not a ROS parameter file; write 'NODE: "
                                 "ros__parameters: {name: value}' (NODE may be /**).")
    return {str(key): value.get("ros__parameters", {}) or {} for key, value in data.items()}


def check_parameter_file(path: Path, configuration: Configuration,
                         declared: Mapping[str, frozenset[str]] | None = None) -> None:
    """Raise ParameterFileError when ``path`` names a node the configuration lacks, or a
    parameter none of the nodes its section applies to declares."""
    declared = declared_parameters(configuration) if declared is None else declared
    for key, params in _sections(path).items():
        target = key.rstrip("/").rsplit("/", 1)[-1] or "**"
        nodes = list(declared) if target in WILDCARDS else [target]
        if target not in WILDCARDS and target not in declared:
            hint = _closest(target, declared)
            raise ParameterFileError(
                f"{path} sets parameters of node '{key}', which the {configuration.name} "
                f"configuration does not have; "
                + (f"did you mean '{hint}'?" if hint else
                   f"its nodes are {', '.join(declared)}."))
        known = frozenset().union(*(declared[n] for n in nodes))
        for name in flatten(params):
            if name in known:
                continue
            hint = _closest(name, known)
            owner = (f"no node of the {configuration.name} configuration declares"
                     if len(nodes) > 1 else f"node '{target}' does not declare")
            raise ParameterFileError(
                f"{path} sets '{name}', which {owner}; "
                + (f"did you mean '{hint}'?" if hint else
                   "see docs/reference for the declared parameters."))
