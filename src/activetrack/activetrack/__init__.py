"""activetrack core: ROS-free models, sensors, filters, bounds and planning.

This package never imports rclpy; the ROS nodes are thin wrappers around it.
"""

__version__ = "0.1.0"
