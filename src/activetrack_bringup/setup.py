from setuptools import find_packages, setup

package_name = "activetrack_bringup"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
        # ros2 launch activetrack_bringup activetrack.launch.py (a full ROS 2 install)
        ("share/" + package_name + "/launch", ["launch/activetrack.launch.py"]),
    ],
    # The Python distributions the modules import (tests/setup/test_package_deps.py); the ROS
    # packages are in package.xml (rosdep); versions in the workspace's constraints.txt.
    install_requires=[
        "activetrack",
        "activetrack-experiments",
        "activetrack_ros",
        "sim_node",
        "tracker_node",
        "planner_node",
        "numpy",
        "pyyaml",
        "rosbags",
        "mcap",
        "lz4",
        "zstandard",
        "tqdm",
        "foxglove-sdk",
    ],
    extras_require={"test": ["pytest", "hypothesis", "mcap-ros2-support"]},
    zip_safe=True,
    maintainer="activetrack developers",
    maintainer_email="dev@activetrack.invalid",
    description="See package.xml.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "activetrack = activetrack_bringup.cli:main",
            # the runner's evaluator and recorder as nodes of their own (the launch file's)
            "activetrack_evaluator = activetrack_bringup.standalone:evaluator_main",
            "activetrack_recorder = activetrack_bringup.standalone:recorder_main",
        ]
    },
)
