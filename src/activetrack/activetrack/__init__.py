"""activetrack core: ROS-free models, sensors, filters, bounds and planning.

This package never imports rclpy; the ROS nodes are thin wrappers around it.
"""

from activetrack.allocator import tune_allocator

__version__ = "0.1.0"

tune_allocator()  # numpy temporaries stay on the heap (see activetrack.allocator)
