"""Sensor data as a filter takes it, from a simulator or a real robot.

* :mod:`filters.robot_data.scans` -- :class:`~filters.robot_data.scans.LaserScan` and
  :class:`~filters.robot_data.scans.SemanticScan`.
"""
