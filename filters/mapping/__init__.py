"""Maps: grids, mapping from scans with known poses, ROS map files, map quality.

* `filters.mapping.grid` -- `GridMap` (occupancy + per-class grids).
* `filters.mapping.occupancy` -- log-odds occupancy and semantic mapping from scans.
* `filters.mapping.ros_map` -- ROS map_server files (PGM/YAML + semantic sidecar).
* `filters.mapping.metrics` -- map quality against a reference.
"""
