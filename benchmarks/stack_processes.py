"""The gripper stack of one version, started three ways, and its CPU read from /proc.

* ``ros2 launch tactile_sensor gripper.launch.py`` where ``ros2`` is on PATH: each node is
  a child process of the launch, found by its ``__node:=`` remapping;
* without it, the same node modules with the same parameter files, remappings and ports,
  one process each, started in the launch file's order (the mock first, a node with a
  device once its link exists), each configuring and activating itself (``autostart``)
  where the launch file would send the transitions;
* ``tactile-sensor bringup gripper --protocol idle``: one process, and whatever it starts.

What to start comes from the version's own ``configurations.py`` and ``config/`` (asked in
a child process with that version's PYTHONPATH), so a version that moved a node or a
parameter file runs as its own launch file would start it.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import shutil
import signal
import subprocess
import sys
import tarfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from side_by_side import Variant, _git, cpu_seconds
from stack_figures import task_ticks, thread_labels

#: How long a stack may take until it serves a grasp (a loaded 2-core machine: minutes).
BRING_UP_S = 240.0
#: The mock's node name in the gripper configuration, and what the tables call it.
MOCK_NODE = "gripper_world"
NODE_LABELS = {"driver": "driver", "gripper": "gripper", "model": "model",
               MOCK_NODE: "mock hardware"}
TICK = os.sysconf("SC_CLK_TCK")

SPECS = """
import json, sys
from tactile_sensor.configurations import GRIPPER, config_dir, config_files
print(json.dumps({"config_dir": str(config_dir()), "ports": list(GRIPPER.ports),
    "nodes": [{"name": s.name, "module": s.module, "lifecycle": s.lifecycle,
               "mock_only": s.mock_only, "remappings": [list(r) for r in s.remappings],
               "ports": [list(p) for p in s.port_parameters],
               "files": [str(config_dir() / f) for f in config_files(s, True)]}
              for s in GRIPPER.nodes]}))
"""


class StackError(RuntimeError):
    """The stack did not come up or went down; the message says which part and its log."""


def with_own_config(variant: Variant) -> None:
    """Unpack the version's ``config/`` beside its sources (``variants`` unpacks only the
    Python package), so that its nodes load the parameter files of their own commit."""
    target = variant.source / "config"
    if target.exists() or variant.label.startswith("this"):
        return
    archive = _git("archive", "--format=tar", variant.label, "tactile_sensor/config")
    if archive.returncode:
        raise StackError(f"commit {variant.label} has no tactile_sensor/config "
                         f"({archive.stderr.decode().strip()}); compare with a later one.")
    with tarfile.open(fileobj=io.BytesIO(archive.stdout)) as tar:
        tar.extractall(variant.source.parent, filter="data")


def node_specs(variant: Variant) -> dict[str, object]:
    """The version's gripper configuration: its nodes, their files, remappings and ports."""
    done = subprocess.run([sys.executable, "-c", SPECS], env=variant.env(),
                          capture_output=True, text=True, check=False, timeout=120)
    if done.returncode:
        tail = done.stderr.strip().splitlines()[-1:] or ["no output"]
        raise StackError(f"{variant.label}'s configurations.py cannot be read: {tail[0]}")
    return json.loads(done.stdout)


def descendants(pid: int) -> list[int]:
    """Every process below ``pid`` (children, their children, ...), from /proc."""
    parents: dict[int, list[int]] = {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            ppid = int((entry / "stat").read_text().rsplit(")", 1)[1].split()[1])
        except (OSError, IndexError, ValueError):
            continue
        parents.setdefault(ppid, []).append(int(entry.name))
    out, todo = [], [pid]
    while todo:
        for child in parents.get(todo.pop(), []):
            out.append(child)
            todo.append(child)
    return out


def cmdline(pid: int) -> list[str]:
    try:
        return Path(f"/proc/{pid}/cmdline").read_bytes().decode(errors="replace").split("\0")
    except OSError:
        return []


def node_of(pid: int) -> str | None:
    """The node a process runs, from its ``-r __node:=NAME`` (as launch_ros passes it)."""
    for arg in cmdline(pid):
        if arg.startswith("__node:="):
            return arg.split(":=", 1)[1]
    return None


def process_label(pid: int) -> str:
    """What a child of the in-process bringup runs: its node, module or program."""
    node = node_of(pid)
    if node is not None:
        return NODE_LABELS.get(node, node)
    argv = [a for a in cmdline(pid) if a]
    if "-m" in argv[:-1]:
        return argv[argv.index("-m") + 1].rsplit(".", 1)[-1]
    return Path(argv[0]).name if argv else f"pid {pid}"


def thread_seconds(pid: int) -> dict[str, float]:
    """CPU seconds so far of each live thread of ``pid``, by label (``thread_labels``)."""
    comms: dict[int, str] = {}
    ticks: dict[int, int] = {}
    with contextlib.suppress(OSError):
        for task in Path(f"/proc/{pid}/task").iterdir():
            try:
                ticks[int(task.name)] = task_ticks((task / "stat").read_text())
                comms[int(task.name)] = (task / "comm").read_text().strip()
            except (OSError, ValueError):
                continue
    labels = thread_labels(pid, {t: comms[t] for t in ticks if t in comms})
    return {labels[t]: ticks[t] / TICK for t in labels}


@dataclass
class Snapshot:
    """CPU seconds so far of each process of a stack and of each of their threads."""

    at: float
    processes: dict[str, float]
    threads: dict[tuple[str, str], float]


def snapshot(pids: dict[str, int]) -> Snapshot:
    processes: dict[str, float] = {}
    threads: dict[tuple[str, str], float] = {}
    for name, pid in pids.items():
        with contextlib.suppress(OSError, IndexError, ValueError):
            processes[name] = cpu_seconds(pid)
            threads.update({(name, t): s for t, s in thread_seconds(pid).items()})
    return Snapshot(time.monotonic(), processes, threads)


def wait_until(condition: Callable[[], object], timeout_s: float, period_s: float = 0.1
               ) -> bool:
    deadline = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() > deadline:
            return False
        time.sleep(period_s)
    return True


@dataclass
class Child:
    name: str
    proc: subprocess.Popen  # type: ignore[type-arg]
    log: Path

    def tail(self, lines: int = 5) -> str:
        text = self.log.read_text(errors="replace") if self.log.exists() else ""
        return " | ".join(text.strip().splitlines()[-lines:])


def start(name: str, argv: list[str], folder: Path, env: dict[str, str]) -> Child:
    log = folder / f"{name.replace(' ', '_')}.log"
    with log.open("ab") as out:
        proc = subprocess.Popen(argv, env={**env, "PYTHONUNBUFFERED": "1"}, stdout=out,
                                stderr=subprocess.STDOUT, start_new_session=True)
    return Child(name, proc, log)


def stop(children: list[Child], timeout_s: float = 20.0) -> None:
    """SIGINT to every child at once (as ``ros2 launch`` stops its nodes), then SIGKILL to
    the process group of any still running, its own children included."""
    for child in children:
        with contextlib.suppress(ProcessLookupError):
            child.proc.send_signal(signal.SIGINT)
    deadline = time.monotonic() + timeout_s
    for child in children:
        with contextlib.suppress(subprocess.TimeoutExpired):
            child.proc.wait(max(0.1, deadline - time.monotonic()))
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.killpg(child.proc.pid, signal.SIGKILL)
        with contextlib.suppress(subprocess.TimeoutExpired):
            child.proc.wait(5)


@dataclass
class Stack:
    """One version's gripper stack, one way: its processes while it runs."""

    way: str  # "launch", "processes" or "bringup"
    variant: Variant
    folder: Path
    children: list[Child] = field(default_factory=list)

    @property
    def adc(self) -> Path:
        return self.folder / "adc"

    @property
    def servo(self) -> Path:
        return self.folder / "xm430"

    def start(self) -> None:
        with_own_config(self.variant)
        env = self.variant.env()
        py = sys.executable
        ports = [f"adc_port:={self.adc}", f"servo_port:={self.servo}"]
        if self.way == "launch":
            self.children.append(start("launch", [
                "ros2", "launch", "tactile_sensor", "gripper.launch.py",
                "use_mock_hardware:=true", "protocol:=idle", *ports], self.folder, env))
        elif self.way == "bringup":
            self.children.append(start("bringup", [
                py, "-m", "tactile_sensor.cli", "bringup", "gripper", "--protocol", "idle",
                *(f"--port={p.replace(':=', '=')}" for p in ports)], self.folder, env))
        else:
            self._start_processes(node_specs(self.variant), env)

    def _start_processes(self, config: dict, env: dict[str, str]) -> None:  # type: ignore[type-arg]
        """As launch_description.build: the mock first; a node with a device port once the
        mock has made its link; lifecycle nodes configure and activate themselves."""
        port_paths = {"adc_port": str(self.adc), "servo_port": str(self.servo)}
        nodes = config["nodes"]
        mock = next((n for n in nodes if n["mock_only"]), None)
        ordered = ([mock] if mock else []) + [n for n in nodes if n is not mock]
        for spec in ordered:
            argv = [sys.executable, "-m", spec["module"], "--ros-args",
                    "-r", f"__node:={spec['name']}"]
            for path in spec["files"]:
                argv += ["--params-file", path]
            for source, target in spec["remappings"]:
                argv += ["-r", f"{source}:={target}"]
            for param, arg in spec["ports"]:
                argv += ["-p", f"{param}:={port_paths[arg]}"]
            if spec["mock_only"]:
                argv += ["-p", "protocol.name:=idle"]
            if spec["lifecycle"]:
                argv += ["-p", "autostart:=true"]
                devices = [Path(port_paths[arg]) for _, arg in spec["ports"]]
                if mock is not None and devices and not wait_until(
                        lambda d=devices: all(p.exists() for p in d), BRING_UP_S):
                    raise StackError(f"the mock made no device links in {BRING_UP_S:g} s; "
                                     f"its log ends: {self.children[0].tail()}")
            label = NODE_LABELS.get(spec["name"], spec["name"])
            self.children.append(start(label, argv, self.folder, env))

    def processes(self) -> dict[str, int]:
        """The processes whose CPU counts, by what they run; the launch process itself is
        listed apart (it is not part of the robot's stack)."""
        if self.way == "processes":
            return {c.name: c.proc.pid for c in self.children if c.proc.poll() is None}
        root = self.children[0].proc.pid
        out: dict[str, int] = {}
        if self.way == "bringup":
            out["bringup (every node)"] = root
        for pid in descendants(root):
            label = (NODE_LABELS.get(node_of(pid) or "") if self.way == "launch"
                     else process_label(pid))
            if label:
                out[label if label not in out else f"{label} ({pid})"] = pid
        if self.way == "launch":
            out["ros2 launch itself"] = root
        return out

    def check_alive(self) -> None:
        for child in self.children:
            code = child.proc.poll()
            if code is not None:
                raise StackError(f"{child.name} exited with {code}; {child.log} ends: "
                                 f"{child.tail()}")

    def stop(self) -> None:
        stop(self.children)


def launch_available() -> bool:
    return shutil.which("ros2") is not None
