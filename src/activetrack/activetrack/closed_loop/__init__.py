"""The closed loop: simulator, tracker and planner components and the batch runner.

See docs/closed-loop.md for the epoch protocol the ROS graph follows too.
"""
