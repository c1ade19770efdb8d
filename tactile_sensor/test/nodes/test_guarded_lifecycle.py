"""Transitions run one at a time: a ChangeState that arrives while another thread's
transition runs (the in-process bringup's ``trigger_configure``) waits for it, then is done
or refused from the state it left. Without the lock, a request for the running transition's
own next step (id 10, on_configure_success, valid only while 'configuring') is taken in
the middle of it, and the transition's thread then fails in rcl. (While it waits, the
node's other lifecycle services wait too: they share its default, mutually exclusive,
callback group.)"""

from __future__ import annotations

import threading

import rclpy
from lifecycle_msgs.msg import Transition
from lifecycle_msgs.srv import ChangeState
from rclpy.executors import MultiThreadedExecutor
from rclpy.lifecycle import State, TransitionCallbackReturn
from waiting import PATIENCE_S, wait_until

from tactile_sensor.nodes.background_spin import BackgroundSpin
from tactile_sensor.nodes.guarded_lifecycle import GuardedLifecycleNode
from tactile_sensor.nodes.ros_session import ros_session


class SlowToConfigure(GuardedLifecycleNode):
    """Its configure ends only once the executor has taken a ChangeState request."""

    def __init__(self) -> None:
        super().__init__("slow_to_configure")
        self.configuring = threading.Event()
        self.request_taken = threading.Event()
        for service in self.services:
            if service.srv_type is ChangeState:
                guarded = service.callback

                def taken(request, response, guarded=guarded):
                    if self.configuring.is_set():  # not the warm-up request
                        self.request_taken.set()
                    return guarded(request, response)

                service.callback = taken

    def on_configure(self, state: State) -> TransitionCallbackReturn:
        self.configuring.set()
        self.request_taken.wait(PATIENCE_S)
        return TransitionCallbackReturn.SUCCESS


def refused_once_heard(change) -> bool:
    """Send a refused id until one answer comes (a new client's first may be lost)."""
    request = ChangeState.Request()
    request.transition.id = 99
    for _ in range(6):
        future = change.call_async(request)
        if wait_until(future.done, 10.0):
            return future.result().success is False
        change.remove_pending_request(future)
    return False


def test_a_request_during_a_transition_waits_for_it_then_is_refused(ros_domain):
    with ros_session():
        node, client_node = SlowToConfigure(), rclpy.create_node("transition_client")
        executor = MultiThreadedExecutor(num_threads=4)
        executor.add_node(node)
        executor.add_node(client_node)
        spin = BackgroundSpin(executor)
        try:
            change = client_node.create_client(ChangeState, "/slow_to_configure/change_state")
            assert change.wait_for_service(timeout_sec=PATIENCE_S)
            assert refused_once_heard(change)  # the reply path is matched from here on
            outcome: list[TransitionCallbackReturn] = []
            thread = threading.Thread(target=lambda: outcome.append(node.trigger_configure()))
            thread.start()
            assert node.configuring.wait(PATIENCE_S)
            request = ChangeState.Request()
            request.transition.id = Transition.TRANSITION_ON_CONFIGURE_SUCCESS
            answer = change.call_async(request)  # taken during the transition, then waits
            thread.join(PATIENCE_S)
            assert outcome == [TransitionCallbackReturn.SUCCESS]
            assert wait_until(answer.done, PATIENCE_S)
            assert answer.result().success is False
            assert node._state_machine.current_state[1] == "inactive"
        finally:
            node.request_taken.set()
            spin.stop()
            node.destroy_node()
            client_node.destroy_node()
