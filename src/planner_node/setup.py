# colcon (ament_python) and pip build from here; the metadata is in setup.cfg.
from setuptools import setup

setup()
