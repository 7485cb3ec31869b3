"""Sensor data as a filter takes it, from a simulator or a real robot.

* :mod:`filters.robot_data.scans` -- :class:`~filters.robot_data.scans.LaserScan` (with
  :meth:`~filters.robot_data.scans.LaserScan.from_ros` and a sensor mounting pose) and
  :class:`~filters.robot_data.scans.SemanticScan`.
* :mod:`filters.robot_data.carmen` -- :func:`~filters.robot_data.carmen.read_carmen`, a CARMEN log reader.
"""
