"""Maps: grids, mapping from scans with known poses, ROS map files, map quality.

* :mod:`filters.mapping.grid` -- :class:`~filters.mapping.grid.GridMap` (occupancy + per-class grids).
* :mod:`filters.mapping.occupancy` -- log-odds occupancy and semantic mapping from scans.
* :mod:`filters.mapping.ros_map` -- ROS map_server files (PGM/YAML + semantic sidecar).
* :mod:`filters.mapping.metrics` -- map quality against a reference.
"""
