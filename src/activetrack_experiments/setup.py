# Shim so that colcon (ament_python) builds the experiments too; the metadata lives in
# pyproject.toml.
from setuptools import setup

setup(
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/activetrack_experiments"]),
        ("share/activetrack_experiments", ["package.xml"]),
    ],
)
