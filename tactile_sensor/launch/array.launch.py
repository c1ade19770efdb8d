"""Modules on four faces of the skin on the bench: mock three-axis stage and gauge (or real
devices), the model with the array calibration, and the tactile driver publishing
force.x/y/z.

    ros2 launch tactile_sensor array.launch.py [use_mock_hardware:=true] [protocol:=shear]
        [adc_port:=/dev/ttyACM0] [namespace:=...] [config:=extra.yaml] [record:=bag_folder]
"""

from tactile_sensor.configurations import ARRAY
from tactile_sensor.launch_description import build


def generate_launch_description():  # noqa: ANN201
    return build(ARRAY)
