"""activetrack core: ROS-free models, sensors, filters, bounds and planning.

This package never imports rclpy; the ROS nodes are thin wrappers around it. Importing it
changes no process-wide setting: the glibc allocator tuning that makes planning and particle
filtering faster (activetrack.allocator) is opt-in; the command line and the nodes turn it on.
"""

__version__ = "0.1.0"
