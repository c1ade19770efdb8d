"""The paper's soft gripper: XM430 with rack and pinion, tactile module on a fingertip.

    ros2 launch tactile_sensor gripper.launch.py [use_mock_hardware:=true]
        [adc_port:=/dev/ttyACM0] [servo_port:=/dev/ttyUSB0] [namespace:=...]
        [config:=extra.yaml] [record:=bag_folder]
"""

from tactile_sensor.configurations import GRIPPER
from tactile_sensor.launch_description import build


def generate_launch_description():  # noqa: ANN201
    return build(GRIPPER)
