"""Rasterise a layout into the grids a perfect map would hold (`filters.mapping.grid.GridMap`).

Time and memory are linear in the number of cells plus ``rows x vertices`` (a scanline fill);
a grid of more than `MAX_RASTER_CELLS` cells is refused before anything is allocated.
"""

from __future__ import annotations

import numpy as np

from filters.mapping.grid import GridMap

from .layouts import CLASS_NAMES, Layout

MAX_RASTER_CELLS = 25_000_000
"""Largest grid `rasterize` builds (about 22 bytes a cell, so ~550 MB): e.g. 250 m x 250 m at 5 cm is refused."""


def _mark_segments(
    mask: np.ndarray, segments: np.ndarray, res: float, origin: tuple[float, float], offset: tuple[int, int] = (0, 0)
) -> None:
    """Mark the cells segments pass through; ``mask[0, 0]`` is cell ``offset`` (row, col) of the grid at ``origin``."""
    for a, b in segments:
        n = max(2, int(np.ceil(np.linalg.norm(b - a) / (res / 4))) + 1)
        t = np.linspace(0.0, 1.0, n)[:, None]
        pts = a + t * (b - a)
        col = np.floor((pts[:, 0] - origin[0]) / res).astype(int) - offset[1]
        row = np.floor((pts[:, 1] - origin[1]) / res).astype(int) - offset[0]
        ok = (row >= 0) & (row < mask.shape[0]) & (col >= 0) & (col < mask.shape[1])
        mask[row[ok], col[ok]] = True


def fill_polygon(
    shape: tuple[int, int],
    poly: np.ndarray,
    res: float,
    origin: tuple[float, float],
    offset: tuple[int, int] = (0, 0),
) -> np.ndarray:
    """Bool ``shape`` mask of the cells whose centres lie inside ``poly`` (even-odd rule).

    ``mask[0, 0]`` is cell ``offset`` (row, col) of the grid whose corner is ``origin``.
    The same rule as `semreloc_env.layouts.point_in_polygon` at every cell centre, by
    scanlines: ``O(rows x vertices + cells)`` time instead of ``O(cells x vertices)``.
    """
    h, w = shape
    poly = np.asarray(poly, dtype=np.float64)
    x0, y0 = poly[:, 0], poly[:, 1]
    x1, y1 = np.roll(x0, -1), np.roll(y0, -1)
    diff = np.zeros((h, w + 1), np.int8)
    r_lo = max(0, int(np.floor((y0.min() - origin[1]) / res - 0.5)) - offset[0])
    r_hi = min(h, int(np.ceil((y0.max() - origin[1]) / res + 0.5)) - offset[0])
    for r in range(r_lo, r_hi):
        y = origin[1] + (r + offset[0] + 0.5) * res
        straddle = (y0 > y) != (y1 > y)
        if not straddle.any():
            continue
        a, b, c, d = x0[straddle], y0[straddle], x1[straddle], y1[straddle]
        xc = np.sort(a + (y - b) * (c - a) / (d - b))
        # centre x is inside iff an odd number of crossings lie strictly right of it: [xc0, xc1), ...
        cols = np.clip(np.ceil((xc - origin[0]) / res - 0.5).astype(np.int64) - offset[1], 0, w)
        np.add.at(diff[r], cols[0::2], 1)
        np.add.at(diff[r], cols[1::2], -1)
    return np.cumsum(diff[:, :w], axis=1, dtype=np.int8) > 0


def grid_shape(layout: Layout, resolution_m: float = 0.05, margin_m: float = 0.5) -> tuple[int, int]:
    """``(rows, cols)`` of `rasterize`'s grid; ValueError past `MAX_RASTER_CELLS`."""
    if not (isinstance(resolution_m, (int, float)) and np.isfinite(resolution_m) and resolution_m > 0):
        raise ValueError(f"resolution_m must be a positive finite number, got {resolution_m!r}")
    if not (isinstance(margin_m, (int, float)) and np.isfinite(margin_m) and margin_m >= 0):
        raise ValueError(f"margin_m must be a finite number >= 0, got {margin_m!r}")
    x0, x1, y0, y1 = layout.bounds()
    w = int(np.ceil((x1 - x0 + 2 * margin_m) / resolution_m))
    h = int(np.ceil((y1 - y0 + 2 * margin_m) / resolution_m))
    if h * w > MAX_RASTER_CELLS:
        raise ValueError(
            f"layout {layout.name!r} ({x1 - x0:.1f} m x {y1 - y0:.1f} m) needs a {w} x {h} grid at "
            f"{resolution_m} m: {h * w} cells, more than MAX_RASTER_CELLS = {MAX_RASTER_CELLS}; "
            "is the layout in metres? (the envs map at 0.05 m; rasterize and scripts/build_maps.py take a "
            "coarser resolution_m)"
        )
    return h, w


def raster_geometry(layout: Layout, resolution_m: float = 0.05, margin_m: float = 0.5):
    """``((rows, cols), origin_xy_m)`` of `rasterize`'s grid (checked as `grid_shape` does)."""
    h, w = grid_shape(layout, resolution_m, margin_m)
    x0, _, y0, _ = layout.bounds()
    return (h, w), (x0 - margin_m, y0 - margin_m)


def rasterize(layout: Layout, resolution_m: float = 0.05, margin_m: float = 0.5) -> GridMap:
    """The perfect occupancy and semantic grids of ``layout``.

    Walls and object outlines mark the cells they pass through as occupied (1.0);
    object interiors are occupied and carry their class (probability 1.0), block interiors
    are occupied without a class; free
    space inside the outer wall is 0.0; outside it the map is unknown (0.5).
    The grid covers the outer wall's bounds plus ``margin_m`` on each side.

    Raises:
        ValueError: a bad resolution or margin, or a grid of more than `MAX_RASTER_CELLS`
            cells (checked before any allocation).
    """
    h, w = grid_shape(layout, resolution_m, margin_m)
    x0, _, y0, _ = layout.bounds()
    origin = (x0 - margin_m, y0 - margin_m)
    inside = fill_polygon((h, w), np.asarray(layout.outer), resolution_m, origin)
    occ = np.where(inside, np.float32(0.0), np.float32(0.5))
    del inside
    walls = np.zeros((h, w), bool)
    _mark_segments(walls, layout.wall_segments(), resolution_m, origin)
    sem = np.zeros((len(CLASS_NAMES), h, w), np.float32)
    solids = [(np.asarray(obj.polygon), obj.label) for obj in layout.objects]
    solids += [(np.asarray(b), 0) for b in layout.blocks]  # solid, no class
    for poly, label in solids:
        # only the polygon's bounding box of cells: linear in the layout, not polygons x cells
        c0 = max(0, int(np.floor((poly[:, 0].min() - origin[0]) / resolution_m)) - 1)
        c1 = min(w, int(np.ceil((poly[:, 0].max() - origin[0]) / resolution_m)) + 2)
        r0 = max(0, int(np.floor((poly[:, 1].min() - origin[1]) / resolution_m)) - 1)
        r1 = min(h, int(np.ceil((poly[:, 1].max() - origin[1]) / resolution_m)) + 2)
        cells = fill_polygon((r1 - r0, c1 - c0), poly, resolution_m, origin, (r0, c0))
        edges = np.stack([poly, np.roll(poly, -1, axis=0)], axis=1)
        _mark_segments(cells, edges, resolution_m, origin, (r0, c0))
        walls[r0:r1, c0:c1] |= cells
        if label:
            sem[label - 1][r0:r1, c0:c1][cells] = 1.0
    occ[walls] = 1.0
    return GridMap(occ, resolution_m, origin, sem, CLASS_NAMES)
