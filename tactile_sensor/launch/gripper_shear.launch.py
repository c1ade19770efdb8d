"""The soft gripper with a fingertip that feels shear: modules on four side faces of finger
A's skin, so the driver's wrench carries the force along the fingers.

    ros2 launch tactile_sensor gripper_shear.launch.py [use_mock_hardware:=true]
        [adc_port:=/dev/ttyACM0] [servo_port:=/dev/ttyUSB0] [namespace:=...]
        [config:=extra.yaml] [record:=bag_folder]
"""

from tactile_sensor.configurations import GRIPPER_SHEAR
from tactile_sensor.launch_description import build


def generate_launch_description():  # noqa: ANN201
    return build(GRIPPER_SHEAR)
