"""What a supervisor sees when a node dies: a node whose executor stops on an exception
exits 1 after its shutdown ran (``ros2 launch`` reports "process has died", ``respawn``
restarts it), a lifecycle node's and a plain node's main alike; a signal other than SIGINT
or SIGTERM ends it with that signal's status. SIGINT and SIGTERM end a node with 0
(test_clean_exit.py, test_requests_never_stop_a_node.py).

The exception comes from a timer of a node the test defines, run by the product's own
mains (``run_lifecycle_node``, ``run_plain_node``): no request of ours can raise any more
(test_requests_never_stop_a_node.py), and the product has no test switch.
"""

from __future__ import annotations

import signal
import sys

import pytest
from waiting import PATIENCE_S

pytestmark = [pytest.mark.ros]

NODE = '''
import sys
from rclpy.node import Node
from tactile_sensor.nodes.guarded_lifecycle import GuardedLifecycleNode
from tactile_sensor.nodes.lifecycle_main import run_lifecycle_node, run_plain_node

KIND, FAIL = sys.argv[1], sys.argv[2] == "fail"


def tick(node):
    if FAIL:
        raise RuntimeError("a bug in a timer callback")
    print("ticking", flush=True)


class Lifecycle(GuardedLifecycleNode):
    def __init__(self):
        super().__init__("exit_status_node")
        self.timer = self.create_timer(0.05, lambda: tick(self))

    def on_shutdown(self, state):
        print("shutdown transition ran", flush=True)
        return super().on_shutdown(state)


class Plain(Node):
    def __init__(self):
        super().__init__("exit_status_node")
        self.timer = self.create_timer(0.05, lambda: tick(self))


if KIND == "lifecycle":
    sys.exit(run_lifecycle_node(Lifecycle))
sys.exit(run_plain_node("plain", Plain, (), lambda node: print("finish ran", flush=True)))
'''


@pytest.mark.parametrize(("kind", "finished"), [("lifecycle", "shutdown transition ran"),
                                                ("plain", "finish ran")])
def test_a_node_whose_executor_died_exits_1_after_its_shutdown(ros_domain, spawn, kind,
                                                               finished):
    node = spawn(sys.executable, "-c", NODE, kind, "fail")
    assert node.proc.wait(PATIENCE_S) == 1, node.output()
    output = node.output()
    assert "RuntimeError: a bug in a timer callback" in output, output
    assert finished in output, output
    assert "the executor stopped on RuntimeError" in output, output


def test_a_signal_other_than_sigint_or_sigterm_gives_its_status(ros_domain, spawn):
    node = spawn(sys.executable, "-c", NODE, "lifecycle", "run")
    assert node.wait_for_output("ticking", PATIENCE_S), node.output()
    node.proc.send_signal(signal.SIGHUP)
    assert node.proc.wait(PATIENCE_S) == -signal.SIGHUP, node.output()
