"""Spin a node until SIGINT or SIGTERM, then stop it while its ROS context is still valid.

rclpy's own signal handler shuts the context down the moment Ctrl-C arrives, before
``main`` gets control back: threads that publish on their own (the driver's ADC dispatch,
the mock rig's gauge) then publish on a dead context ("publisher's context is invalid"),
and the last log lines cannot reach /rosout. Here a signal only asks for a stop: the
node's ``finish`` (join its threads, close its bag, the lifecycle shutdown transition) runs
while the executor still spins, and the context is shut down last, by the caller's
``with rclpy.init(...)``. A second Ctrl-C changes nothing (``ros2 launch`` forwards one
on top of the terminal's).
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Callable
from types import FrameType

from rclpy.executors import Executor
from rclpy.signals import SignalHandlerOptions

#: Give this to ``rclpy.init``: the stop handlers below replace rclpy's.
NO_RCLPY_SIGNAL_HANDLERS = SignalHandlerOptions.NO
SPIN_TIMEOUT_S = 0.1  # bounds how long a stop waits for the executor to notice it


def spin_until_signal(executor: Executor, finish: Callable[[], None]) -> None:
    """Spin ``executor`` until SIGINT/SIGTERM, run ``finish`` while it still spins, then
    stop spinning. The caller destroys the nodes and shuts the context down afterwards."""
    stop = threading.Event()

    def on_signal(signum: int, frame: FrameType | None) -> None:
        stop.set()

    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, on_signal)
    spinning = threading.Event()
    spinning.set()

    def spin() -> None:
        while spinning.is_set() and executor.context.ok():
            executor.spin_once(timeout_sec=SPIN_TIMEOUT_S)

    spinner = threading.Thread(target=spin, name="executor", daemon=True)
    spinner.start()
    try:
        while not stop.wait(0.2) and spinner.is_alive():
            pass
        finish()
    finally:
        # The stop handlers stay: the process is ending, and a late Ctrl-C must not
        # interrupt destroying the nodes.
        spinning.clear()
        spinner.join()
        executor.shutdown()
