"""Where an env's map comes from: a mapping run (default), the rasterised layout, a map file, or another layout."""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np

from filters.mapping.grid import GridMap
from filters.mapping.ros_map import load_map

from .config import CameraParams, LidarParams
from .layouts import CLASS_NAMES, LAYOUT_NAMES, Layout, find_layout_file, get_layout
from .rasterize import rasterize

MAP_SOURCES = ("mapping", "perfect")


@functools.lru_cache(maxsize=16)
def _mapped(layout: Layout, lidar: LidarParams, camera: CameraParams) -> GridMap:
    from .mapping_run import build_maps

    return build_maps(layout, lidar, camera)


def is_ros_map_file(path) -> bool:
    """True for a ``.yaml`` / ``.yml`` file that is a ROS map (has ``image``, no ``outer``), not a layout."""
    p = Path(path)
    if p.suffix.lower() not in (".yaml", ".yml") or not p.is_file():
        return False
    import yaml

    try:
        doc = yaml.safe_load(p.read_text(encoding="utf-8"))
    except (yaml.YAMLError, UnicodeDecodeError):
        return True  # let load_map report what is wrong with it
    return isinstance(doc, dict) and "image" in doc and "outer" not in doc


def names_a_layout(source) -> bool:
    """True if ``source`` names a layout: a built-in / procedural name, a name on ``$SEMRELOC_LAYOUT_PATH``,
    a ``.json`` file, or an existing YAML file that is not a ROS map."""
    if isinstance(source, str) and (source in LAYOUT_NAMES or find_layout_file(source) is not None):
        return True
    if isinstance(source, (str, Path)):
        p = Path(source)
        if p.suffix.lower() == ".json":
            return True
        return p.suffix.lower() in (".yaml", ".yml") and p.is_file() and not is_ros_map_file(p)
    return False


def maps_for(layout: Layout, source, lidar: LidarParams, camera: CameraParams, semantic: bool = True) -> GridMap:
    """The GridMap an env's filter uses.

    Args:
        source: ``"mapping"`` (a mapping run with these sensors, seed 0; cached per
            layout and sensor settings within the process), ``"perfect"`` (the
            rasterised layout), a ROS map ``.yaml`` / ``.yml`` path (:func:`filters.mapping.ros_map.load_map`),
            a GridMap, or a *layout* (a name such as ``"lab"``, or a layout file): the mapping run
            of that layout, so the world can differ from the map ("the map is the lab, the world
            is the lab with furniture moved"). A map's classes must be those of the layouts, in
            order; a map without classes (a plain ROS map, no semantic sidecar) needs ``semantic=False``.
        semantic: whether the relocalizer uses the semantic factor.

    Raises:
        ValueError: classes that do not fit, or a map (file, GridMap or other layout) whose extent
            or frame does not fit the world (:func:`semreloc_env.map_world.check_map_matches_world`).
    """
    from .map_world import MapLayout, check_map_matches_world

    derived = False
    if isinstance(source, GridMap):
        grid = source
    elif isinstance(source, str) and source == "perfect":
        grid, derived = rasterize(layout), True
    elif isinstance(source, str) and source == "mapping":
        grid, derived = _mapped(layout, lidar, camera), True
    elif names_a_layout(source):
        grid = _mapped(get_layout(source), lidar, camera)
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
    if not derived and not (isinstance(layout, MapLayout) and _same_map(layout.grid, grid)):
        check_map_matches_world(grid, layout)
    return grid


def _same_map(a: GridMap, b: GridMap) -> bool:
    return a is b or (
        a.shape == b.shape
        and a.resolution_m == b.resolution_m
        and a.origin_xy_m == b.origin_xy_m
        and bool(np.array_equal(a.occupied_mask(), b.occupied_mask()))
    )
