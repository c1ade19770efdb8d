"""Message field definitions: the bag's embedded ones first, then ours, then ROS 2 Kilted.

Why: ``ros2 bag record`` (Jazzy+) and rosbags' Writer embed definitions, older bags do not;
our own types then come from the interfaces package (.msg text) wherever it is installed.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

from rosbags.interfaces import Connection, MessageDefinitionFormat
from rosbags.typesys import Stores, get_types_from_idl, get_types_from_msg, get_typestore
from rosbags.typesys.base import TypesysError

from .errors import BagError

INTERFACES_PACKAGE = "tactile_sensor_interfaces"

# msgtype -> (constants, fields) exactly as rosbags' Typestore.fielddefs holds them.
FieldDefs = Mapping[str, tuple[list[Any], list[tuple[str, Any]]]]


def _newest_ros2_store() -> Stores:
    """ROS 2 Kilted if this rosbags knows it, else the newest ROS 2 store it has."""
    if hasattr(Stores, "ROS2_KILTED"):
        return Stores.ROS2_KILTED
    ros2 = [s for s in Stores if s.name.startswith("ROS2_")]
    return ros2[-1]


def interface_msg_dirs() -> list[Path]:
    """Directories that may hold our .msg files: AMENT_PREFIX_PATH, then the source tree."""
    dirs: list[Path] = []
    for prefix in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep):
        if prefix:
            dirs.append(Path(prefix) / "share" / INTERFACES_PACKAGE / "msg")
    root = Path(__file__).resolve().parents[3]  # analysis -> pkg -> ament pkg -> workspace
    dirs.append(root / INTERFACES_PACKAGE / "msg")
    # built workspaces, one per distribution (install/jazzy, install/kilted, ...)
    dirs.extend(sorted((root / "install").glob(
        f"*/{INTERFACES_PACKAGE}/share/{INTERFACES_PACKAGE}/msg")))
    return [d for d in dirs if d.is_dir()]


def interface_types() -> dict[str, Any]:
    """Our message types parsed from the first interfaces directory found (empty if none)."""
    for directory in interface_msg_dirs():
        typs: dict[str, Any] = {}
        for path in sorted(directory.glob("*.msg")):
            name = f"{INTERFACES_PACKAGE}/msg/{path.stem}"
            typs.update(get_types_from_msg(path.read_text(encoding="utf-8"), name))
        if typs:
            return typs
    return {}


def embedded_types(connections: Iterable[Connection]) -> dict[str, Any]:
    """Types from the definitions a bag carries for its connections."""
    typs: dict[str, Any] = {}
    sep = "=" * 80 + "\n"
    for conn in connections:
        fmt, data = conn.msgdef.format, conn.msgdef.data
        try:
            if fmt == MessageDefinitionFormat.MSG and data:
                typs.update(get_types_from_msg(data, conn.msgtype))
            elif fmt == MessageDefinitionFormat.IDL and data:
                if data.startswith(f"{sep}IDL: "):
                    for block in data.split(sep)[1:]:
                        typs.update(get_types_from_idl(block.split("\n", 1)[1]))
                else:
                    typs.update(get_types_from_idl(data))
        except (TypesysError, IndexError) as err:
            msg = (f"the bag's definition of {conn.msgtype} on {conn.topic} cannot be parsed "
                   f"({err}); re-record with a ROS 2 that writes valid definitions.")
            raise BagError(msg) from None
    return typs


def field_definitions(connections: Iterable[Connection]) -> FieldDefs:
    """Merged definitions: embedded override ours, ours override the stock Kilted store."""
    store = get_typestore(_newest_ros2_store())
    merged: dict[str, Any] = dict(store.fielddefs)
    for name, (consts, fields, *_) in {**interface_types(),
                                        **embedded_types(connections)}.items():
        merged[name] = (consts, fields)
    return merged
