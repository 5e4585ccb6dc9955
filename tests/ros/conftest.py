"""Fixtures for tests that spin nodes in-process (no launch)."""

import pytest

rclpy = pytest.importorskip("rclpy", reason="ROS tests need the workspace venv (make setup)")

from activetrack_bringup.inprocess import InProcessGraph  # noqa: E402


@pytest.fixture
def graph():
    """A fresh rclpy context with an executor; every node added to it is destroyed after."""
    g = InProcessGraph()
    try:
        yield g
    finally:
        g.close()
    assert not g.context.ok()


@pytest.fixture
def localhost_discovery(monkeypatch):
    """For tests with node processes: DDS discovery between processes on this host
    (tests/conftest.py switches it off for everything else). The domain stays private."""
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
