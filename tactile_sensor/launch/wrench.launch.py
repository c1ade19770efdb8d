"""Two modules on each side face of the skin on the bench: mock six-axis stage and gauge (or
real devices), the model with the six-column calibration, and the tactile driver publishing
force and torque.

    ros2 launch tactile_sensor wrench.launch.py [use_mock_hardware:=true] [protocol:=wrench]
        [adc_port:=/dev/ttyUSB0] [namespace:=...] [config:=extra.yaml] [record:=bag_folder]
"""

from tactile_sensor.configurations import WRENCH
from tactile_sensor.launch_description import build


def generate_launch_description():  # noqa: ANN201
    return build(WRENCH)
