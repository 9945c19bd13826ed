"""Helpers for testing fleets: isolation (ROS domains, ports, processes) and the pytest plugin."""
