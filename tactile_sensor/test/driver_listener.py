"""A node that listens to the driver from a background executor, for the driver's tests
(conftest.py puts this folder on ``sys.path``): subclasses add their subscriptions in
``subscribe``; the node spins once they are made."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import rclpy
import rclpy.client
import rclpy.executors
from std_srvs.srv import Trigger
from waiting import PATIENCE_S, wait_until

from tactile_sensor.nodes.background_spin import BackgroundSpin
from tactile_sensor.nodes.ros_session import ros_session


class DriverListener:
    def __init__(self, name: str) -> None:
        self.node = rclpy.create_node(name)
        self._tare_client: rclpy.client.Client | None = None
        self.subscribe()
        self.executor = rclpy.executors.SingleThreadedExecutor()
        self.executor.add_node(self.node)
        self.spin = BackgroundSpin(self.executor)

    def subscribe(self) -> None:
        """Create the subscriptions (before the node spins)."""

    @staticmethod
    def wait_for(predicate, timeout_s: float) -> bool:  # type: ignore[no-untyped-def]
        return wait_until(predicate, timeout_s)

    def call_tare(self) -> Trigger.Response:
        """The driver's ``~/tare``, answered (the test fails if it never is)."""
        if self._tare_client is None:
            self._tare_client = self.node.create_client(Trigger, "/driver/tare")
        client = self._tare_client
        assert client.wait_for_service(timeout_sec=PATIENCE_S)
        future = client.call_async(Trigger.Request())
        assert wait_until(future.done, PATIENCE_S)
        return future.result()

    def close(self) -> None:
        self.spin.stop()
        self.node.destroy_node()

    @classmethod
    @contextmanager
    def listening(cls) -> Iterator[DriverListener]:
        """One listener in its own ROS session, closed after the test."""
        with ros_session():
            listener = cls()
            try:
                yield listener
            finally:
                listener.close()


def start_driver(spawn, link: Path, calibration: Path, *extra: str):  # type: ignore[no-untyped-def]
    """The driver node on ``link`` with a calibration file, active at once."""
    return spawn("--ros-args", "-r", "__node:=driver", "-p", f"port:={link}",
                 "-p", "calibration_source:=file", "-p", f"calibration_file:={calibration}",
                 "-p", "autostart:=true", *extra, module="tactile_sensor.nodes.driver")
