"""The gripper's parameters: names, defaults, units and ranges (``ros2 param describe``),
in one list apart from the node, so that nodes/gripper.py reads as wiring."""

from __future__ import annotations

from tactile_sensor.nodes.parameters import ParamSpec

SPECS = [
    ParamSpec("port", "/dev/ttyUSB0", "serial device of the Dynamixel bus (U2D2)"),
    ParamSpec("baud_rate", 1_000_000, "Dynamixel bus baud rate [bit/s]", minimum=9600,
              maximum=4_500_000),
    ParamSpec("servo_id", 1, "Dynamixel id of the XM430", minimum=0, maximum=252),
    ParamSpec("geometry.pitch_radius", 0.014, "pinion pitch radius [m] (servo angle -> "
              "finger travel)", minimum=0.0, exclusive_minimum=True, maximum=0.2),
    ParamSpec("geometry.open_opening", 0.060, "finger opening at the open limit [m]",
              minimum=0.0, exclusive_minimum=True, maximum=1.0),
    ParamSpec("geometry.closed_opening", 0.002, "finger opening at the closed limit [m]",
              minimum=0.0, maximum=1.0),
    ParamSpec("current_limit", 1.0, "servo current limit and holding current cap [A]",
              minimum=0.0, exclusive_minimum=True, maximum=3.2),
    ParamSpec("closing_current", 0.6, "goal current while closing and holding [A] (<= "
              "current_limit)", minimum=0.0, exclusive_minimum=True, maximum=3.2),
    ParamSpec("default_closing_speed", 0.01, "finger speed when a goal gives 0 [m/s]",
              minimum=0.0, exclusive_minimum=True, maximum=0.2),
    ParamSpec("release_speed", 0.02, "finger speed while releasing [m/s]", minimum=0.0,
              exclusive_minimum=True, maximum=0.2),
    ParamSpec("default_timeout", 10.0, "grasp/release timeout when a goal gives 0 [s]",
              minimum=0.0, exclusive_minimum=True),
    ParamSpec("control_rate", 100.0, "servo sync-read and control loop rate while a goal "
              "runs [Hz]", minimum=1.0, maximum=1000.0),
    ParamSpec("idle_rate", 10.0, "servo sync-read rate while no goal runs, and so the rate "
              "of ~/joint_states and of taking the tactile force then [Hz] (<= control_rate)",
              minimum=0.5, maximum=1000.0),
    ParamSpec("tactile_timeout", 0.2, "abort a goal when the tactile force is older than "
              "this [s]; a goal that acts on the force and arrives before the first one "
              "waits this long for it before the fingers move, then aborts tactile_stale; "
              "also the longest a goal's control loop may go without a servo sample",
              minimum=0.0, exclusive_minimum=True),
    ParamSpec("feedback_rate", 50.0, "action feedback rate [Hz]", minimum=1.0,
              maximum=1000.0),
    ParamSpec("auto_reboot", False, "reboot the servo by itself after a hardware error"),
    ParamSpec("settle_time", 1.5, "after contact, regulate the force onto the target for "
              "at most this long [s] (0 = hold where contact was detected)", minimum=0.0,
              maximum=10.0),
    ParamSpec("skin_stiffness", 2500.0, "fingertip skin stiffness the contact stop assumes "
              "[N/m] (FEM: 1750 N/m at touch to 2850 N/m at 3 mm); the hold moves on the FEM "
              "skin's tangent at its target and on the servo's measured position",
              minimum=1.0),
    ParamSpec("packet_timeout", 0.05, "wait this long for a status packet [s]", minimum=0.001,
              maximum=1.0),
    ParamSpec("comm_retries", 2, "retries of a transaction that timed out or arrived "
              "damaged before the servo counts as unreachable", minimum=0, maximum=10),
    ParamSpec("joint_name", "finger_opening", "name of the finger-opening joint in "
              "~/joint_states, the URDF and ParallelGripperCommand goals"),
    ParamSpec("goal_tolerance", 0.0005, "a GripperCommand within this of its target "
              "position has reached it [m]", minimum=0.0, exclusive_minimum=True,
              maximum=0.01),
    ParamSpec("stall_timeout", 0.2, "a GripperCommand at rest short of its target this "
              "long has stalled [s]", minimum=0.0, exclusive_minimum=True, maximum=10.0),
    ParamSpec("max_grasp_force", 10.0, "the most a Grasp target_force or a GripperCommand / "
              "ParallelGripperCommand max_effort may ask [N]; the tactile sensor's full scale "
              "(latched by the driver on tactile_full_scale) lowers the ceiling further",
              minimum=0.0, exclusive_minimum=True, maximum=100.0),
    ParamSpec("allow_stalling", True, "a stalled GripperCommand (tactile force limit or "
              "current limit) succeeds; false: it aborts"),
    ParamSpec("self_check_speed", 0.001, "finger speed of a SelfCheck goal that gives 0 "
              "[m/s] (slow: the fit takes a sample per control tick)", minimum=0.0,
              exclusive_minimum=True, maximum=0.05),
    ParamSpec("self_check_backlash", 0.0, "play between pinion and racks the self-check's "
              "indentation map allows for [rad of the pinion]", minimum=0.0, maximum=0.2),
    ParamSpec("self_check_compliance", 0.0, "how far a rack lags the pinion per newton of "
              "rack force, in the self-check's indentation map [m/N]", minimum=0.0,
              maximum=1e-3),
    ParamSpec("hold_mode", "fixed", "the hold after contact when a goal names none: "
              "'fixed' (the target force) or 'adaptive' (the least grip that keeps the "
              "object plus a margin, raised on slip; needs shear_sensing); control_msgs "
              "goals with a max_effort always take this", choices=("fixed", "adaptive")),
    ParamSpec("hold_time", 0.0, "an adaptive hold runs this long before the goal's result "
              "[s] (0 = until a cancel or a newer goal)", minimum=0.0),
    ParamSpec("shear_sensing", False, "the tactile wrench carries the force along and across "
              "the fingers (configuration gripper_shear); an adaptive hold needs it"),
    ParamSpec("slip_bandwidth", 20.0, "low-pass cutoff of the adaptive hold's friction margin "
              "[Hz] (the slip study's choice; under half control_rate)", minimum=1.0,
              maximum=200.0),
]
