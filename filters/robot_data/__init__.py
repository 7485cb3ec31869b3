"""Sensor data as a filter takes it, from a simulator or a real robot.

* `filters.robot_data.scans` -- `LaserScan` (with
  `from_ros` and a sensor mounting pose) and
  `SemanticScan`.
* `filters.robot_data.carmen` -- `read_carmen`, a CARMEN log reader.
* `ACES_LOG` -- a real robot's log shipped with the package (the ACES building, CARMEN format; its
  ``data/README.md``).
"""

from pathlib import Path

ACES_LOG = Path(__file__).parent / "data" / "aces-corrected.log.gz"
"""The ACES building's corrected CARMEN log (440 scans of 180 beams), installed with the package."""
