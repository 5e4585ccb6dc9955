"""``activetrack ros ...``: stand-ins for the ROS 2 command line (not on PyPI) on any graph,
generic over topics and types (docs/ros-tools.md)."""
