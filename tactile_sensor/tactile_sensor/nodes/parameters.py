"""Declared, described and validated ROS parameters, shared by every node.

Parameters are declared with dynamic typing so that a wrong value given at start-up does
not kill the constructor with a traceback; instead :func:`read_parameters` validates
every value in ``on_configure`` and the transition fails with one sentence naming the
parameter, its value and what it should be. The same validation guards runtime
``ros2 param set`` calls.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
from rclpy.node import Node
from rclpy.parameter import Parameter

Value = bool | int | float | str | list[float] | list[str]


class ParameterError(ValueError):
    """A parameter value a user gave is unusable; the message names it and the fix."""


@dataclass(frozen=True)
class ParamSpec:
    """One parameter: default, meaning with unit, and the values it accepts."""

    name: str
    default: Value
    description: str
    minimum: float | None = None
    maximum: float | None = None
    choices: tuple[str, ...] | None = None
    exclusive_minimum: bool = False
    check: Callable[[Any], str | None] | None = None  # returns a reason when bad

    @property
    def constraints(self) -> str:
        parts = []
        if self.minimum is not None:
            parts.append(f"{'>' if self.exclusive_minimum else '>='} {self.minimum:g}")
        if self.maximum is not None:
            parts.append(f"<= {self.maximum:g}")
        if self.choices:
            parts.append("one of " + ", ".join(self.choices))
        return " and ".join(parts)

    def validate(self, value: Any) -> Value:
        """The value coerced to the default's type, or ParameterError naming the fix."""
        kind = type(self.default)
        bad = f"Parameter '{self.name}' = {value!r} is invalid: "
        if kind is bool:
            if not isinstance(value, bool):
                raise ParameterError(bad + "expected true or false.")
            return value
        if kind is int:
            if isinstance(value, bool) or not isinstance(value, int):
                raise ParameterError(bad + "expected an integer.")
        elif kind is float:
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise ParameterError(bad + "expected a number.")
            value = float(value)
            if not math.isfinite(value):
                raise ParameterError(bad + "expected a finite number.")
        elif kind is str:
            if not isinstance(value, str):
                raise ParameterError(bad + "expected a string.")
        elif kind is list:
            if not isinstance(value, list | tuple):
                raise ParameterError(bad + "expected a list.")
            value = list(value)
        if isinstance(value, int | float) and not isinstance(value, bool):
            low_bad = self.minimum is not None and (
                value <= self.minimum if self.exclusive_minimum else value < self.minimum)
            high_bad = self.maximum is not None and value > self.maximum
            if low_bad or high_bad:
                raise ParameterError(bad + f"it must be {self.constraints}.")
        if self.choices is not None and value not in self.choices:
            raise ParameterError(bad + f"it must be {self.constraints}.")
        if self.check is not None:
            reason = self.check(value)
            if reason:
                raise ParameterError(bad + reason)
        return value


def declare_parameters(node: Node, specs: Sequence[ParamSpec]) -> None:
    """Declare every spec with its description; values are checked on configure."""
    for spec in specs:
        descriptor = ParameterDescriptor(
            description=spec.description,
            additional_constraints=spec.constraints,
            dynamic_typing=True,
        )
        node.declare_parameter(spec.name, spec.default, descriptor)
    by_name = {spec.name: spec for spec in specs}

    def on_set(params: list[Parameter]) -> SetParametersResult:
        for param in params:
            spec = by_name.get(param.name)
            if spec is None:
                continue
            try:
                spec.validate(param.value)
            except ParameterError as exc:
                return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    node.add_on_set_parameters_callback(on_set)


def read_parameters(node: Node, specs: Sequence[ParamSpec]) -> dict[str, Any]:
    """Every declared value, validated; raises ParameterError for the first bad one."""
    return {spec.name: spec.validate(node.get_parameter(spec.name).value) for spec in specs}
