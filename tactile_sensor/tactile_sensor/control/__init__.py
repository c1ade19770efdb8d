"""control layer: pure grasp/release logic for the gripper (no rclpy, no I/O)."""
