"""The closed loop: simulator, tracker and planner components and the batch runner (the epoch
protocol, which the ROS graph follows too: docs/closed-loop.md)."""
