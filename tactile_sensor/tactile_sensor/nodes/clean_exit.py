"""Spin a node until SIGINT or SIGTERM, then stop it while its ROS context is still valid.

rclpy's own signal handler shuts the context down the moment Ctrl-C arrives, before
``main`` gets control back: threads that publish on their own (the driver's ADC reader,
the mock rig's gauge) then publish on a dead context ("publisher's context is invalid"),
and the last log lines cannot reach /rosout. Here a signal only asks for a stop: the
node's ``finish`` (join its threads, close its bag, the lifecycle shutdown transition) runs
while the context is valid, and the context is shut down last, by the caller's
``with ros_session(...)`` (nodes/ros_session.py). A second Ctrl-C changes nothing
(``ros2 launch`` forwards one on top of the terminal's): once a stop is under way SIGINT is
ignored, not merely handled, because Python resets every signal it handles to the default
action when the interpreter finalizes, before rclpy's and Fast DDS's objects are torn down
(80-300 ms measured on Jazzy), and a Ctrl-C landing then killed the node (``ros2 launch``:
"process has died [... exit code -2]").

A node whose executor died (an exception escaped a callback) is shut down the same way
and then exits ``EXIT_EXECUTOR_DIED``, not 0: ``ros2 launch`` then reports "process has
died" and ``respawn`` restarts it; a signal other than SIGINT/SIGTERM ends the process
with that signal's status, as before.
"""

from __future__ import annotations

import signal
import sys
import threading
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from types import FrameType

from rclpy.executors import Executor
from rclpy.signals import SignalHandlerOptions

#: Give this to ``rclpy.init``: the stop handlers below replace rclpy's.
NO_RCLPY_SIGNAL_HANDLERS = SignalHandlerOptions.NO
SPIN_TIMEOUT_S = 0.1  # bounds how long a stop waits for the executor to notice it
EXECUTOR_SHUTDOWN_S = 2.0  # callbacks still running (e.g. a goal) get this long [s]
#: Exit status of a node whose executor died: Python's own for an uncaught exception.
EXIT_EXECUTOR_DIED = 1


def spin_until_signal(executor: Executor, finish: Callable[[], None]) -> int:
    """Spin ``executor`` until SIGINT/SIGTERM, stop spinning, run ``finish``, then shut the
    executor down. The caller destroys the nodes and shuts the context down afterwards.
    Returns the process's exit status: 0 after a signal, ``EXIT_EXECUTOR_DIED`` when an
    exception ended the executor's thread (its traceback printed as the thread ends).

    ``finish`` runs once the executor stopped waiting on the node's entities and running
    their callbacks: destroying a subscription, timer or publisher while another thread
    uses it raises ``InvalidHandle`` there ("exception was never retrieved"). Nothing
    ``finish`` does needs the executor: the transition runs in this thread, and the node's
    own threads publish directly.
    """
    stop = threading.Event()

    def on_signal(signum: int, frame: FrameType | None) -> None:
        stop.set()

    # The handlers stay (SIGINT's becomes SIG_IGN once stopping): the process is ending,
    # and a late Ctrl-C must not interrupt destroying the nodes.
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, on_signal)
    spinning = threading.Event()
    spinning.set()
    died: list[BaseException] = []

    def spin() -> None:
        try:
            while spinning.is_set() and executor.context.ok():
                executor.spin_once(timeout_sec=SPIN_TIMEOUT_S)
        except BaseException as exc:
            died.append(exc)
            raise  # threading's hook prints the traceback: a bug to report

    spinner = threading.Thread(target=spin, name="executor", daemon=True)
    spinner.start()
    try:
        while not stop.wait(0.2) and spinner.is_alive():
            pass
    finally:
        # SIG_IGN, unlike a Python handler, outlasts the interpreter's finalization.
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        spinning.clear()
        spinner.join()
        # Callbacks still running or queued in worker threads (a timer's last tick) end
        # before ``finish`` destroys what they use. A goal that keeps its worker longer
        # than EXECUTOR_SHUTDOWN_S is aborted by ``finish`` instead.
        closer = threading.Thread(target=_drain_then_shut_down, args=(executor,),
                                  name="executor-shutdown", daemon=True)
        closer.start()
        closer.join(EXECUTOR_SHUTDOWN_S)
    finish()
    if died:
        print(f"the executor stopped on {type(died[0]).__name__} (traceback above); the node "
              f"shut down and exits {EXIT_EXECUTOR_DIED}", file=sys.stderr)
        return EXIT_EXECUTOR_DIED
    return 0


def _drain_then_shut_down(executor: Executor) -> None:
    """Let a MultiThreadedExecutor's queued handlers run, then shut it down.

    rclpy 9.1 ``Executor.shutdown`` destroys its guard condition without waiting for the
    work it queued (its wait is skipped: ``if not self._is_shutdown`` right after setting
    it), and a handler still queued in the worker pool then triggers the destroyed guard:
    "The following exception was never retrieved: cannot use Destroyable because
    destruction was requested". Draining the pool first (rclpy keeps it in ``_executor``)
    avoids that; a SingleThreadedExecutor runs its handlers inline and queues none.
    """
    pool = getattr(executor, "_executor", None)
    if isinstance(pool, ThreadPoolExecutor):
        pool.shutdown(wait=True)
    executor.shutdown()
