"""Sensor data as a filter takes it, from a simulator or a real robot.

* `filters.robot_data.scans` -- `LaserScan` (with
  `from_ros` and a sensor mounting pose) and
  `SemanticScan`.
* `filters.robot_data.carmen` -- `read_carmen`, a CARMEN log reader.
"""
