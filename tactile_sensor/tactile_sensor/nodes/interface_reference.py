"""Each node's ROS interface as data, and the Markdown reference pages rendered from it.

Parameters come from the nodes' own spec lists (``*_parameters.py``, the model's, the mock
hardware's and the recorder's), so their names, types, defaults, ranges and descriptions
cannot differ from what the nodes declare. Topics, services and actions are listed here
beside the node's behaviour that creates them; ``test/nodes/test_interface_reference.py``
starts every node in each listed variant and fails when the node has an endpoint or a
parameter without an entry here, or an entry names one the node lacks.

``python -m tactile_sensor.nodes.interface_reference DIR`` writes ``DIR/<node>.md`` and
``DIR/index.md`` (``make docs`` does, into ``docs/reference``).
"""

from __future__ import annotations

import re
import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from enum import Enum
from pathlib import Path
from typing import Any

from tactile_sensor.nodes import driver_parameters, gripper_parameters
from tactile_sensor.nodes.lifecycle_main import AUTOSTART
from tactile_sensor.nodes.parameters import ParamSpec
from tactile_sensor.nodes.physics_parameters import physics_specs
from tactile_sensor.physics.params import PhysicsParams
from tactile_sensor.sensing.chain_parameters import RUNTIME_PARAMETERS


class Applied(Enum):
    """When a new value of a parameter takes effect."""

    RUNTIME = "run time"  # ros2 param set takes effect at once, also while active
    CONFIGURE = "next configure"  # accepted any time, read by the configure transition
    CONFIGURE_ONLY = "configure only"  # refused while configured
    STARTUP = "start-up"  # read when the node is constructed


@dataclass(frozen=True)
class Endpoint:
    """A topic, service or action as the node names it (``~/`` = the node's own name)."""

    name: str
    type: str  # pkg/msg/Type, pkg/srv/Type or pkg/action/Type
    text: str
    variants: frozenset[str] | None = None  # None: in every variant of the node


@dataclass(frozen=True)
class NodeInterface:
    """What one node offers: its endpoints, its parameters and when each applies."""

    name: str  # default node name
    executable: str  # ros2 run tactile_sensor <executable>
    summary: str
    lifecycle: bool
    parameters: Sequence[ParamSpec]
    applied: Mapping[str, Applied]  # parameter name -> when it applies
    publishers: Sequence[Endpoint] = ()
    subscriptions: Sequence[Endpoint] = ()
    services: Sequence[Endpoint] = ()
    actions: Sequence[Endpoint] = ()
    #: Parameter overrides that change the endpoints, by variant name; the reference test
    #: starts the node in each.
    variants: Mapping[str, Mapping[str, Any]] = field(default_factory=lambda: {"default": {}})
    notes: str = ""

    def endpoints(self, kind: str, variant: str) -> list[Endpoint]:
        return [e for e in getattr(self, kind)
                if e.variants is None or variant in e.variants]


#: Endpoints rclpy creates for every node (and lifecycle node): not listed per node.
STANDARD_PUBLISHERS = frozenset({"/rosout", "/parameter_events", "~/transition_event"})
STANDARD_SERVICES = frozenset({
    "~/describe_parameters", "~/get_parameter_types", "~/get_parameters",
    "~/list_parameters", "~/set_parameters", "~/set_parameters_atomically",
    "~/get_type_description", "~/change_state", "~/get_state", "~/get_available_states",
    "~/get_available_transitions", "~/get_transition_graph"})
STANDARD_PARAMETERS = frozenset({"use_sim_time", "start_type_description_service"})

_DIAGNOSTICS = "diagnostic_msgs/msg/DiagnosticArray"
_WRENCH = "geometry_msgs/msg/WrenchStamped"
_JOINTS = "sensor_msgs/msg/JointState"
_TRIGGER = "std_srvs/srv/Trigger"


def _all(specs: Sequence[ParamSpec], applied: Applied) -> dict[str, Applied]:
    return {spec.name: applied for spec in specs}


def _driver() -> NodeInterface:
    specs = [*driver_parameters.SPECS, AUTOSTART]
    applied = {spec.name: (Applied.RUNTIME if spec.name in RUNTIME_PARAMETERS
                           else Applied.CONFIGURE_ONLY) for spec in specs}
    applied[AUTOSTART.name] = Applied.STARTUP
    array = frozenset({"array"})
    single = frozenset({"one module"})
    return NodeInterface(
        "driver", "driver_node",
        "The photoreflector ADC on a serial port turned into a calibrated contact force.",
        lifecycle=True, parameters=specs, applied=applied,
        publishers=[
            Endpoint("~/wrench", _WRENCH, "contact force [N] on +z of `frame_id` (with "
                     "`modules`: force x, y and z), the live force: one per sample, or at "
                     "`publish_rate`, the newest only when the driver is behind its ADC"),
            Endpoint("~/reading", "tactile_sensor_interfaces/msg/TactileReading",
                     "voltage [V], inverted output [V], force [N] and contact of each "
                     "sample, every sample (the record; with `modules`: each face's voltage "
                     "and output too)"),
            Endpoint("~/joint_states", _JOINTS, "with `bend_modules`: the finger's joint "
                     "angle [rad] (`joint_name`; 0 straight, REP 103) of each sample at "
                     "`publish_rate`, NaN beyond the calibration's range (/diagnostics WARN "
                     "`angles_out_of_range`); ~/wrench force.z then carries the fingertip's "
                     "contact force [N], NaN with the joint module alone",
                     frozenset({"bend"})),
            Endpoint("~/full_scale_force", "std_msgs/msg/Float64",
                     "latched full-scale force [N] of the calibration in use (the curve's "
                     "top; every larger output clamps there): the gripper's force ceiling"),
            Endpoint("/diagnostics", _DIAGNOSTICS, "the ADC's connection, frame rate, "
                     "lost frames, tare and calibration state, `full_scale_force_n`, "
                     "`readings_published`, `reading_subscribers`, `wrench_subscribers`; "
                     "one module: `blind` (ERROR 'ambient light saturates the detector' "
                     "while the detector is at its rail: force NaN, no ~/wrench), "
                     "`blind_samples`, `detector_headroom_v` and `detector_headroom_ratio` "
                     "(room left before light saturates it; docs/ambient.md)"),
        ],
        subscriptions=[
            Endpoint("calibration_curve", "tactile_sensor_interfaces/msg/CalibrationCurve",
                     "latched output -> force curve from the model node "
                     "(`calibration_source: model`, one module)", single),
            Endpoint("calibration_correction",
                     "tactile_sensor_interfaces/msg/CalibrationCorrection",
                     "latched optical gain and stiffness from the gripper's self-check, "
                     "applied over the calibration in use (file or model) unless a "
                     "calibration stamped later came; one module (docs/ambient.md)", single),
            Endpoint("array_calibration", "tactile_sensor_interfaces/msg/ArrayCalibration",
                     "latched outputs -> (Fx, Fy, Fz) calibration from the model node "
                     "(`calibration_source: model` with `modules`)", array),
        ],
        services=[Endpoint("~/tare", _TRIGGER, "zero the output on the last `tare_window` "
                           "at rest; refused while pressed")],
        variants={"one module": {}, "array": {"modules": "0:front,1:back,2:left,3:right"}},
        notes="Endpoints exist from the configure transition on; `~/wrench` and "
              "`~/reading` publish while active.")


def _model() -> NodeInterface:
    from tactile_sensor.nodes.model import NODE_SPECS

    specs = [*physics_specs(), *NODE_SPECS, AUTOSTART]
    applied = _all(specs, Applied.CONFIGURE)
    applied[AUTOSTART.name] = Applied.STARTUP
    return NodeInterface(
        "model", "model_node",
        "FEM predictions of the module's output, and the calibration they give, latched "
        "for the driver.",
        lifecycle=True, parameters=specs, applied=applied,
        publishers=[
            Endpoint("calibration_curve", "tactile_sensor_interfaces/msg/CalibrationCurve",
                     "latched output -> force curve of the FEM prediction (with "
                     "`calibration_rate_terms`: the physics' Prony terms too)"),
            Endpoint("array_calibration", "tactile_sensor_interfaces/msg/ArrayCalibration",
                     "latched outputs -> (Fx, Fy, Fz) calibration fitted on the FEM array "
                     "grid (physics `modules` names several faces)", frozenset({"array"})),
        ],
        services=[Endpoint("~/predict", "tactile_sensor_interfaces/srv/PredictOutput",
                           "indentations [m] in; forces [N], distances [m], voltages [V] "
                           "and outputs [V] out")],
        variants={"one module": {}, "array": {"modules": "front,back,left,right"}},
        notes="Every physics parameter is also in `config/physics.yaml`, which the mock "
              "hardware loads too. The FEM runs in a background thread after configure; "
              "`~/predict` answers 'not ready' until it is done.")


def _gripper() -> NodeInterface:
    specs = [*gripper_parameters.SPECS, AUTOSTART]
    applied = _all(specs, Applied.CONFIGURE)
    applied[AUTOSTART.name] = Applied.STARTUP
    return NodeInterface(
        "gripper", "gripper_node",
        "An XM430 on a rack and pinion, closed until the tactile force says contact.",
        lifecycle=True, parameters=specs, applied=applied,
        publishers=[
            Endpoint("~/joint_states", _JOINTS, "finger opening [m] (joint `joint_name`), "
                     "its speed [m/s] and the tactile force [N] as effort"),
            Endpoint("/diagnostics", _DIAGNOSTICS, "the servo's connection, hardware "
                     "error bits, temperature, voltage and the running goal"),
            Endpoint("calibration_correction",
                     "tactile_sensor_interfaces/msg/CalibrationCorrection",
                     "latched: the self-check's optical gain and stiffness, which the "
                     "driver applies over its calibration; published when a SelfCheck "
                     "goal asks `apply` and the fit is certain"),
            Endpoint("~/slip", "tactile_sensor_interfaces/msg/SlipEvent", "the adaptive "
                     "hold's events: a friction learned, an onset of slip (grip raised), "
                     "slipping at the force ceiling"),
        ],
        subscriptions=[Endpoint("tactile_wrench", _WRENCH, "the tactile force (remap to "
                                "the driver's `~/wrench`; force x and y feed the adaptive "
                                "hold)"),
                       # variants: none, since it exists only while a goal runs
                       Endpoint("tactile_reading", "tactile_sensor_interfaces/msg/"
                                "TactileReading", "the module output [V] the self-check "
                                "records (remap to the driver's `~/reading`); subscribed "
                                "only while a SelfCheck goal runs", variants=frozenset()),
                       Endpoint("tactile_full_scale", "std_msgs/msg/Float64",
                                "the tactile sensor's latched full-scale force [N] (remap "
                                "to the driver's `~/full_scale_force`): with "
                                "`max_grasp_force`, the force ceiling of every goal")],
        services=[Endpoint("~/reboot", _TRIGGER, "reboot the servo after a hardware "
                           "error; ends the running goal")],
        actions=[
            Endpoint("~/grasp", "tactile_sensor_interfaces/action/Grasp",
                     "close until the tactile force reaches `target_force` [N], then hold "
                     "(`hold_mode` fixed or adaptive)"),
            Endpoint("~/release", "tactile_sensor_interfaces/action/Release",
                     "open to `opening` [m] (0 = fully open)"),
            Endpoint("~/gripper_cmd", "control_msgs/action/GripperCommand",
                     "MoveIt's gripper action: position = opening [m], max_effort = "
                     "tactile force limit [N] (0 = position only)"),
            Endpoint("~/parallel_gripper_cmd", "control_msgs/action/ParallelGripperCommand",
                     "ros2_controllers' parallel gripper action, joint `joint_name`"),
            Endpoint("~/self_check", "tactile_sensor_interfaces/action/SelfCheck",
                     "close slowly on a rigid object; fit the optical gain and the skin "
                     "stiffness against the model's prediction (docs/ambient.md)"),
        ],
        notes="A new goal of any kind preempts the running one; see the gripper page "
              "for the goal policy. The self-check calls the model's `~/predict` as "
              "`model_predict` (remap it to the model node's). Without control_msgs "
              "installed, `~/gripper_cmd` and `~/parallel_gripper_cmd` are not served.")


def _mock_hardware() -> NodeInterface:
    from tactile_sensor.nodes.mock_hardware import SPECS

    specs = [*physics_specs(), *SPECS]
    bench, gripper = frozenset({"bench"}), frozenset({"gripper"})
    held = frozenset({"object"})
    return NodeInterface(
        "mock_hardware", "mock_hardware_node",
        "The devices on pseudo-terminals (a photoreflector ADC, an XM430) and the rig's "
        "ground truth, all driven by one simulated world.",
        lifecycle=False, parameters=specs, applied=_all(specs, Applied.STARTUP),
        publishers=[
            Endpoint("~/stage/joint_states", _JOINTS, "stage joints `stage_z` "
                     "(indentation [m], + into the skin), `stage_x`, `stage_y` (lateral "
                     "probe displacement [m]); with a wrench protocol also `stage_rx`, "
                     "`stage_ry`, `stage_rz` (probe tilt about x, y and twist about z "
                     "[rad])", bench),
            Endpoint("~/gauge/wrench", _WRENCH, "the probe's force on the skin [N], "
                     "+z pressing in; with a wrench protocol also its torque on the skin "
                     "about the probe's centre [N m]", bench),
            Endpoint("~/ground_truth", _WRENCH, "finger A's true skin force [N]: force.z "
                     "normal; with an object (`object.mass_kg` > 0) force.x along the "
                     "fingers, toward their tips", gripper | held),
            Endpoint("~/object/joint_states", _JOINTS, "the object along the fingers "
                     "(+ toward their tips): `object_position` its travel [m] (the skins' "
                     "deflection included), `object_slip` its slip over the skins [m]",
                     held),
            Endpoint("~/joint_states", _JOINTS, "world bend: the finger's true joint angle "
                     "`finger_joint` [rad] (0 straight, + toward the palm) at `truth_rate`",
                     frozenset({"bend"})),
            Endpoint("~/tip/wrench", _WRENCH, "world bend: the true contact force on the "
                     "fingertip [N], force.z into its palmar pad, at `truth_rate`",
                     frozenset({"bend"})),
        ],
        services=[Endpoint("~/start", _TRIGGER, "start the protocol now (with "
                           "`protocol.start_delay` < 0 it waits for this)",
                           bench | frozenset({"bend"}))],
        variants={"bench": {"world": "bench"}, "gripper": {"world": "gripper"},
                  "object": {"world": "gripper", "object.mass_kg": 0.1}},
        notes="Not a lifecycle node: it opens its devices when it starts. The ADC appears "
              "at `adc_link`, the servo at `servo_link` (gripper world).")


def _recorder() -> NodeInterface:
    from tactile_sensor.nodes.recorder import PARAMETERS

    return NodeInterface(
        "recorder", "recorder_node",
        "Chosen topics into a rosbag2 folder (MCAP or sqlite3), losing nothing.",
        lifecycle=False, parameters=PARAMETERS, applied=_all(PARAMETERS, Applied.STARTUP),
        notes="Subscribes to each topic of `topics` once a publisher appears (at once for "
              "`topic_types` entries), with its type and QoS taken from the graph; it "
              "publishes nothing and serves nothing of its own.")


def nodes() -> list[NodeInterface]:
    """Every node the package installs, in the order the reference lists them."""
    return [_driver(), _model(), _gripper(), _mock_hardware(), _recorder()]


# -- rendering ---------------------------------------------------------------------------------

_UNIT = re.compile(r"^\[([^\]'\"]+)\]\s*|\[([^\]'\"]+)\]")
_DIMENSIONLESS = {"1", "-"}


def unit_of(spec: ParamSpec) -> str:
    """The unit the description names in brackets ('[m]', '[bit/s]'), '' when none."""
    match = _UNIT.search(spec.description)
    if match is None:
        return ""
    unit = match.group(1) or match.group(2)
    return "" if unit in _DIMENSIONLESS else unit


def type_of(spec: ParamSpec) -> str:
    """The ROS parameter type of the spec's default (empty lists are string lists here)."""
    value = spec.default
    if isinstance(value, bool):
        return "bool"
    if isinstance(value, int):
        return "integer"
    if isinstance(value, float):
        return "double"
    if isinstance(value, str):
        return "string"
    if value and all(isinstance(v, int | float) for v in value):
        return "double[]"
    return "string[]"


def _number(value: float) -> str:
    return str(int(value)) if float(value).is_integer() and abs(value) < 1e12 else f"{value:g}"


def range_of(spec: ParamSpec) -> str:
    """The accepted values: the spec's bounds and choices, or the physics model's bounds."""
    meta: Mapping[str, Any] = {"low": spec.minimum, "high": spec.maximum,
                               "low_open": spec.exclusive_minimum}
    fields = PhysicsParams.__dataclass_fields__
    if spec.minimum is None and spec.maximum is None and spec.name in fields:
        meta = fields[spec.name].metadata
    parts = []
    if meta.get("low") is not None:
        parts.append(f"{'>' if meta.get('low_open') else '>='} {_number(meta['low'])}")
    if meta.get("high") is not None:
        parts.append(f"<= {_number(meta['high'])}")
    if spec.choices:
        parts.append("one of " + ", ".join(f"`{c}`" for c in spec.choices))
    return " and ".join(parts)


def _description(spec: ParamSpec) -> str:
    """The description without a leading '[unit] ' (the unit has its own column)."""
    return re.sub(r"^\[[^\]]+\]\s*", "", spec.description)


def _cell(text: Any) -> str:
    text = str(text).replace("|", "\\|").replace("\n", " ")
    return text or "–"


def _default(spec: ParamSpec) -> str:
    value = spec.default
    if isinstance(value, bool):
        return "`true`" if value else "`false`"
    if isinstance(value, str):
        return f"`'{value}'`"
    if isinstance(value, list):
        return "`[" + ", ".join(f"{v:g}" if isinstance(v, float) else repr(v)
                                for v in value) + "]`"
    return f"`{_number(value)}`" if isinstance(value, float) else f"`{value}`"


def _endpoint_table(title: str, endpoints: Sequence[Endpoint], node: NodeInterface) -> list[str]:
    if not endpoints:
        return []
    lines = [f"## {title}", "", "| name | type | what |", "| --- | --- | --- |"]
    for e in endpoints:
        when = (f" (only: {', '.join(sorted(e.variants))})"
                if e.variants is not None and len(node.variants) > 1 else "")
        lines.append(f"| `{e.name}` | `{e.type}` | {_cell(e.text)}{when} |")
    return [*lines, ""]


def render(node: NodeInterface) -> str:
    """The node's reference page in Markdown (MyST)."""
    kind = "lifecycle node" if node.lifecycle else "node"
    lines = [
        f"# {node.name}", "",
        "<!-- Generated by `python -m tactile_sensor.nodes.interface_reference` from the "
        "node's parameter specs; edit those, not this page. -->", "",
        node.summary, "",
        f"A {kind}: `ros2 run tactile_sensor {node.executable}`. Names starting with `~/` "
        f"are under the node's name (`/{node.name}/...` by default).", "",
    ]
    if node.notes:
        lines += [node.notes, ""]
    if len(node.variants) > 1:
        lines += ["Variants the endpoints depend on: " + "; ".join(
            f"{name} (" + (", ".join(f"`{k}: {v}`" for k, v in overrides.items())
                           or "defaults") + ")"
            for name, overrides in node.variants.items()) + ".", ""]
    lines += _endpoint_table("Published topics", node.publishers, node)
    lines += _endpoint_table("Subscribed topics", node.subscriptions, node)
    lines += _endpoint_table("Services", node.services, node)
    lines += _endpoint_table("Actions", node.actions, node)
    lines += ["## Parameters", "",
              "| name | type | default | range | unit | applied | description |",
              "| --- | --- | --- | --- | --- | --- | --- |"]
    for spec in node.parameters:
        lines.append(
            f"| `{spec.name}` | {type_of(spec)} | {_default(spec)} | {_cell(range_of(spec))} "
            f"| {_cell(unit_of(spec))} | {node.applied[spec.name].value} "
            f"| {_cell(_description(spec))} |")
    lines += ["", "Applied: *run time* = `ros2 param set` takes effect at once, also while "
              "active; *configure only* = refused while configured (deactivate, clean up, "
              "set, configure); *next configure* = read by the next configure transition; "
              "*start-up* = read when the node starts.", "",
              "Besides these, every node has rclpy's own parameter services, "
              "`/rosout` and `/parameter_events`" + (", and the lifecycle services "
              "(`~/change_state`, `~/get_state`, ...) and `~/transition_event`"
              if node.lifecycle else "") + "."]
    return "\n".join(lines) + "\n"


def render_index(all_nodes: Sequence[NodeInterface]) -> str:
    lines = ["# ROS interface reference", "",
             "Generated from the nodes' parameter specs and interface lists "
             "(`tactile_sensor/nodes/interface_reference.py`); a test starts each node and "
             "fails when this reference and the node disagree.", "",
             "| node | executable | what |", "| --- | --- | --- |"]
    lines += [f"| [{n.name}]({n.name}.md) | `{n.executable}` | {_cell(n.summary)} |"
              for n in all_nodes]
    lines += ["", "```{toctree}", ":hidden:", "", *(n.name for n in all_nodes), "```"]
    return "\n".join(lines) + "\n"


def pages() -> dict[str, str]:
    """File name -> Markdown of every reference page."""
    all_nodes = nodes()
    return {"index.md": render_index(all_nodes),
            **{f"{n.name}.md": render(n) for n in all_nodes}}


def write_pages(folder: Path) -> list[Path]:
    folder.mkdir(parents=True, exist_ok=True)
    written = []
    for name, text in pages().items():
        path = folder / name
        if not path.is_file() or path.read_text() != text:
            path.write_text(text)
        written.append(path)
    return written


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    if len(args) != 1:
        print("usage: python -m tactile_sensor.nodes.interface_reference OUTPUT_DIR",
              file=sys.stderr)
        return 2
    for path in write_pages(Path(args[0])):
        print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
