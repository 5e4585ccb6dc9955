from setuptools import find_packages, setup

package_name = "tracker_node"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
    ],
    # The Python distributions the module imports (tests/setup/test_package_deps.py); the ROS
    # packages are in package.xml (rosdep); versions in the workspace's constraints.txt.
    install_requires=["activetrack", "activetrack_ros", "numpy"],
    extras_require={"test": ["pytest", "hypothesis"]},
    zip_safe=True,
    maintainer="activetrack developers",
    maintainer_email="dev@activetrack.invalid",
    description="See package.xml.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "tracker_node = tracker_node.tracker_node:main",
        ]
    },
)
