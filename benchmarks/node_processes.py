"""Nodes a benchmark starts as child processes: kept to this machine in the benchmark's own
ROS domain, and stopped as ``ros2 launch`` stops them (SIGINT, then a kill for one that
hangs)."""

from __future__ import annotations

import os
import signal
import subprocess


def isolate_ros(domain: int | str) -> None:
    """This benchmark's ROS domain ($ROS_DOMAIN_ID wins) and discovery on this machine only,
    so that runs beside each other do not hear one another."""
    os.environ.setdefault("ROS_DOMAIN_ID", str(domain))
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"


def interrupt(*procs: subprocess.Popen, timeout_s: float) -> None:  # type: ignore[type-arg]
    """SIGINT to every process first (they shut down side by side), then wait for each and
    kill the ones still running after ``timeout_s``."""
    for proc in procs:
        proc.send_signal(signal.SIGINT)
    for proc in procs:
        try:
            proc.wait(timeout_s)
        except subprocess.TimeoutExpired:
            proc.kill()
