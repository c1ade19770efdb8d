"""An action client whose requests cannot lose their answer (ros2/rclpy#1123).

Jazzy's rclpy (7.1.6) sends a goal, cancel or result request first and files the future
that awaits its answer afterwards. An executor thread that takes and handles the answer in
between finds no future, logs "Ignoring unexpected goal response", and the caller's future
never completes. This was seen as a grasp goal that stayed unanswered for 60 s in a test
on a busy machine. Kilted's rclpy (9.1.2) closes the race with a lock. This class does the
same on both: sending and filing hold a lock, and so does taking an answer, so an answer is
only handled once its future is filed.
"""

from __future__ import annotations

import threading
from typing import Any

from rclpy.action import ActionClient


class RaceFreeActionClient(ActionClient):
    def __init__(self, *args: Any, **kwargs: Any) -> None:
        # Both before the base class adds the client to its node: an executor already
        # spinning that node may take it up at once. Kilted's rclpy creates its own '_lock'
        # only after adding it (an AttributeError in the spinning thread, which then stops);
        # this one stands in until the base class replaces it.
        self._filing = threading.RLock()
        self._lock = threading.Lock()
        super().__init__(*args, **kwargs)

    def send_goal_async(self, *args: Any, **kwargs: Any) -> Any:
        with self._filing:
            return super().send_goal_async(*args, **kwargs)

    def _cancel_goal_async(self, *args: Any, **kwargs: Any) -> Any:
        with self._filing:
            return super()._cancel_goal_async(*args, **kwargs)

    def _get_result_async(self, *args: Any, **kwargs: Any) -> Any:
        with self._filing:
            return super()._get_result_async(*args, **kwargs)

    def take_data(self) -> Any:
        with self._filing:
            return super().take_data()
