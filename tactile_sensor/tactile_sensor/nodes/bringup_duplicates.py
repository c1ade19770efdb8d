"""Refuse an in-process bringup whose node names already run in its ROS domain.

Two bringups (or a bringup beside ``ros2 launch``) in one domain with the same names share
every topic: each gripper hears both drivers' forces, each recorder records both, and the
second's mock hardware replaces the first's device links under /tmp (measured: two
``bringup gripper --protocol idle`` both ran on to exit 0 that way). So the second is
refused in one sentence before it creates anything, two ways:

* on this host, a lock per domain and namespace (``claim_bringup``), held while the
  bringup runs and released by the kernel however the process ends: certain and instant;
* anywhere in the domain (``ros2 launch``, another host), the ROS graph: the wait ends as
  soon as one of the names is seen, and a bringup with nothing to collide with waits
  ``DISCOVERY_S``. Discovery is not bounded: at load 20 on this 2-core machine a running
  bringup's nodes took 1.2-5.6 s to be seen, so a launch found late is missed (both then
  run, as before this check).
"""

from __future__ import annotations

import fcntl
import os
import re
import tempfile
import time
from collections.abc import Iterable
from pathlib import Path
from typing import IO

import rclpy

from tactile_sensor.configurations import Configuration

#: How long to look for a duplicate before starting [s] (see the module docstring).
DISCOVERY_S = 1.0
POLL_S = 0.02


def bringup_node_names(configuration: Configuration, namespace: str, use_mock: bool,
                       record: bool) -> list[str]:
    """The fully qualified names the bringup would create, e.g. ['/driver', '/gripper']."""
    ns = "/" + namespace.strip("/") if namespace.strip("/") else ""
    names = [spec.name for spec in configuration.nodes if use_mock or not spec.mock_only]
    return [f"{ns}/{name}" for name in (["recorder"] if record else []) + names]


def running_already(names: Iterable[str], within_s: float = DISCOVERY_S) -> list[str]:
    """Those of ``names`` a node of this domain already has, looked for up to ``within_s``
    (needs ``rclpy.init``; the looking node is gone again on return)."""
    wanted = set(names)
    probe = rclpy.create_node(f"bringup_check_{os.getpid()}")
    try:
        deadline = time.monotonic() + within_s
        while True:
            found = sorted(wanted & {(ns.rstrip("/") + "/" + name)
                                     for name, ns in probe.get_node_names_and_namespaces()})
            if found or time.monotonic() >= deadline:
                return found
            time.sleep(POLL_S)
    finally:
        probe.destroy_node()


def duplicate_refusal(names: list[str]) -> str | None:
    """One sentence refusing the bringup when its names run already (None: they do not)."""
    found = running_already(names)
    if not found:
        return None
    domain = os.environ.get("ROS_DOMAIN_ID", "0")
    return (f"node(s) {', '.join(found)} already run in ROS domain {domain} (another bringup "
            "or launch); stop them, or start this bringup with --namespace NAME or another "
            "ROS_DOMAIN_ID.")


class BringupClaim:
    """This host's claim on a domain and namespace: ``refusal`` None when the bringup may
    start. The lock lives as long as this object (or the process)."""

    def __init__(self, lock: IO[str] | None, refusal: str | None) -> None:
        self._lock = lock
        self.refusal = refusal


def claim_bringup(names: list[str], namespace: str) -> BringupClaim:
    """Take this host's lock for the domain and namespace, then look at the graph."""
    domain = os.environ.get("ROS_DOMAIN_ID", "0")
    tag = re.sub(r"[^A-Za-z0-9_]", "_", namespace.strip("/")) or "_"
    folder = Path(tempfile.gettempdir()) / "tactile_sensor"
    folder.mkdir(parents=True, exist_ok=True)
    lock = (folder / f"bringup-domain{domain}-{tag}.lock").open("a")
    try:
        fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        lock.close()
        return BringupClaim(None, f"another bringup with namespace '{namespace or '/'}' runs "
                            f"on this host in ROS domain {domain}; stop it, or start this "
                            "one with --namespace NAME or another ROS_DOMAIN_ID.")
    refusal = duplicate_refusal(names)
    if refusal is not None:
        lock.close()
    return BringupClaim(lock if refusal is None else None, refusal)
