"""The in-process bringup itself: compose, transition, run the protocol, shut down cleanly."""

from __future__ import annotations

import importlib
import signal
import sys
import threading
import time
from pathlib import Path
from typing import Any

import rclpy
from rclpy.executors import MultiThreadedExecutor
from rclpy.lifecycle import Node as LifecycleNode
from rclpy.lifecycle import TransitionCallbackReturn
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.signals import SignalHandlerOptions

from tactile_sensor.configurations import Configuration, NodeSpec, config_dir, config_files
from tactile_sensor.nodes.background_spin import settle_callbacks
from tactile_sensor.nodes.bringup_duplicates import bringup_node_names, claim_bringup
from tactile_sensor.nodes.bringup_protocols import run_protocol
from tactile_sensor.nodes.bringup_session import say


def _refused_nodes() -> tuple[type[Exception], ...]:
    from tactile_sensor.nodes.mock_hardware import MockHardwareError

    return (MockHardwareError,)


def node_arguments(spec: NodeSpec, extra_config: Path | None,
                   use_mock: bool = True) -> list[str]:
    """The --ros-args a launch file would give this node (device ports go in as parameter
    overrides instead: a node-specific section of a file would beat a global ``-p``)."""
    args = ["--ros-args"]
    for name in config_files(spec, use_mock):
        args += ["--params-file", str(config_dir() / name)]
    if extra_config is not None:
        args += ["--params-file", str(extra_config)]
    for source, target in spec.remappings:
        args += ["-r", f"{source}:={target}"]
    return args




class BringupRunner:
    def __init__(self, configuration: Configuration, *, ports: dict[str, str],
                 protocol: dict[str, Any], namespace: str, use_mock: bool,
                 extra_config: Path | None, record: Path | None) -> None:
        self.configuration = configuration
        self.ports = ports
        self.protocol = protocol
        self.namespace = namespace
        self.use_mock = use_mock
        self.extra_config = extra_config
        self.record = record
        self.nodes: dict[str, Node] = {}
        self._states: dict[str, str] = {}  # lifecycle node -> 'inactive' | 'active'
        self._stop = threading.Event()
        self._stop_reason = ""

    def request_stop(self, reason: str) -> None:
        self._stop_reason = self._stop_reason or reason
        self._stop.set()

    # -- composition --------------------------------------------------------------------------
    def _create_nodes(self) -> None:
        if self.record is not None:
            from tactile_sensor.nodes.recorder import RecorderNode

            topics = [self._absolute(t) for t in self.configuration.record_topics]
            self.nodes["recorder"] = RecorderNode(
                "recorder", namespace=self.namespace,
                parameter_overrides=[Parameter("path", value=str(self.record)),
                                     Parameter("topics", value=topics)])
        for spec in self.configuration.nodes:
            if spec.mock_only and not self.use_mock:
                continue
            node_class = getattr(importlib.import_module(spec.module), spec.node_class)
            overrides = [Parameter(param, value=self.ports[arg])
                         for param, arg in spec.port_parameters]
            if spec.mock_only:
                # The runner starts the protocol once the driver streams force.
                overrides += [Parameter(name, value=value)
                              for name, value in self.protocol.items()]
                overrides.append(Parameter("protocol.start_delay", value=-1.0))
            self.nodes[spec.name] = node_class(
                spec.name, namespace=self.namespace,
                cli_args=node_arguments(spec, self.extra_config, self.use_mock),
                parameter_overrides=overrides)

    def _absolute(self, topic: str) -> str:
        ns = self.namespace.strip("/")
        return f"/{ns}{topic}" if ns else topic

    def _lifecycle_up(self) -> bool:
        for name, node in self.nodes.items():
            if not isinstance(node, LifecycleNode):
                continue
            for transition in ("configure", "activate"):
                result = getattr(node, f"trigger_{transition}")()
                if result != TransitionCallbackReturn.SUCCESS:
                    say(f"{name}: {transition} failed (see its log above); stopping.")
                    return False
                self._states[name] = "inactive" if transition == "configure" else "active"
            say(f"{name}: active")
        return True

    def _lifecycle_down(self) -> None:
        for name in reversed(list(self._states)):
            node = self.nodes[name]
            if self._states[name] == "active":
                node.trigger_deactivate()
            node.trigger_cleanup()
        self._states.clear()

    def _destroy_nodes(self) -> None:
        for node in reversed(list(self.nodes.values())):
            node.destroy_node()

    # -- run ------------------------------------------------------------------------------------
    def run(self, duration: float | None) -> int:
        # dynamixel-sdk busy-waits for replies; with the emulator in this process a short
        # switch interval lets the emulator's thread answer in time (docs/gripper.md).
        sys.setswitchinterval(5e-4)
        rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
        claim = claim_bringup(bringup_node_names(self.configuration, self.namespace,
                                                 self.use_mock, self.record is not None),
                              self.namespace)
        if claim.refusal is not None:
            rclpy.try_shutdown()
            say(claim.refusal)
            return 2
        previous = signal.signal(signal.SIGINT, lambda *_: self.request_stop("Ctrl-C"))
        executor = MultiThreadedExecutor(num_threads=6)
        spinner: threading.Thread | None = None
        code = 0
        try:
            try:
                self._create_nodes()
            except _refused_nodes() as exc:  # a mock rig the parameters refuse
                say(str(exc))
                self.request_stop("a node refused its parameters")
                return 2
            for node in self.nodes.values():
                executor.add_node(node)
            spinning = threading.Event()
            spinning.set()

            def spin() -> None:
                while spinning.is_set():
                    executor.spin_once(timeout_sec=0.05)

            spinner = threading.Thread(target=spin, name="executor", daemon=True)
            spinner.start()
            if self._lifecycle_up():
                code = run_protocol(self, duration)
            else:
                code = 1
                self.request_stop("a node did not start")
            if code != 0:
                self.request_stop("the protocol failed; see above")
        finally:
            signal.signal(signal.SIGINT, previous)
            say(f"shutting down ({self._stop_reason or 'protocol finished'})")
            if spinner is not None:  # stop waiting on entities before destroying them
                spinning.clear()
                spinner.join(timeout=2.0)
                settle_callbacks(executor, timeout_s=2.0)
            self._lifecycle_down()
            executor.shutdown(timeout_sec=2.0)
            self._destroy_nodes()  # after the executor stopped waiting on them
            rclpy.try_shutdown()
            code = self._report_recording(code)
        return code

    def _report_recording(self, code: int) -> int:
        """Last line: where the bag is, or what a failed recording kept (and exit 1)."""
        if self.record is None:
            return code
        failure = getattr(self.nodes.get("recorder"), "failure", None)
        if failure:
            say(failure)
            return code or 1
        say(f"bag written to {self.record}")
        return code

    def wait(self, seconds: float) -> bool:
        """Sleep unless a stop is requested; False when stopped."""
        return not self._stop.wait(seconds)

    @property
    def stopped(self) -> bool:
        return self._stop.is_set()

    def now(self) -> float:
        return time.monotonic()
