"""Rasterise a layout into the grids a perfect map would hold (:class:`filters.mapping.grid.GridMap`)."""

from __future__ import annotations

import numpy as np

from filters.mapping.grid import GridMap

from .layouts import CLASS_NAMES, Layout, point_in_polygon


def _mark_segments(mask: np.ndarray, segments: np.ndarray, res: float, origin: tuple[float, float]) -> None:
    for a, b in segments:
        n = max(2, int(np.ceil(np.linalg.norm(b - a) / (res / 4))) + 1)
        t = np.linspace(0.0, 1.0, n)[:, None]
        pts = a + t * (b - a)
        col = np.floor((pts[:, 0] - origin[0]) / res).astype(int)
        row = np.floor((pts[:, 1] - origin[1]) / res).astype(int)
        ok = (row >= 0) & (row < mask.shape[0]) & (col >= 0) & (col < mask.shape[1])
        mask[row[ok], col[ok]] = True


def raster_geometry(layout: Layout, resolution_m: float = 0.05, margin_m: float = 0.5):
    """``((H, W), origin_xy_m)`` of the raster :func:`rasterize` uses for ``layout``."""
    if not (np.isfinite(resolution_m) and resolution_m > 0):
        raise ValueError(f"resolution_m must be positive, got {resolution_m!r}")
    x0, x1, y0, y1 = layout.bounds()
    origin = (x0 - margin_m, y0 - margin_m)
    w = int(np.ceil((x1 - x0 + 2 * margin_m) / resolution_m))
    h = int(np.ceil((y1 - y0 + 2 * margin_m) / resolution_m))
    return (h, w), origin


def rasterize(layout: Layout, resolution_m: float = 0.05, margin_m: float = 0.5) -> GridMap:
    """The perfect occupancy and semantic grids of ``layout``.

    Walls and object outlines mark the cells they pass through as occupied (1.0);
    object interiors are occupied and carry their class (probability 1.0); free
    space inside the outer wall is 0.0; outside it the map is unknown (0.5).
    The grid covers the outer wall's bounds plus ``margin_m`` on each side.
    """
    (h, w), origin = raster_geometry(layout, resolution_m, margin_m)
    cols, rows = np.meshgrid(np.arange(w), np.arange(h))
    centers = np.stack([origin[0] + (cols + 0.5) * resolution_m, origin[1] + (rows + 0.5) * resolution_m], -1)
    flat = centers.reshape(-1, 2)
    inside = point_in_polygon(flat, np.asarray(layout.outer)).reshape(h, w)
    occ = np.where(inside, 0.0, 0.5).astype(np.float32)
    walls = np.zeros((h, w), bool)
    _mark_segments(walls, layout.wall_segments(), resolution_m, origin)
    sem = np.zeros((len(CLASS_NAMES), h, w), np.float32)
    for obj in layout.objects:
        poly = np.asarray(obj.polygon)
        cells = point_in_polygon(flat, poly).reshape(h, w)
        _mark_segments(cells, np.stack([poly, np.roll(poly, -1, axis=0)], axis=1), resolution_m, origin)
        walls |= cells
        sem[obj.label - 1][cells] = 1.0
    occ[walls] = 1.0
    return GridMap(occ, resolution_m, origin, sem, CLASS_NAMES)
