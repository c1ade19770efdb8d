"""The gripper's parameters in process tests that are about something other than its timing.

Beside a busy core (the suite's own setting) the mock, the driver and the gripper are Python
processes that get a share of two cores, and each of these bounds was once crossed there:

- ``tactile_timeout`` (0.2 s configured): the driver keeps every ADC sample (none is dropped
  to catch up), so a starved driver's forces arrive late, not seldom. Beside two busy loops
  the in-process bringup's forces carried stamps 3.7 s old while they still arrived at most
  0.43 s apart, and a GripperCommand aborted "tactile_stale: no tactile force for 1.262 s"
  under the 1 s this once was. A goal rightly aborts on a force that old (tested in
  test/control); these tests are not about that.
- ``packet_timeout``, ``comm_retries``: the emulated servo can be kept from answering for
  longer than the 3 x 50 ms a real XM430 is given ("servo unreachable" mid-goal; the timeout:
  test/hardware/test_xm430_client.py).
- ``settle_time``: each of the hold's corrections waits for forces stamped after the fingers
  stopped, and 1 s once ran out at 2.84 N on a 2 N target; the settle ends once settled, so
  the longer bound costs nothing otherwise (running out is tested in test/control).
"""

GRIPPER_UNDER_LOAD: dict[str, float | int] = {
    "tactile_timeout": 5.0, "packet_timeout": 0.5, "comm_retries": 4, "settle_time": 5.0}
