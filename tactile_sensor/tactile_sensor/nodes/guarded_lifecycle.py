"""The lifecycle node every managed node of ours derives from: no request stops it.

rclpy's lifecycle node lets a ChangeState request for a transition the current state lacks
raise in the executor thread, which ends the process: on Jazzy (rclpy 7.1.6)
``__change_state`` calls ``trigger_transition_by_id`` unguarded, and ``RCLError: Failed to
trigger lifecycle state machine transition`` escapes the service callback ("activate"
sent while active, any id in ``finalized``). Kilted (rclpy 9.1.2) catches that error and
answers ``success: false``, but logs it as an error of the node. On both, a SetParameters
request whose value type is no ``ParameterType`` (e.g. 99) raises ``ValueError`` in
rclpy's parameter service (``Parameter.from_parameter_msg``), and an exception in an
on-set-parameters callback escapes the same way. Here:

* ``~/change_state`` refuses (``success: false``, one warning naming the state and its
  transitions) every transition the current state lacks, by id or by label, before rcl
  sees it; the rest run as rclpy runs them.
* Transitions are serialised: the service and ``trigger_*`` (autostart, the in-process
  bringup, the shutdown at exit) take one lock, so two requests at once run one after the
  other and the second is done or refused from the state the first left.
* A parameter rclpy cannot read, one the node lacks, and a parameter callback that raises,
  are refused with the reason (the callbacks' own refusals are unchanged; rclpy's own
  reason for an unknown name lists no name: "Invalid access to undeclared parameter(s): []").

Only requests are guarded: an exception in a timer or subscription still ends the process
(non-zero, ``nodes/clean_exit.py``), where a supervisor sees it.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any

from lifecycle_msgs.srv import ChangeState
from rcl_interfaces.msg import SetParametersResult
from rcl_interfaces.srv import SetParameters, SetParametersAtomically
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.lifecycle import Node, TransitionCallbackReturn
from rclpy.node import Node as RclpyNode
from rclpy.parameter import Parameter

#: A parameter callback as rclpy calls it (on-set: returns a result; post-set: None).
ParameterCallback = Callable[[list[Parameter]], Any]
#: The value types rclpy reads (rcl_interfaces/msg/ParameterType); any other raises there.
PARAMETER_TYPES = frozenset(kind.value for kind in Parameter.Type)


class GuardedLifecycleNode(Node):
    """``rclpy.lifecycle.Node`` whose requests are done or refused, never fatal."""

    def __init__(self, node_name: str, **kwargs: Any) -> None:
        self._transitions = threading.RLock()
        super().__init__(node_name, **kwargs)
        guard_parameter_services(self)
        for service in self.services:
            if service.srv_type is ChangeState:
                service.callback = _guarded_change_state(self, service.callback)

    # -- transitions, one at a time ------------------------------------------------------------
    def trigger_configure(self) -> TransitionCallbackReturn:
        with self._transitions:
            return super().trigger_configure()

    def trigger_cleanup(self) -> TransitionCallbackReturn:
        with self._transitions:
            return super().trigger_cleanup()

    def trigger_activate(self) -> TransitionCallbackReturn:
        with self._transitions:
            return super().trigger_activate()

    def trigger_deactivate(self) -> TransitionCallbackReturn:
        with self._transitions:
            return super().trigger_deactivate()

    def trigger_shutdown(self) -> TransitionCallbackReturn:
        with self._transitions:
            return super().trigger_shutdown()

    def refusal(self, transition_id: int, label: str) -> str | None:
        """Why the current state cannot take this transition (None: it can). A label, when
        given, names the transition, as in rclpy (the id is then ignored)."""
        state = self._state_machine.current_state[1]
        # (id, label, start id, start label, goal id, goal label) of the current state's
        # transitions; the same tuple on rclpy 7.1 and 9.1
        available = [(t[0], t[1]) for t in self._state_machine.available_transitions]
        if any((label == name) if label else (transition_id == number)
               for number, name in available):
            return None
        asked = f"'{label}'" if label else f"id {transition_id}"
        offered = ", ".join(f"{name} ({number})" for number, name in available)
        return (f"transition {asked} refused: state '{state}' offers "
                + (offered if offered else "none (finalized: restart the node)") + ".")

    # -- parameter callbacks that raise are refusals -------------------------------------------
    def add_on_set_parameters_callback(self, callback: ParameterCallback) -> None:
        super().add_on_set_parameters_callback(_refusing_on_error(self, callback))

    def add_post_set_parameters_callback(self, callback: ParameterCallback) -> None:
        super().add_post_set_parameters_callback(_logging_on_error(self, callback))


def _guarded_change_state(node: GuardedLifecycleNode, serve: Callable[[Any, Any], Any]
                          ) -> Callable[[Any, Any], Any]:
    def change_state(request: ChangeState.Request, response: ChangeState.Response
                     ) -> ChangeState.Response:
        with node._transitions:
            reason = node.refusal(request.transition.id, request.transition.label)
            if reason is not None:
                node.get_logger().warning(reason)
                response.success = False
                return response
            try:
                return serve(request, response)
            except _rclpy.RCLError as exc:  # rclpy 7.1: rcl refused a step of it
                node.get_logger().error(f"transition {request.transition.id} failed: {exc}")
                response.success = False
                return response

    return change_state


def guard_parameter_services(node: RclpyNode) -> None:
    """Make rclpy's set_parameters services of ``node`` refuse what they cannot read (any
    node: the plain ones' executables call this too, ``nodes/lifecycle_main.py``)."""
    for service in node.services:
        if service.srv_type is SetParameters:
            service.callback = _guarded_set_parameters(node, service.callback)
        elif service.srv_type is SetParametersAtomically:
            service.callback = _guarded_set_parameters_atomically(node, service.callback)


def _refusal_of(node: RclpyNode, param: Any) -> str | None:
    """Why a parameter message cannot be set at all (None: the node's callbacks decide)."""
    if param.value.type not in PARAMETER_TYPES:
        return (f"Parameter '{param.name}' has value type {param.value.type}, which is none "
                "of rcl_interfaces/msg/ParameterType (0-9); give a typed value.")
    if not node.has_parameter(param.name):
        return (f"Parameter '{param.name}' is not one of {node.get_fully_qualified_name()}'s; "
                f"'ros2 param list {node.get_fully_qualified_name()}' lists them.")
    return None


def _guarded_set_parameters(node: RclpyNode, serve: Callable[[Any, Any], Any]
                            ) -> Callable[[Any, Any], Any]:
    """SetParameters: each parameter rclpy cannot read or the node lacks is refused with
    its reason; the others are set one by one, as rclpy does."""

    def set_parameters(request: SetParameters.Request, response: SetParameters.Response
                       ) -> SetParameters.Response:
        refusals = [_refusal_of(node, p) for p in request.parameters]
        served = iter(serve(SetParameters.Request(parameters=[
            p for p, why in zip(request.parameters, refusals, strict=True) if why is None]),
            SetParameters.Response()).results)
        response.results = [SetParametersResult(successful=False, reason=why)
                            if why is not None else next(served) for why in refusals]
        return response

    return set_parameters


def _guarded_set_parameters_atomically(node: RclpyNode, serve: Callable[[Any, Any], Any]
                                       ) -> Callable[[Any, Any], Any]:
    """SetParametersAtomically: a parameter rclpy cannot read or the node lacks refuses
    the whole request, nothing set."""

    def set_parameters_atomically(request: SetParametersAtomically.Request,
                                  response: SetParametersAtomically.Response
                                  ) -> SetParametersAtomically.Response:
        for param in request.parameters:
            if (why := _refusal_of(node, param)) is not None:
                response.result = SetParametersResult(
                    successful=False, reason=why + " Nothing of this request was set.")
                return response
        return serve(request, response)

    return set_parameters_atomically


def _refusing_on_error(node: Node, callback: ParameterCallback) -> ParameterCallback:
    def on_set(params: list[Parameter]) -> SetParametersResult:
        try:
            return callback(params)
        except Exception as exc:  # a request must not stop the node: refuse, say why
            names = ", ".join(p.name for p in params)
            reason = f"Parameter(s) {names} refused: {type(exc).__name__}: {exc}"
            node.get_logger().error(reason)
            return SetParametersResult(successful=False, reason=reason)

    return on_set


def _logging_on_error(node: Node, callback: ParameterCallback) -> ParameterCallback:
    def post_set(params: list[Parameter]) -> None:
        try:
            callback(params)
        except Exception as exc:  # set already: say it did not take effect
            names = ", ".join(p.name for p in params)
            node.get_logger().error(
                f"Parameter(s) {names} were set but not applied ({type(exc).__name__}: "
                f"{exc}); set them again, or reconfigure the node.")

    return post_set
