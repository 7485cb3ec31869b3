"""Top-down rasters of the filter's map and belief: an egocentric crop and a whole-map view.

Both images are ``float32 (channels, S, S)`` in ``[0, 1]``, channels in this order:

* ``n_heading_bins`` channels of particle mass, one per heading bin (``2 pi / n_heading_bins``
  wide, the first centred on heading 0 of the image frame), each cell holding the weight of
  the particles in it divided by the largest such value in the image (so the image is the
  belief's *shape*, whatever the particle count; its total mass is elsewhere);
* ``occupied``: 1 where some map cell inside the raster cell is an obstacle (max pooling, so
  thin walls survive any raster size);
* ``free``: share of the raster cell's map cells that are known free space;
* one channel per semantic class (one-hot, max pooling): 1 where a map cell of that class lies.

Cells outside the map read 0 in every channel (unknown, nothing believed there).

Frames: in `egocentric_raster` the anchor pose ``(ax, ay, atheta)`` sits at the image
centre; column index grows along the anchor's heading (x forward), row index along its left
(y left), so cell ``(r, c)`` covers the anchor-frame point
``((c + 0.5 - S/2) * cell_m, (r + 0.5 - S/2) * cell_m)``. In `allocentric_raster` the
map's bounding box is fitted into a square of side ``max(width, height)`` (lower-left corner
at the map's), row ``r`` along +y, column ``c`` along +x.
"""

from __future__ import annotations

import math

import numpy as np

from filters.mapping.grid import GridMap
from filters.pose import wrap_angle


def _pool(grid: GridMap, origin_xy: tuple[float, float], cell_m: float, shape: tuple[int, int]) -> np.ndarray:
    """``(2 + C, H, W)`` pooled map channels (occupied max, free mean, classes max) on a raster."""
    h, w = grid.shape
    rows, cols = np.mgrid[0:h, 0:w]
    centres = grid.cell_centers(rows.ravel(), cols.ravel())
    c = np.floor((centres[:, 0] - origin_xy[0]) / cell_m).astype(np.int64)
    r = np.floor((centres[:, 1] - origin_xy[1]) / cell_m).astype(np.int64)
    inside = (r >= 0) & (r < shape[0]) & (c >= 0) & (c < shape[1])
    flat = (r * shape[1] + c)[inside]
    size = shape[0] * shape[1]
    n_cls = len(grid.class_names)
    out = np.zeros((2 + n_cls, size), dtype=np.float32)
    count = np.bincount(flat, minlength=size)
    occ = grid.occupied_mask().ravel()[inside]
    out[0] = np.bincount(flat, weights=occ, minlength=size) > 0
    free = np.bincount(flat, weights=grid.free_mask().ravel()[inside], minlength=size)
    out[1] = np.divide(free, count, out=np.zeros(size), where=count > 0)
    for k in range(n_cls):
        out[2 + k] = np.bincount(flat, weights=grid.class_mask(k).ravel()[inside], minlength=size) > 0
    return out.reshape((2 + n_cls,) + shape)


class MapRasters:
    """Pooled map channels of one GridMap, computed once per raster cell size (the maps are frozen).

    Args:
        grid: the filter's map.
        ego_cell_m: raster cell of the egocentric crop, metres.
        global_size: side of the allocentric image, cells.
    """

    def __init__(self, grid: GridMap, ego_cell_m: float, global_size: int):
        self.grid = grid
        x0, x1, y0, y1 = grid.extent_m
        self.ego_cell_m = float(ego_cell_m)
        # ego: pool on a raster aligned with the map, sampled at rotated points later
        self._ego_origin = (x0, y0)
        self._ego_shape = (max(1, math.ceil((y1 - y0) / ego_cell_m)), max(1, math.ceil((x1 - x0) / ego_cell_m)))
        self._ego = _pool(grid, self._ego_origin, self.ego_cell_m, self._ego_shape)
        self.side_m = max(x1 - x0, y1 - y0)
        """Side of the square the allocentric image covers, metres (the larger map extent)."""
        self.global_origin = (x0, y0)
        self.global_cell_m = self.side_m / global_size
        self.global_size = int(global_size)
        self._global = _pool(grid, self.global_origin, self.global_cell_m, (global_size, global_size))

    @property
    def n_map_channels(self) -> int:
        return self._global.shape[0]

    def ego_map(self, anchor: np.ndarray, size: int) -> np.ndarray:
        """``(2 + C, size, size)`` map channels around ``anchor`` in its frame (nearest pooled cell)."""
        ax, ay, at = (float(v) for v in anchor)
        u = (np.arange(size) + 0.5 - size / 2) * self.ego_cell_m
        fwd, left = np.meshgrid(u, u)  # [row, col]: col along forward, row along left
        ca, sa = math.cos(at), math.sin(at)
        x = ax + ca * fwd - sa * left
        y = ay + sa * fwd + ca * left
        c = np.floor((x - self._ego_origin[0]) / self.ego_cell_m).astype(np.int64)
        r = np.floor((y - self._ego_origin[1]) / self.ego_cell_m).astype(np.int64)
        inside = (r >= 0) & (r < self._ego_shape[0]) & (c >= 0) & (c < self._ego_shape[1])
        out = np.zeros((self._ego.shape[0], size, size), dtype=np.float32)
        out[:, inside] = self._ego[:, r[inside], c[inside]]
        return out

    def global_map(self) -> np.ndarray:
        """``(2 + C, S, S)`` map channels of the whole map (a copy)."""
        return self._global.copy()

    def normalised_xy(self, xy: np.ndarray) -> np.ndarray:
        """World ``(..., 2)`` points in map-normalised coordinates (``[0, 1]`` inside the square)."""
        return (np.asarray(xy, dtype=np.float64) - np.asarray(self.global_origin)) / self.side_m


def mass_image(
    rc: tuple[np.ndarray, np.ndarray], heading: np.ndarray, weights: np.ndarray, size: int, n_heading_bins: int
) -> np.ndarray:
    """``(n_heading_bins, size, size)`` particle mass, max-normalised; particles outside are dropped.

    Args:
        rc: integer ``(row, col)`` of every particle in the image.
        heading: ``(N,)`` particle headings in the image frame, radians.
        weights: ``(N,)`` particle weights.
    """
    r, c = rc
    k = np.floor((wrap_angle(heading) + math.pi / n_heading_bins) / (2 * math.pi / n_heading_bins)).astype(np.int64)
    k %= n_heading_bins
    inside = (r >= 0) & (r < size) & (c >= 0) & (c < size)
    flat = ((k * size + r) * size + c)[inside]
    img = np.bincount(flat, weights=weights[inside], minlength=n_heading_bins * size * size)
    top = img.max(initial=0.0)
    if top > 0:
        img = img / top
    return img.reshape(n_heading_bins, size, size).astype(np.float32)


def egocentric_raster(
    rasters: MapRasters,
    poses: np.ndarray,
    weights: np.ndarray,
    anchor: np.ndarray,
    size: int,
    n_heading_bins: int,
) -> tuple[np.ndarray, float]:
    """The egocentric image around ``anchor`` (see the module docstring) and the belief mass
    (weights normalised to sum 1) inside it."""
    w = np.asarray(weights, dtype=np.float64)
    w = w / w.sum()
    ax, ay, at = (float(v) for v in anchor)
    dx, dy = poses[:, 0] - ax, poses[:, 1] - ay
    ca, sa = math.cos(at), math.sin(at)
    fwd = ca * dx + sa * dy
    left = -sa * dx + ca * dy
    cell = rasters.ego_cell_m
    c = np.floor(fwd / cell + size / 2).astype(np.int64)
    r = np.floor(left / cell + size / 2).astype(np.int64)
    inside = (r >= 0) & (r < size) & (c >= 0) & (c < size)
    mass = mass_image((r, c), poses[:, 2] - at, w, size, n_heading_bins)
    img = np.concatenate([mass, rasters.ego_map(anchor, size)])
    return img, float(np.clip(w[inside].sum(), 0.0, 1.0))


def allocentric_raster(rasters: MapRasters, poses: np.ndarray, weights: np.ndarray, n_heading_bins: int) -> np.ndarray:
    """The whole-map image (see the module docstring)."""
    w = np.asarray(weights, dtype=np.float64)
    w = w / w.sum()
    s, cell = rasters.global_size, rasters.global_cell_m
    c = np.floor((poses[:, 0] - rasters.global_origin[0]) / cell).astype(np.int64)
    r = np.floor((poses[:, 1] - rasters.global_origin[1]) / cell).astype(np.int64)
    mass = mass_image((r, c), poses[:, 2], w, s, n_heading_bins)
    return np.concatenate([mass, rasters.global_map()])
