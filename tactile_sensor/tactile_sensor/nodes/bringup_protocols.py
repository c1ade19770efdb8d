"""What the in-process bringup does once every node is up: run the selected protocol.

- bench: wait until the driver streams calibrated force, start the mock rig's protocol,
  show progress, stop at its end.
- bend: the same with the finger: wait for the driver's angle, run the bends, stop at
  their end.
- gripper ``grasp``: grasp the rod through the gripper's action, hold, release, and print
  the grasp result with a summary of the force trace.
- gripper ``lift``: grasp the mock's object, lift it, load, hold, set down, release
  (``bringup_lift.py``); refused before anything moves without an object.
- otherwise run until ``--duration`` or Ctrl-C.
"""

from __future__ import annotations

import math
import threading
from typing import Any

from geometry_msgs.msg import WrenchStamped

from tactile_sensor.nodes import bringup_lift
from tactile_sensor.nodes.action_client import RaceFreeActionClient
from tactile_sensor.nodes.bringup_session import RunningBringup, call_action, say
from tactile_sensor_interfaces.action import Grasp, Release

READY_TIMEOUT_S = 120.0  # a cold FEM sweep plus the driver's tare
DEVICE_SILENT_S = 5.0  # a real ADC sends its first frame within this after the port opens
MOCK_SILENT_S = 60.0  # the mock's: a starved machine may start it slowly
DRAIN_STALL_S = 30.0  # give up waiting for the streams once they have not advanced for this long
TRACE_CATCH_UP_S = 10.0  # most the hold summary waits for the force stream to reach its end


def run_protocol(runner: RunningBringup, duration: float | None) -> int:
    name = runner.protocol.get("protocol.name")
    lift = "gripper" in runner.nodes and name == "lift"
    if lift and (refusal := bringup_lift.lift_refused(runner)) is not None:
        say(refusal)
        return 2
    driver = runner.nodes.get("driver")
    if driver is not None and not _wait_until(
            runner, lambda: driver.ready or _silent(runner, driver) is not None,
            READY_TIMEOUT_S, "driver streaming calibrated force"):
        if not runner.stopped:
            say("the driver did not become ready (tare and calibration); see its log above")
        return 1
    if driver is not None and (silence := _silent(runner, driver)) is not None:
        say(silence)
        return 1
    if lift:
        return bringup_lift.run_lift(runner)
    bench = runner.nodes.get("bench") or runner.nodes.get("bend")  # a rig with a protocol
    if bench is not None and name:
        return _run_bench(runner, bench, duration)
    if "gripper" in runner.nodes and name == "grasp":
        return _run_grasp(runner, duration)
    end = math.inf if duration is None else runner.now() + duration
    say("running" + ("" if duration is None else f" for {duration:.1f} s")
        + "; Ctrl-C stops")
    while runner.now() < end and runner.wait(0.2):
        pass
    return 0


def _silent(runner: RunningBringup, driver: Any) -> str | None:
    """Why the bringup gives up on an ADC that sent no frame yet (None: not yet): after
    DEVICE_SILENT_S with real devices, MOCK_SILENT_S with the mock's (a busy machine may
    start them slowly, but they do start)."""
    silence = driver.no_frame_for()
    limit = MOCK_SILENT_S if runner.use_mock else DEVICE_SILENT_S
    if silence is None or silence[0] < limit:
        return None
    fix = ("check that the board is plugged in, runs the tactile_adc firmware "
           "(docs/firmware.md) and is the one --port adc_port names" if not runner.use_mock
           else "see the mock's log above")
    reason = silence[1].partition("; retrying")[0]
    return f"no ADC frame in {silence[0]:.0f} s: {reason}; {fix}."


def _wait_until(runner: RunningBringup, predicate: Any, timeout_s: float, what: str) -> bool:
    deadline = runner.now() + timeout_s
    said = runner.now()
    while not predicate():
        if runner.stopped or runner.now() > deadline:
            return False
        if runner.now() - said > 5.0:
            say(f"waiting for {what} ...")
            said = runner.now()
        runner.wait(0.05)
    return True


def _run_bench(runner: RunningBringup, bench: Any, duration: float | None) -> int:
    bench.start_protocol()
    total = bench.protocol_duration_s + 0.5
    limit = total if duration is None else min(duration, total)
    say(f"protocol '{runner.protocol['protocol.name']}': {bench.protocol_duration_s:.1f} s")
    shown = -1
    while runner.wait(0.1):
        elapsed = bench.protocol_elapsed_s or 0.0
        percent = int(100 * min(elapsed / total, 1.0))
        if percent // 10 != shown:
            shown = percent // 10
            say(f"protocol {percent:3d} % ({elapsed:5.1f} / {total:.1f} s)")
        if elapsed >= limit:
            break
    else:
        return 0  # stopped
    return _drain(runner, bench, runner.nodes.get("driver"), limit)


def _drain(runner: RunningBringup, bench: Any, driver: Any, limit_s: float) -> int:
    """Keep running until the stage, gauge and driver have published up to the protocol's
    end (their stamps, not the clock), so the recording holds every press.

    The driver's stamps are the ADC's sample times: on a starved machine its backlog
    trails the protocol's clock by seconds to minutes, and stopping at the clock's end
    cut the last presses out of the recording. So wait as long as the streams advance.
    """
    end_ns = bench.protocol_start_ns + int(limit_s * 1e9)

    def position() -> tuple[int, int]:
        return (bench.published_until_ns,
                end_ns if driver is None else driver.published_until_ns)

    if min(position()) < end_ns:
        say("waiting for the recorded streams to reach the protocol's end ...")
        last, moved, said = position(), runner.now(), runner.now()
        while min(last) < end_ns:
            if not runner.wait(0.05):
                return 0  # stopped
            now = position()
            if now != last:
                last, moved = now, runner.now()
            elif runner.now() - moved > DRAIN_STALL_S:
                say(f"the streams stopped {(end_ns - min(last)) * 1e-9:.1f} s before the "
                    "protocol's end; the last presses are missing from the recording")
                return 0
            if runner.now() - said > 5.0:
                said = runner.now()
                say(f"driver {max(end_ns - last[1], 0) * 1e-9:.1f} s, gauge "
                    f"{max(end_ns - last[0], 0) * 1e-9:.1f} s behind the protocol's end ...")
    runner.wait(0.3)  # let the recorder take the last messages
    return 0


class _ForceTrace:
    """The driver's force with its sample stamps: the hold is a window of stamps, because
    this in-process subscription can deliver late, and a window by arrival once mixed
    samples from before the contact into the hold ("min 0.000 N" while the bag held >= 0.97 N)."""

    def __init__(self) -> None:
        self._samples: list[tuple[int, float]] = []  # (stamp [ns], force [N])
        self._lock = threading.Lock()

    def __call__(self, msg: WrenchStamped) -> None:
        stamp = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
        with self._lock:
            self._samples.append((stamp, msg.wrench.force.z))

    @property
    def values(self) -> list[float]:
        with self._lock:
            return [force for _, force in self._samples]

    def newest_ns(self) -> int:
        with self._lock:
            return max((stamp for stamp, _ in self._samples[-100:]), default=0)

    def between(self, start_ns: int, end_ns: int) -> list[float]:
        with self._lock:
            return [force for stamp, force in self._samples if start_ns <= stamp <= end_ns]


def _run_grasp(runner: RunningBringup, duration: float | None) -> int:
    node = runner.nodes["gripper"]
    p = runner.protocol
    trace = _ForceTrace()
    node.create_subscription(WrenchStamped, "driver/wrench", trace, 100)
    grasp = RaceFreeActionClient(node, Grasp, "~/grasp")
    release = RaceFreeActionClient(node, Release, "~/release")
    if not grasp.wait_for_server(timeout_sec=10.0):
        say("the gripper's ~/grasp action is not available")
        return 1
    goal = Grasp.Goal(target_force=float(p.get("protocol.target_force", 2.0)),
                      closing_speed=float(p.get("protocol.closing_speed", 0.01)),
                      timeout=float(p.get("protocol.timeout", 10.0)))
    say(f"grasp: target {goal.target_force:.2f} N at {goal.closing_speed * 1e3:.1f} mm/s")
    result = call_action(runner, grasp, goal, goal.timeout + 5.0)
    if result is None:
        return 1
    say(f"grasp result: contact={result.contact_detected} force={result.force:.3f} N "
        f"opening={result.opening * 1e3:.2f} mm ({result.message})")
    hold = float(p.get("protocol.hold", 2.0))
    start_ns = node.get_clock().now().nanoseconds
    end_ns = start_ns + int(hold * 1e9)
    runner.wait(hold)
    deadline = runner.now() + TRACE_CATCH_UP_S  # until the trace has the hold's end
    while trace.newest_ns() < end_ns and runner.now() < deadline and runner.wait(0.05):
        pass
    held = trace.between(start_ns, end_ns)
    if held:
        mean = sum(held) / len(held)
        say(f"hold {hold:.1f} s: force mean {mean:.3f} N, min {min(held):.3f} N, "
            f"max {max(held):.3f} N over {len(held)} samples")
    released = call_action(runner, release, Release.Goal(opening=0.0), 15.0)
    if released is None:
        return 1
    say(f"release: success={released.success} opening {released.opening * 1e3:.2f} mm "
        f"({released.message})")
    peak = max(trace.values, default=float("nan"))
    say(f"force trace: {len(trace.values)} samples, peak {peak:.3f} N, "
        f"final {trace.values[-1] if trace.values else float('nan'):.3f} N")
    return 0 if result.contact_detected and released.success else 1
