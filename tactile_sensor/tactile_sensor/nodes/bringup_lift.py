"""The gripper's ``lift`` protocol on mock hardware: grasp the object, lift it, let its
load profile add load, hold, set it down, release; then one line per phase with the true
grip and the slip, and the slip goals' figures (``analysis/lift.py``).

The mock runs in this process: the lift and the set-down are its servo emulator's
``object lift`` / ``object down``, and the ground truth (``gripper_world/ground_truth``
force.z, the true grip; ``gripper_world/object/joint_states``, the slip) and the hold's
``~/slip`` events are read here.
"""

from __future__ import annotations

import math
import threading
from typing import Any

from geometry_msgs.msg import WrenchStamped
from sensor_msgs.msg import JointState

from tactile_sensor.analysis.lift import (
    Trace,
    lift_figures,
    load_rise,
    peak_load_n,
    phase_summary,
)
from tactile_sensor.analysis.slip.signature import least_grip_n
from tactile_sensor.nodes.action_client import RaceFreeActionClient
from tactile_sensor.nodes.bringup_session import RunningBringup, call_action, say
from tactile_sensor.sim.rig_refusals import lift_refusal
from tactile_sensor_interfaces.action import Grasp, Release
from tactile_sensor_interfaces.msg import SlipEvent

#: The grip is settled once the true force stayed this close to the target [1] ...
SETTLED_FRACTION = 0.15
#: ... for this long [s]: past the settle (it judges 0.15 s at rest), so an adaptive hold
#: has begun, as a fixed grasp has when it answers.
SETTLED_S = 0.5
#: Most the protocol waits for the ground truth to reach the release's end [s].
CATCH_UP_S = 10.0


def lift_refused(runner: RunningBringup) -> str | None:
    """The lift's refusal for this bringup (no in-process mock, no object), or None."""
    mock = runner.nodes.get("gripper_world")
    return lift_refusal(getattr(mock, "emulator", None) is not None,
                        getattr(mock, "object_spec", None) is not None)


class _Truth:
    """The ground truth and the hold's events, stamped in host time [s]."""

    def __init__(self) -> None:
        self.grip: list[tuple[float, float]] = []
        self.slip: list[tuple[float, float]] = []
        self.onsets: list[float] = []
        self._lock = threading.Lock()

    def on_truth(self, msg: WrenchStamped) -> None:
        with self._lock:
            self.grip.append((_seconds(msg.header.stamp), msg.wrench.force.z))

    def on_object(self, msg: JointState) -> None:
        with self._lock:
            self.slip.append((_seconds(msg.header.stamp), msg.position[1]))

    def on_slip(self, msg: SlipEvent) -> None:
        say(f"~/slip {msg.kind}: margin {msg.margin:.3f} N, friction {msg.friction:.2f}, "
            f"grip {msg.grip:.2f} N")
        if msg.kind == "onset":
            with self._lock:
                self.onsets.append(_seconds(msg.header.stamp))

    def traces(self) -> tuple[Trace, Trace]:
        with self._lock:
            return Trace.of(self.grip), Trace.of(self.slip)

    def newest_s(self) -> float:
        with self._lock:
            return self.grip[-1][0] if self.grip else 0.0


def _seconds(stamp: Any) -> float:
    return stamp.sec + stamp.nanosec * 1e-9


def run_lift(runner: RunningBringup) -> int:
    mock, node, p = runner.nodes["gripper_world"], runner.nodes["gripper"], runner.protocol
    spec = mock.object_spec
    truth = _Truth()
    node.create_subscription(WrenchStamped, "gripper_world/ground_truth", truth.on_truth, 100)
    node.create_subscription(JointState, "gripper_world/object/joint_states",
                             truth.on_object, 100)
    node.create_subscription(SlipEvent, "~/slip", truth.on_slip, 10)
    grasp = RaceFreeActionClient(node, Grasp, "~/grasp")
    release = RaceFreeActionClient(node, Release, "~/release")
    if not grasp.wait_for_server(timeout_sec=10.0):
        say("the gripper's ~/grasp action is not available")
        return 1
    rise = load_rise(spec.load)
    lifted_s = (rise[1] if rise else 0.0) + float(p.get("protocol.hold", 2.0))
    goal = Grasp.Goal(target_force=float(p.get("protocol.target_force", 2.0)),
                      closing_speed=float(p.get("protocol.closing_speed", 0.01)),
                      timeout=float(p.get("protocol.timeout", 10.0)),
                      hold_mode=str(p.get("protocol.hold_mode", "")))
    goal.hold_time = goal.timeout + lifted_s + 5.0  # canceled before the release
    now = lambda: node.get_clock().now().nanoseconds * 1e-9  # noqa: E731
    say(f"lift: object {spec.mass_kg * 1e3:.0f} g, friction {spec.friction_static:.2f} / "
        f"{spec.friction_kinetic:.2f}; grasp at {goal.target_force:.2f} N, hold "
        f"{goal.hold_mode or 'the gripper s hold_mode'}")
    marks = {"grasp": now()}
    answer = _send(grasp, goal)
    if not _settle(runner, truth, goal, answer):
        return 1
    marks["lift"] = now()
    say(mock.emulator.control("object lift"))
    dropped = _hold_lifted(runner, mock, truth, marks["lift"], lifted_s)
    marks["set down"] = now()
    say(mock.emulator.control("object down"))
    _end_hold(runner, answer)
    released = call_action(runner, release, Release.Goal(opening=0.0), 15.0)
    marks["end"] = now()
    if released is None:
        return 1
    say(f"release: success={released.success} opening {released.opening * 1e3:.2f} mm "
        f"({released.message})")
    if "result" in answer:
        result = answer["result"]
        say(f"grasp result: {result.message}")
    _report(runner, truth, spec, marks, rise, dropped)
    return 0 if released.success else 1


def _send(client: Any, goal: Any) -> dict[str, Any]:
    """Send a goal; the box fills with 'result' (or 'rejected') when the answer comes."""
    box: dict[str, Any] = {}

    def on_goal(future: Any) -> None:
        handle = future.result()
        if not handle.accepted:
            box["rejected"] = True
            return
        box["handle"] = handle
        handle.get_result_async().add_done_callback(
            lambda f: box.setdefault("result", f.result().result))

    client.send_goal_async(goal).add_done_callback(on_goal)
    return box


def _end_hold(runner: RunningBringup, answer: dict[str, Any], timeout_s: float = 5.0) -> None:
    """Cancel the grasp that still holds (the fingers stay where they are) and wait for its
    answer before the release: a release sent over it would preempt it, which the gripper
    reports as an aborted goal (a WARN in a normal run)."""
    handle = answer.get("handle")
    if handle is None or "result" in answer:
        return
    handle.cancel_goal_async()
    deadline = runner.now() + timeout_s
    while "result" not in answer and runner.now() < deadline and runner.wait(0.02):
        pass


def _settle(runner: RunningBringup, truth: _Truth, goal: Any, answer: dict[str, Any]
            ) -> bool:
    """Wait until the true grip stayed near the target (or the fixed hold answered)."""
    deadline = runner.now() + goal.timeout + 5.0
    since: float | None = None
    while runner.wait(0.02):
        if answer.get("rejected"):
            say("the grasp goal was rejected (see the gripper's log above)")
            return False
        result = answer.get("result")
        if result is not None:
            say(f"grasp result: contact={result.contact_detected} force={result.force:.3f} N "
                f"({result.message})")
            return bool(result.contact_detected)
        grip, _ = truth.traces()
        near = grip.value.size and abs(grip.value[-1] - goal.target_force) <= (
            SETTLED_FRACTION * goal.target_force)
        since = (since or runner.now()) if near else None
        if since is not None and runner.now() - since >= SETTLED_S:
            say(f"grasp holding: true grip {grip.value[-1]:.2f} N")
            return True
        if runner.now() > deadline:
            say(f"the grip did not reach {goal.target_force:.2f} N within the goal's timeout")
            return False
    return False


def _hold_lifted(runner: RunningBringup, mock: Any, truth: _Truth, lift_s: float,
                 lifted_s: float) -> bool:
    """Keep the object lifted for ``lifted_s``, saying how it goes; True if it fell."""
    start, said = runner.now(), -1
    while runner.now() - start < lifted_s and runner.wait(0.05):
        held = mock.world.latest.held
        if held is not None and held.dropped:
            say(f"the object fell out of the fingers {runner.now() - start:.2f} s after the "
                f"lift (slip {held.slip_m * 1e3:.1f} mm)")
            return True
        if int(runner.now() - start) != said:
            said = int(runner.now() - start)
            grip, slip = truth.traces()
            say(f"lifted {said} s: true grip {grip.at(math.inf):.2f} N, slip "
                f"{abs(slip.at(math.inf)) * 1e3:.2f} mm")
    held = mock.world.latest.held
    return bool(held is not None and held.dropped)


def _report(runner: RunningBringup, truth: _Truth, spec: Any, marks: dict[str, float],
            rise: tuple[float, float] | None, dropped: bool) -> None:
    deadline = runner.now() + CATCH_UP_S
    while truth.newest_s() < marks["end"] and runner.now() < deadline and runner.wait(0.05):
        pass
    grip, slip = truth.traces()
    lift = marks["lift"]
    spans = [("grasp", marks["grasp"], lift)]
    if rise is not None:
        spans += [("lift", lift, lift + rise[0]), ("load", lift + rise[0], lift + rise[1]),
                  ("hold", lift + rise[1], marks["set down"])]
    else:
        spans.append(("lift and hold", lift, marks["set down"]))
    down = marks["set down"]
    for name, start, end in spans:  # a fall cuts the lifted phases short
        if start < down:
            say(phase_summary(name, start, min(end, down), grip, slip).line())
        else:
            say(f"phase {name}: not reached (set down early)")
    say(phase_summary("set down and release", down, marks["end"], grip, slip).line())
    least = least_grip_n(peak_load_n(spec.mass_kg, spec.load), spec.friction_static)
    figures = lift_figures(lift, marks["set down"], rise, least, grip, slip,
                           truth.onsets, dropped)
    say(f"least grip for the peak load {least:.2f} N (load / (2 mu_s)); lift summary: "
        + figures.line())
