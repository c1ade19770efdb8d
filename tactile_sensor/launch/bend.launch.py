"""A soft finger bending at its joint with modules clipped on its skin: the mock finger (or
the real ADC) and the tactile driver publishing the joint angle on ~/joint_states and the
fingertip's contact force on ~/wrench.

    ros2 launch tactile_sensor bend.launch.py [use_mock_hardware:=true] [protocol:=sweep]
        [adc_port:=/dev/ttyACM0] [namespace:=...] [config:=extra.yaml] [record:=bag_folder]
"""

from tactile_sensor.configurations import BEND
from tactile_sensor.launch_description import build


def generate_launch_description():  # noqa: ANN201
    return build(BEND)
