from glob import glob

from setuptools import find_packages, setup

PACKAGE = "tactile_sensor"

setup(
    name=PACKAGE,
    version="0.2.0",
    packages=find_packages(exclude=["test", "test.*"]),
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
        (f"share/{PACKAGE}/launch", glob("launch/*.launch.py")),
        (f"share/{PACKAGE}/config", glob("config/*.yaml")),
        (f"share/{PACKAGE}/urdf", glob("urdf/*.xacro")),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="tactile_sensor developers",
    maintainer_email="tactile-sensor@example.com",
    description="Photoreflective tactile sensing for soft robots (driver, gripper, FEM model).",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "tactile-sensor = tactile_sensor.cli:main",
            "driver_node = tactile_sensor.nodes.driver:main",
            "gripper_node = tactile_sensor.nodes.gripper:main",
            "model_node = tactile_sensor.nodes.model:main",
            "mock_hardware_node = tactile_sensor.nodes.mock_hardware:main",
            "recorder_node = tactile_sensor.nodes.recorder:main",
        ],
    },
)
