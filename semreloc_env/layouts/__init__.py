"""Layouts: world geometry as validated plain data (built-in, procedural, or from files)."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np

from .builtin import BUILTIN_LAYOUTS
from .layout import CLASS_NAMES, Layout, LayoutError, SemanticObject, layout_from_dict, load_layout, point_in_polygon
from .procedural import ProceduralParams, procedural_layout

__all__ = [
    "CLASS_NAMES",
    "LAYOUT_NAMES",
    "Layout",
    "LayoutError",
    "ProceduralParams",
    "SemanticObject",
    "get_layout",
    "layout_from_dict",
    "load_layout",
    "point_in_polygon",
    "procedural_layout",
]

LAYOUT_NAMES = (*BUILTIN_LAYOUTS, "procedural", "procedural_sym")


def _is_ros_map(spec) -> bool:
    if not isinstance(spec, (str, Path)) or Path(spec).suffix.lower() not in (".yaml", ".yml"):
        return False
    from ..maps import is_ros_map_file  # lazy: maps imports this package

    return is_ros_map_file(spec)


def get_layout(spec: str | Path | Mapping | Layout, seed: int = 0) -> Layout:
    """Resolve a layout spec to a validated :class:`Layout`.

    Args:
        spec: a built-in name (``"lab"``, ``"twin_rooms"``), ``"procedural"`` or
            ``"procedural_sym"`` (generated from ``seed``), a path to a ``.json`` /
            ``.yaml`` file, a dict in the layout format, a Layout (returned as is), or a map: a
            ROS map ``.yaml`` / ``.yml`` (a YAML with an ``image`` key) or a
            :class:`~filters.mapping.grid.GridMap`, whose world is traced from its occupied
            cells (:func:`semreloc_env.map_world.layout_from_map`).
        seed: seed of the procedural generator (ignored otherwise).
    """
    if isinstance(spec, Layout):
        return spec
    from filters.mapping.grid import GridMap

    if isinstance(spec, GridMap) or _is_ros_map(spec):
        from ..map_world import layout_from_map  # lazy: map_world imports this package

        if isinstance(spec, GridMap):
            return layout_from_map(spec)
        from filters.mapping.ros_map import load_map

        return layout_from_map(load_map(spec), name=Path(spec).stem)
    if isinstance(spec, Mapping):
        return layout_from_dict(spec)
    if isinstance(spec, str) and spec in BUILTIN_LAYOUTS:
        return layout_from_dict(BUILTIN_LAYOUTS[spec]())
    if isinstance(spec, str) and spec in ("procedural", "procedural_sym"):
        params = ProceduralParams(symmetric=spec == "procedural_sym")
        return layout_from_dict(procedural_layout(np.random.default_rng(seed), params))
    if isinstance(spec, (str, Path)):
        path = Path(spec)
        if path.suffix.lower() in (".json", ".yaml", ".yml") or path.exists():
            return load_layout(path)
        raise LayoutError(f"unknown layout {str(spec)!r}: not one of {list(LAYOUT_NAMES)} and not a layout file path")
    raise LayoutError(f"a layout must be a name, a file path, a dict or a Layout, got {type(spec).__name__}")
