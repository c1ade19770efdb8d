"""The paper's compression bench: mock stage and force gauge (or real devices), the model,
and the tactile driver.

    ros2 launch tactile_sensor bench.launch.py [use_mock_hardware:=true] [protocol:=compression]
        [scenario:=office] [adc_port:=/dev/ttyACM0] [namespace:=...] [config:=extra.yaml]
        [record:=bag_folder]
"""

from tactile_sensor.configurations import BENCH
from tactile_sensor.launch_description import build


def generate_launch_description():  # noqa: ANN201
    return build(BENCH)
