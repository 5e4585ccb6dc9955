"""Shared ROS plumbing of the activetrack nodes (topic table, QoS, trust, node base)."""
