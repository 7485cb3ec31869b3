"""Where an env's map comes from: a mapping run (default), the rasterised layout, or a file.

Mapping-run maps are cached in memory (per process) and on disk, keyed by the layout's
content, the sensor parameters, the resolution and :data:`~semreloc_env.mapping_run.MAPPING_RUN_VERSION`,
so a process that meets a layout again loads its map in milliseconds. The disk cache lives
in ``$SEMRELOC_CACHE_DIR/maps`` (default ``~/.cache/semreloc/maps``); set
``SEMRELOC_CACHE_DIR`` to an empty string to switch it off. Files are written atomically;
an unreadable file is rebuilt and replaced.
"""

from __future__ import annotations

import functools
import hashlib
import os
import tempfile
from collections import OrderedDict
from pathlib import Path

import numpy as np

from filters.mapping.grid import GridMap
from filters.mapping.ros_map import load_map

from .config import CameraParams, LidarParams
from .layouts import CLASS_NAMES, Layout
from .rasterize import rasterize

MAP_SOURCES = ("mapping", "perfect")
MEMORY_CACHE_SIZE = 16
"""Mapped GridMaps kept in memory per process (least recently used dropped first)."""

_memory: OrderedDict[str, GridMap] = OrderedDict()


def cache_dir() -> Path | None:
    """The on-disk map cache folder, or None if switched off (``SEMRELOC_CACHE_DIR=""``)."""
    root = os.environ.get("SEMRELOC_CACHE_DIR")
    if root is None:
        return Path.home() / ".cache" / "semreloc" / "maps"
    return Path(root) / "maps" if root else None


def map_key(layout: Layout, lidar: LidarParams, camera: CameraParams, resolution_m: float = 0.05) -> str:
    """Hex key of a mapping-run map: layout content, sensor parameters, resolution and code version."""
    from .mapping_run import MAPPING_RUN_VERSION

    text = repr((MAPPING_RUN_VERSION, layout, lidar, camera, float(resolution_m), CLASS_NAMES))
    return hashlib.blake2b(text.encode(), digest_size=16).hexdigest()


def _save(path: Path, grid: GridMap) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            np.savez(
                f,
                occupancy=grid.occupancy,
                semantic=grid.semantic,
                resolution_m=grid.resolution_m,
                origin_xy_m=np.asarray(grid.origin_xy_m),
                class_names=np.asarray(grid.class_names),
                thresholds=np.array([grid.occupied_thresh, grid.free_thresh, grid.semantic_thresh]),
            )
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def _load(path: Path) -> GridMap | None:
    try:
        with np.load(path, allow_pickle=False) as z:
            occ, sem, th = z["occupancy"], z["semantic"], z["thresholds"]
            return GridMap(
                occ,
                float(z["resolution_m"]),
                tuple(z["origin_xy_m"].tolist()),
                sem,
                tuple(z["class_names"].tolist()),
                float(th[0]),
                float(th[1]),
                float(th[2]),
            )
    except FileNotFoundError:
        return None
    except Exception:  # a truncated or foreign file: rebuild it
        return None


def mapped(layout: Layout, lidar: LidarParams, camera: CameraParams) -> GridMap:
    """The mapping-run map of ``layout`` with these sensors (seed 0): from memory, disk, or a new run."""
    key = map_key(layout, lidar, camera)
    grid = _memory.get(key)
    if grid is not None:
        _memory.move_to_end(key)
        return grid
    folder = cache_dir()
    path = folder / f"{key}.npz" if folder is not None else None
    grid = _load(path) if path is not None else None
    if grid is None:
        from .mapping_run import build_maps

        grid = build_maps(layout, lidar, camera)
        if path is not None:
            try:
                _save(path, grid)
            except OSError:  # a read-only or full disk must not break env creation
                pass
    _memory[key] = grid
    while len(_memory) > MEMORY_CACHE_SIZE:
        _memory.popitem(last=False)
    return grid


@functools.lru_cache(maxsize=MEMORY_CACHE_SIZE)
def _perfect(layout: Layout) -> GridMap:
    return rasterize(layout)


def maps_for(layout: Layout, source, lidar: LidarParams, camera: CameraParams) -> GridMap:
    """The GridMap an env's filter uses.

    Args:
        source: ``"mapping"`` (a mapping run with these sensors, seed 0; cached in memory
            and on disk, see the module docstring), ``"perfect"`` (the rasterised layout),
            a ROS map ``.yaml`` path (:func:`filters.mapping.ros_map.load_map`), or a GridMap.
            A map's classes must be those of the layouts, in order.
    """
    if isinstance(source, GridMap):
        grid = source
    elif isinstance(source, str) and source == "perfect":
        grid = _perfect(layout)
    elif isinstance(source, str) and source == "mapping":
        grid = mapped(layout, lidar, camera)
    else:
        grid = load_map(Path(source))
    if grid.class_names != CLASS_NAMES:
        raise ValueError(f"map classes {grid.class_names} differ from the env's {CLASS_NAMES}")
    return grid
