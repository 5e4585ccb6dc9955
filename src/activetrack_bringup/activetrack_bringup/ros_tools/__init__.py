"""``activetrack ros ...``: stand-ins for the ROS 2 command line (not on PyPI) on any graph,
generic over topics and types (docs/ros-tools.md).

This package module imports nothing: the command line builds its parsers from it before
rclpy loads (a Ctrl-C in the first second still gets its exit code)."""

# How long a tool lets DDS discovery fill in the graph before it answers: until nothing new
# appeared for SETTLE_S, at most DISCOVERY_S. There is no ros2 daemon keeping the graph, and a
# new participant learns of some others only at their next periodic announcement (Fast DDS:
# every 3 s; measured here: the runner's evaluator and recorder 2-3 s after the node
# processes), so a quiet spell shorter than that period proves nothing.
DISCOVERY_S = 10.0
SETTLE_S = 3.5
