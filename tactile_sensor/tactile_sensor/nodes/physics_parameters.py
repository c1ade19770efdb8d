"""Physics parameters as ROS parameters, for every node that needs the physical model.

The model node and the mock hardware both load ``config/physics.yaml``, so the mock skin
and the predictions agree by construction; :class:`PhysicsParams` does the validation.
"""

from __future__ import annotations

from typing import Any

from tactile_sensor.nodes.parameters import ParamSpec
from tactile_sensor.physics.params import PhysicsParams


def physics_specs() -> list[ParamSpec]:
    specs = []
    for name, info in PhysicsParams.describe().items():
        default = info["default"]
        if isinstance(default, tuple):
            default = [float(v) for v in default]
        specs.append(ParamSpec(name, default, f"[{info['unit']}] {info['doc']}"))
    return specs


def physics_from_values(values: dict[str, Any]) -> PhysicsParams:
    """The physics fields of a node's parameter values (raises PhysicsError when bad)."""
    names = set(PhysicsParams.names())
    return PhysicsParams.from_mapping({k: v for k, v in values.items() if k in names})
