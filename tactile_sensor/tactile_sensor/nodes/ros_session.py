"""``rclpy.init`` as a context manager on every rclpy we support.

Kilted's ``rclpy.init`` returns a context manager; Jazzy's (rclpy 7) returns None, so
``with rclpy.init(...)`` fails there ("'NoneType' object does not support the context
manager protocol") and every node would fail to start. This one path works on both.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

import rclpy
from rclpy.signals import SignalHandlerOptions


@contextlib.contextmanager
def ros_session(args: list[str] | None = None,
                signal_handler_options: SignalHandlerOptions | None = None) -> Iterator[None]:
    """Initialise the default context; shut it down on leaving, unless already shut down."""
    if signal_handler_options is None:
        rclpy.init(args=args)
    else:
        rclpy.init(args=args, signal_handler_options=signal_handler_options)
    try:
        yield
    finally:
        rclpy.try_shutdown()
