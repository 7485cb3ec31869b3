"""One call from scans at known poses (a robot log with SLAM-corrected poses) to a ROS map.

`raster_for` sizes the raster from the data: the bounding box of every sensor
position and every *returned* beam end point (no-return beams do not widen it; the
mapper skips the part of a beam that leaves the raster), grown by ``margin_m`` and
snapped outwards to whole cells. `map_from_scans` runs
`OccupancyMapper` on that raster and optionally
writes the result with `filters.mapping.ros_map.save_map`.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from filters.mapping.grid import GridMap
from filters.mapping.occupancy import OccupancyMapper, OccupancyParams
from filters.mapping.ros_map import SAVE_MODES, save_map
from filters.pose import compose
from filters.robot_data.scans import LaserScan

__all__ = ["LOG_OCCUPANCY_PARAMS", "raster_for", "map_from_scans"]

LOG_OCCUPANCY_PARAMS = OccupancyParams(clear_no_return=False)
"""Default for logged scans: no-return readings (often dropouts on glass or black surfaces, or a
sensor's clipped value such as the ACES log's 50 m) clear nothing; real returns clear their way."""

_MAX_CELLS = 200_000_000


def _checked(poses, scans) -> np.ndarray:
    p = np.asarray(poses, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 3 or not np.all(np.isfinite(p)):
        raise ValueError(f"poses must be a finite (N, 3) array, got shape {p.shape}")
    if p.shape[0] != len(scans) or p.shape[0] == 0:
        raise ValueError(f"need one pose per scan and at least one scan, got {p.shape[0]} poses, {len(scans)} scans")
    for s in scans:
        if not isinstance(s, LaserScan):
            raise TypeError(f"scans must be LaserScan objects, got {type(s).__name__}")
    return p


def raster_for(
    poses: np.ndarray, scans: Sequence[LaserScan], resolution_m: float = 0.05, margin_m: float = 1.0
) -> tuple[tuple[int, int], tuple[float, float]]:
    """``(shape (H, W), origin_xy_m)`` of a raster holding every sensor position and returned end point.

    Args:
        poses: ``(N, 3)`` robot poses of the scans (metres, radians).
        scans: the scans (their ``sensor_pose`` is honoured).
        resolution_m: cell edge, metres (> 0).
        margin_m: free border around the data, metres (>= 0).
    """
    if not (math.isfinite(resolution_m) and resolution_m > 0):
        raise ValueError(f"resolution_m must be a positive number, got {resolution_m!r}")
    if not (math.isfinite(margin_m) and margin_m >= 0):
        raise ValueError(f"margin_m must be a number >= 0, got {margin_m!r}")
    p = _checked(poses, scans)
    xs, ys = [], []
    for pose, s in zip(p, scans):
        sensor = compose(pose, s.sensor_pose)
        xs.append([sensor[0]])
        ys.append([sensor[1]])
        v = s.valid
        if v.any():
            ex, ey = s.endpoints()
            world = compose(np.repeat(pose[None], int(v.sum()), axis=0), np.column_stack([ex[v], ey[v], 0 * ex[v]]))
            xs.append(world[:, 0])
            ys.append(world[:, 1])
    x = np.concatenate(xs)
    y = np.concatenate(ys)
    x0 = math.floor((x.min() - margin_m) / resolution_m) * resolution_m
    y0 = math.floor((y.min() - margin_m) / resolution_m) * resolution_m
    w = int(math.ceil((x.max() + margin_m - x0) / resolution_m)) + 1
    h = int(math.ceil((y.max() + margin_m - y0) / resolution_m)) + 1
    if h * w > _MAX_CELLS:
        raise ValueError(f"the data span {h} x {w} cells at {resolution_m} m: raise resolution_m")
    return (h, w), (round(x0, 9), round(y0, 9))


def map_from_scans(
    poses: np.ndarray,
    scans: Sequence[LaserScan],
    resolution_m: float = 0.05,
    margin_m: float = 1.0,
    params: OccupancyParams | None = None,
    save_to: str | os.PathLike | None = None,
    mode: str = "trinary",
    occupied_thresh: float = 0.65,
    free_thresh: float = 0.196,
    clear_unobserved: bool = False,
) -> GridMap:
    """Occupancy map of ``scans`` taken at the known robot ``poses``, on a raster sized from the data.

    Args:
        poses: see `raster_for`.
        scans: see `raster_for`.
        resolution_m: see `raster_for`.
        margin_m: see `raster_for`.
        params: log-odds increments and no-return policy; default `LOG_OCCUPANCY_PARAMS`.
        save_to: if given, a ``.yaml`` / ``.yml`` path: the map is written there as a ROS map
            (`save_map` with ``mode``).
        occupied_thresh: occupancy threshold of the returned map (and of the file).
        free_thresh: free threshold of the returned map (and of the file).
        clear_unobserved: after the scans, let their no-return beams clear the space the returns left
            unknown, up to the first surface (`OccupancyMapper.clear_unobserved`; what the simulator's
            mapping run does since its version 5). Off by default: a no-return reading of a real laser can
            also be glass or a black surface, which no return marked and such a beam would clear behind.
            On the ACES log it adds 11 free cells (620 no-return beams of 79,200; returns reached nearly everywhere).

    Returns:
        The map (no semantic classes).
    """
    if save_to is not None and Path(save_to).suffix not in (".yaml", ".yml"):
        raise ValueError(f"save_to must be a .yaml or .yml path, got {str(save_to)!r}")
    if mode not in SAVE_MODES:  # checked before the map is built, whether or not it is saved
        raise ValueError(f"mode must be one of {SAVE_MODES} (save_map's), got {mode!r}")
    shape, origin = raster_for(poses, scans, resolution_m, margin_m)
    mapper = OccupancyMapper(shape, resolution_m, origin, params if params is not None else LOG_OCCUPANCY_PARAMS)
    poses = np.asarray(poses, dtype=np.float64)
    mapper.update_many(poses, scans)
    if clear_unobserved:
        mapper.clear_unobserved(poses, scans)
    grid = mapper.to_grid(occupied_thresh=occupied_thresh, free_thresh=free_thresh)
    if save_to is not None:
        save_map(grid, save_to, mode=mode)
    return grid
