"""A small grid ray caster: simulated lidar and semantic scans from a `GridMap`.

For tests, benchmarks and offline experiments with nothing but a map (the
simulator has its own, geometric, sensors). Rays are traversed cell by cell
(Amanatides & Woo 1987 DDA) from the pose until they enter an occupied cell;
the range is the distance to that cell's boundary. A ray that leaves the map or
reaches ``range_max_m`` returns ``range_max_m`` (no return).

The semantic scan labels a beam with ``k + 1`` if the occupied cell it hit is a
cell of class ``k`` (the first class whose mask holds it), else 0.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from filters.mapping.grid import GridMap
from filters.robot_data.scans import LaserScan, SemanticScan


@numba.njit(cache=True)
def _cast(occ, ox, oy, res, x, y, angles, range_max, out_r, out_row, out_col):
    h, w = occ.shape
    for j in range(angles.shape[0]):
        dx = math.cos(angles[j])
        dy = math.sin(angles[j])
        fx = (x - ox) / res
        fy = (y - oy) / res
        cx = int(math.floor(fx))
        cy = int(math.floor(fy))
        out_r[j] = range_max
        out_row[j] = -1
        out_col[j] = -1
        if cx < 0 or cx >= w or cy < 0 or cy >= h:
            continue
        if occ[cy, cx]:
            out_r[j] = 0.0
            out_row[j] = cy
            out_col[j] = cx
            continue
        step_x = 1 if dx > 0 else -1
        step_y = 1 if dy > 0 else -1
        inf = 1e300
        if dx != 0.0:
            nx = (cx + (1 if dx > 0 else 0)) - fx
            t_max_x = nx * res / dx
            t_dx = res / abs(dx)
        else:
            t_max_x = inf
            t_dx = inf
        if dy != 0.0:
            ny = (cy + (1 if dy > 0 else 0)) - fy
            t_max_y = ny * res / dy
            t_dy = res / abs(dy)
        else:
            t_max_y = inf
            t_dy = inf
        while True:
            if t_max_x < t_max_y:
                t = t_max_x
                cx += step_x
                t_max_x += t_dx
            else:
                t = t_max_y
                cy += step_y
                t_max_y += t_dy
            if t >= range_max:
                break
            if cx < 0 or cx >= w or cy < 0 or cy >= h:
                break
            if occ[cy, cx]:
                out_r[j] = t
                out_row[j] = cy
                out_col[j] = cx
                break


def cast_rays(grid: GridMap, pose, angles: np.ndarray, range_max_m: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Ranges ``(B,)`` (metres, ``range_max_m`` = no return) and hit cells ``(row, col)`` (-1 = none)."""
    p = np.asarray(pose, dtype=np.float64).reshape(-1)
    if p.shape != (3,) or not np.all(np.isfinite(p)):
        raise ValueError(f"pose must be 3 finite numbers (x m, y m, theta rad), got {pose!r:.80}")
    a = p[2] + np.asarray(angles, dtype=np.float64).reshape(-1)
    r = np.empty(a.size)
    row = np.empty(a.size, np.int64)
    col = np.empty(a.size, np.int64)
    ox, oy = grid.origin_xy_m
    _cast(grid.occupied_mask(), float(ox), float(oy), grid.resolution_m, p[0], p[1], a, float(range_max_m), r, row, col)
    return r, row, col


def _add_noise(r: np.ndarray, range_max_m: float, noise_std_m: float, rng) -> np.ndarray:
    """Gaussian noise on the beams that hit (kept below ``range_max_m``); no-returns unchanged."""
    if noise_std_m <= 0:
        return r
    if not isinstance(rng, np.random.Generator):
        raise TypeError(f"noise_std_m > 0 needs rng, a numpy.random.Generator; got {type(rng).__name__}")
    hit = r < range_max_m
    r = r.copy()
    r[hit] = np.clip(r[hit] + rng.normal(0.0, noise_std_m, int(hit.sum())), 0.0, range_max_m * (1 - 1e-9))
    return r


def simulate_lidar(
    grid: GridMap,
    pose,
    angles: np.ndarray,
    range_max_m: float,
    noise_std_m: float = 0.0,
    rng: np.random.Generator | None = None,
) -> LaserScan:
    """A `LaserScan` from ``pose``; Gaussian range noise (``rng`` required if > 0)."""
    r, _, _ = cast_rays(grid, pose, angles, range_max_m)
    r = _add_noise(r, range_max_m, noise_std_m, rng)
    return LaserScan(r, np.asarray(angles, dtype=np.float64), range_max_m)


def simulate_semantic(
    grid: GridMap,
    pose,
    angles: np.ndarray,
    range_max_m: float,
    noise_std_m: float = 0.0,
    rng: np.random.Generator | None = None,
) -> SemanticScan:
    """A `SemanticScan` from ``pose``: label ``k + 1`` where the hit cell is of class ``k``."""
    r, row, col = cast_rays(grid, pose, angles, range_max_m)
    labels = np.zeros(r.size, np.int64)
    hit = row >= 0
    for k in range(len(grid.class_names) - 1, -1, -1):
        m = grid.class_mask(k)
        labels[hit] = np.where(m[row[hit], col[hit]], k + 1, labels[hit])
    r = _add_noise(r, range_max_m, noise_std_m, rng)
    return SemanticScan(r, np.asarray(angles, dtype=np.float64), labels, range_max_m)


@numba.njit(cache=True)
def cast_many_labelled(occ, labels, ox, oy, res, xy, angles, range_max, class_max, out_r, out_lab):
    """Casts along ``angles`` (absolute, rad) from every position ``xy[p]`` (metres) on the
    occupancy grid ``occ``: ranges ``out_r[p]`` and the class label of the cell hit (``labels``,
    0 = none) when it lies within ``class_max`` metres, else 0, in ``out_lab[p]``.

    It lives beside `_cast`, which it calls: numba checks only a cached function's own file
    for changes, so a cached kernel calling a kernel of another file could run a stale copy."""
    b = angles.shape[0]
    r = np.empty(b)
    row = np.empty(b, np.int64)
    col = np.empty(b, np.int64)
    for p in range(xy.shape[0]):
        _cast(occ, ox, oy, res, xy[p, 0], xy[p, 1], angles, range_max, r, row, col)
        for j in range(b):
            out_r[p, j] = r[j]
            if row[j] >= 0 and r[j] < class_max:
                out_lab[p, j] = labels[row[j], col[j]]
            else:
                out_lab[p, j] = 0
