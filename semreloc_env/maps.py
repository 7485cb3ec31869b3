"""Where an env's map comes from: a mapping run (default), the rasterised layout, or a file."""

from __future__ import annotations

import functools
from pathlib import Path

from filters.mapping.grid import GridMap
from filters.mapping.ros_map import load_map

from .config import CameraParams, LidarParams
from .layouts import CLASS_NAMES, Layout
from .rasterize import rasterize

MAP_SOURCES = ("mapping", "perfect")


@functools.lru_cache(maxsize=16)
def _mapped(layout: Layout, lidar: LidarParams, camera: CameraParams) -> GridMap:
    from .mapping_run import build_maps

    return build_maps(layout, lidar, camera)


def maps_for(layout: Layout, source, lidar: LidarParams, camera: CameraParams, semantic: bool = True) -> GridMap:
    """The GridMap an env's filter uses.

    Args:
        source: ``"mapping"`` (a mapping run with these sensors, seed 0; cached per
            layout and sensor settings within the process), ``"perfect"`` (the
            rasterised layout), a ROS map ``.yaml`` / ``.yml`` path (:func:`filters.mapping.ros_map.load_map`),
            or a GridMap. A map's classes must be those of the layouts, in order; a map
            without classes (a plain ROS map, no semantic sidecar) needs ``semantic=False``.
        semantic: whether the relocalizer uses the semantic factor.
    """
    if isinstance(source, GridMap):
        grid = source
    elif isinstance(source, str) and source == "perfect":
        grid = rasterize(layout)
    elif isinstance(source, str) and source == "mapping":
        grid = _mapped(layout, lidar, camera)
    else:
        grid = load_map(Path(source))
    if not grid.class_names:
        if semantic:
            raise ValueError(
                f"map {source if not isinstance(source, GridMap) else '(GridMap)'} has no semantic classes "
                "(a plain ROS map without a <name>.semantic.yaml sidecar): pass semantic=False for lidar-only "
                f"relocalization, or give the map a sidecar with the classes {CLASS_NAMES} (docs/maps.md)"
            )
    elif grid.class_names != CLASS_NAMES:
        raise ValueError(f"map classes {grid.class_names} differ from the env's {CLASS_NAMES}")
    return grid
