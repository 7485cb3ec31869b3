"""Worlds from occupancy maps, and the check that a map and a world agree.

`layout_from_map` turns a `GridMap` (e.g. a ROS map
loaded with `filters.mapping.ros_map.load_map`) into a `MapLayout`, which
`semreloc_env.world.build_world` builds like any layout:

* **walls**: the boundaries of the occupied cells (``grid.occupied_mask()``, minus the cells of
  semantic classes), traced along cell edges into closed rings (occupied side on the left)
  and simplified with Douglas-Peucker (pymunk's ``simplify_curves``) to ``simplify_m``
  (default half a cell), so a building has hundreds of segments, not a segment per cell edge;
* **outer wall**: the map's extent (the robot cannot leave the raster);
* **objects**: if the map has semantic classes, the outer boundary of each connected
  component of a class mask (4-connected), simplified the same way, as a
  `SemanticObject` of that class. Components whose traced
  outline is not a simple polygon after simplification are traced again unsimplified. An object
  is solid for the lidar and the robot like a wall, also where its cells are free in the occupancy
  layer (an open doorway labelled door becomes a closed door): then the simulated lidar sees what
  the relocalizer's lidar map does not have, and `layout_from_map` warns (`MapWorldWarning`);
* **placement**: a robot pose is free only on a known-free cell of the map
  (`MapLayout.solid_at`), so start poses are not drawn inside thick walls or in unknown
  space; unknown cells are not solid for physics and sensing (only occupied cells are).

`check_map_matches_world` raises ``ValueError`` when a map's extent or frame does not
fit a layout (see its docstring): a map paired with the wrong world is an error, not a 4 m
pose error after 30 steps.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np
from pymunk import Vec2d
from pymunk.autogeometry import simplify_curves
from scipy import ndimage

from filters.mapping.grid import GridMap

from .layouts import CLASS_NAMES, Layout, SemanticObject
from .layouts.layout import _ring

__all__ = ["MapLayout", "MapWorldWarning", "layout_from_map", "trace_boundaries", "check_map_matches_world"]


class MapWorldWarning(UserWarning):
    """A world built from a map differs from the map where it should not (`layout_from_map`)."""


@dataclass(frozen=True, eq=False)
class MapLayout(Layout):
    """A `Layout` built from a map; ``grid`` is the map it came from."""

    grid: GridMap | None = None

    def solid_at(self, xy: np.ndarray) -> np.ndarray:
        """Bool ``(P,)``: points ``(P, 2)`` where the robot may not be placed: cells that are not
        known free in the map (occupied or unknown), or off the map."""
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        row, col = self.grid.world_to_cell(xy)
        ok = self.grid.in_bounds(row, col)
        out = np.ones(xy.shape[0], dtype=bool)
        out[ok] = ~self.grid.free_mask()[row[ok], col[ok]]
        return out


def trace_boundaries(mask: np.ndarray) -> list[np.ndarray]:
    """Closed rings ``(V + 1, 2)`` (corner coordinates: x = column, y = row; first point repeated)
    along the cell edges between ``True`` and ``False`` cells (outside the array is ``False``).

    Rings run with the ``True`` side on the left (counter-clockwise around a blob, clockwise
    around a hole); collinear edges are merged. Where two blobs touch only at a corner the
    tracer keeps them apart (it turns left there).
    """
    m = np.pad(np.asarray(mask, dtype=bool), 1)
    inner = m[1:-1, 1:-1]
    r, c = np.nonzero(inner)
    starts, ends = [], []
    # (neighbour offset, edge start corner, edge end corner) with the occupied cell on the left
    for (dr, dc), (s0, s1), (e0, e1) in (
        ((-1, 0), (0, 0), (1, 0)),  # free below: left -> right along the bottom edge
        ((0, 1), (1, 0), (1, 1)),  # free right: up the right edge
        ((1, 0), (1, 1), (0, 1)),  # free above: right -> left along the top edge
        ((0, -1), (0, 1), (0, 0)),  # free left: down the left edge
    ):
        free = ~m[r + 1 + dr, c + 1 + dc]
        rr, cc = r[free], c[free]
        starts.append(np.column_stack([cc + s0, rr + s1]))
        ends.append(np.column_stack([cc + e0, rr + e1]))
    if not starts or sum(len(s) for s in starts) == 0:
        return []
    a = np.concatenate(starts)
    b = np.concatenate(ends)
    out_edges: dict[tuple[int, int], list[int]] = {}
    for i, key in enumerate(map(tuple, a.tolist())):
        out_edges.setdefault(key, []).append(i)
    used = np.zeros(len(a), dtype=bool)
    direction = b - a
    rings = []
    for first in range(len(a)):
        if used[first]:
            continue
        ring = [a[first]]
        i = first
        while True:
            used[i] = True
            ring.append(b[i])
            cands = [j for j in out_edges[tuple(b[i].tolist())] if not used[j]]
            if not cands:
                break
            if len(cands) > 1:  # corner contact: take the left turn (keeps touching blobs apart)
                d = direction[i]
                cands.sort(key=lambda j: -(d[0] * direction[j][1] - d[1] * direction[j][0]))
            i = cands[0]
        pts = np.asarray(ring, dtype=np.float64)
        # merge collinear edges
        d = np.diff(pts, axis=0)
        keep = np.ones(len(pts), dtype=bool)
        turn = d[1:, 0] * d[:-1, 1] - d[1:, 1] * d[:-1, 0]
        keep[1:-1] = turn != 0
        if len(d) > 1 and d[0, 0] * d[-1, 1] - d[0, 1] * d[-1, 0] == 0:  # the start point is mid-edge
            keep[0] = False
            keep[-1] = False
            pts = pts[keep]
            pts = np.vstack([pts, pts[:1]])
        else:
            pts = pts[keep]
        rings.append(pts)
    return rings


def _to_world(ring: np.ndarray, grid: GridMap) -> np.ndarray:
    ox, oy = grid.origin_xy_m
    return np.column_stack([ox + ring[:, 0] * grid.resolution_m, oy + ring[:, 1] * grid.resolution_m])


def _simplify(ring: np.ndarray, tol: float) -> np.ndarray:
    if tol <= 0 or len(ring) <= 4:
        return ring
    s = simplify_curves([Vec2d(float(x), float(y)) for x, y in ring], tol)
    out = np.array([(p.x, p.y) for p in s], dtype=np.float64)
    return out if len(out) >= 4 else ring


def _ring_area(ring: np.ndarray) -> float:
    x, y = ring[:-1, 0], ring[:-1, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def layout_from_map(
    grid: GridMap, name: str = "map", simplify_m: float | None = None, untraced_as_walls: bool = True
) -> MapLayout:
    """The world a map shows (see the module docstring).

    Args:
        grid: the map.
        name: the layout's name.
        simplify_m: Douglas-Peucker tolerance in metres (default half a cell; 0 = exact cell edges).
        untraced_as_walls: a class region whose outline is no simple polygon even unsimplified (it touches itself at
            a corner, a diagonal pinch) keeps its occupied cells as walls, without a class (True, the default), or
            is left out of the world (False: as the registered envs, ``SemReloc-v22`` and older, have always built
            worlds from maps, so that their episodes stay what they were). Either way a `MapWorldWarning` names it.

    Raises:
        ValueError: the map has no free cell, or a semantic class that is not the env's
            (`CLASS_NAMES`; any of them, in any order, make objects of that class).
    """
    if not isinstance(grid, GridMap):
        raise TypeError(f"grid must be a GridMap, got {type(grid).__name__}")
    if not grid.free_mask().any():
        raise ValueError("the map has no free cell: no world to build")
    unknown = [c for c in grid.class_names if c not in CLASS_NAMES]
    if unknown:
        raise ValueError(f"map {name!r}: classes {unknown} are not among the env's {CLASS_NAMES} (docs/maps.md)")
    res = grid.resolution_m
    tol = 0.5 * res if simplify_m is None else float(simplify_m)
    if not (math.isfinite(tol) and tol >= 0):
        raise ValueError(f"simplify_m must be a number >= 0, got {simplify_m!r}")
    class_cells = np.zeros(grid.shape, dtype=bool)
    objects = []
    # a class region one cell wider than its occupied cells is how maps are drawn (the mapping run's too): the
    # world's object is then a cell larger than the lidar map's; farther out, the world has an obstacle the map lacks
    away = grid.free_mask() & ~ndimage.binary_dilation(grid.occupied_mask(), np.ones((3, 3), bool))
    on_free = {c: int((grid.class_mask(k) & away).sum()) for k, c in enumerate(grid.class_names)}
    on_free = {c: n for c, n in on_free.items() if n}
    if on_free:
        warnings.warn(
            f"map {name!r}: class cells lie on cells the occupancy layer calls free, farther than one cell from any "
            f"occupied cell ({on_free}); the simulated world "
            "makes every class region a solid object, which its lidar sees and its robot cannot pass, but the "
            "relocalizer's lidar map does not have: mark those cells occupied in the map image if the lidar sees "
            "the object there (docs/real_robot.md, section 6)",
            MapWorldWarning,
            stacklevel=2,
        )
    untraced = []
    for k, cls in enumerate(grid.class_names):
        mask = grid.class_mask(k)
        labels, n = ndimage.label(mask)
        for comp in range(1, n + 1):
            cells = labels == comp
            rings = [_to_world(r, grid) for r in trace_boundaries(cells)]
            outer = max(rings, key=_ring_area)  # the one counter-clockwise ring around the component
            poly = None
            for t in (tol, 0.0):
                cand = _simplify(outer, t)[:-1]
                try:
                    _ring(cand, "object")
                except ValueError:
                    continue
                poly = cand
                break
            if poly is None:
                untraced.append(f"{cls} at {_region_at(cells, grid)}")
                if untraced_as_walls:
                    continue  # not a class cell: its occupied cells stay walls
            else:
                objects.append(SemanticObject(cls, tuple(map(tuple, poly.tolist())), f"{cls}_{len(objects)}"))
            class_cells |= cells
    if untraced:
        kept = (
            "its occupied cells are walls without a class"
            if untraced_as_walls
            else "it is left out of the world, wall and all (as the registered envs build worlds from maps)"
        )
        warnings.warn(
            f"map {name!r}: class regions whose outline touches itself (no simple polygon): {', '.join(untraced)}; "
            f"{kept}",
            MapWorldWarning,
            stacklevel=2,
        )
    walls = tuple(
        tuple(map(tuple, _simplify(_to_world(r, grid), tol).tolist()))
        for r in trace_boundaries(grid.occupied_mask() & ~class_cells)
    )
    x0, x1, y0, y1 = grid.extent_m
    outer = ((x0, y0), (x1, y0), (x1, y1), (x0, y1))
    return MapLayout(name, outer, walls, tuple(objects), grid=grid)


def _region_at(cells: np.ndarray, grid: GridMap) -> str:
    """Where the cells ``cells`` (a bool raster of ``grid``) lie, for messages: the centre of their bounding box."""
    rows, cols = np.nonzero(cells)
    x, y = grid.cell_centers(np.array([(rows.min() + rows.max()) // 2]), np.array([(cols.min() + cols.max()) // 2]))[0]
    return f"({x:.2f}, {y:.2f}) m"


def check_map_matches_world(
    grid: GridMap, layout: Layout, extent_slack_m: float = 2.0, max_wall_dist_m: float = 0.25, min_fraction=0.8
) -> None:
    """Raise ``ValueError`` unless ``grid`` could be a map of ``layout``.

    * Extent: the layout's bounds must lie inside the map (to one cell) and the map must not
      reach more than ``extent_slack_m`` (or 20 % of the layout's size, whichever is larger)
      beyond them on any side.
    * Frame: points every cell along the layout's walls must lie within ``max_wall_dist_m`` of
      an occupied map cell, for at least ``min_fraction`` of them, and so must ``min_fraction`` of
      those along the interior walls and blocks alone (so that a long outer wall cannot carry
      interior walls that lie elsewhere). Moved furniture passes (objects are not checked); a
      shifted, rotated or foreign map does not. Occupied map cells away from the layout's walls
      (walls the world lacks) are not checked.
    """
    lx0, lx1, ly0, ly1 = layout.bounds()
    mx0, mx1, my0, my1 = grid.extent_m
    res = grid.resolution_m
    slack_x = max(extent_slack_m, 0.2 * (lx1 - lx0))
    slack_y = max(extent_slack_m, 0.2 * (ly1 - ly0))
    inside = mx0 <= lx0 + res and mx1 >= lx1 - res and my0 <= ly0 + res and my1 >= ly1 - res
    tight = lx0 - mx0 <= slack_x and mx1 - lx1 <= slack_x and ly0 - my0 <= slack_y and my1 - ly1 <= slack_y
    if not (inside and tight):
        raise ValueError(
            f"map extent x [{mx0:.2f}, {mx1:.2f}] y [{my0:.2f}, {my1:.2f}] m does not fit the world "
            f"{layout.name!r} (x [{lx0:.2f}, {lx1:.2f}] y [{ly0:.2f}, {ly1:.2f}] m): the map is of another place "
            "or another frame; to run in the world the map shows, pass the map as layout too (or leave layout unset)"
        )
    segs = layout.wall_segments()
    n_outer = 0 if isinstance(layout, MapLayout) else len(layout.outer)  # a map's outer "wall" is only its edge
    occ = grid.occupied_mask()
    if not occ.any():
        raise ValueError(f"the map has no occupied cell: it cannot be a map of the world {layout.name!r}")
    dist = ndimage.distance_transform_edt(~occ, sampling=res)
    interior = segs[len(layout.outer) :]
    for part, part_segs in (("walls", segs[len(layout.outer) - n_outer :]), ("interior walls", interior)):
        pts = [np.zeros((0, 2))]
        for a, b in part_segs:
            n = max(2, int(math.ceil(np.linalg.norm(b - a) / res)) + 1)
            pts.append(a + np.linspace(0.0, 1.0, n)[:, None] * (b - a))
        pts = np.concatenate(pts)
        if not len(pts):
            continue
        row, col = grid.world_to_cell(pts)
        row = np.clip(row, 0, grid.shape[0] - 1)
        col = np.clip(col, 0, grid.shape[1] - 1)
        frac = float(np.mean(dist[row, col] <= max_wall_dist_m))
        if frac < min_fraction:
            raise ValueError(
                f"only {100 * frac:.0f} % of the {part} of the world {layout.name!r} lie within {max_wall_dist_m} m "
                f"of an occupied map cell (need {100 * min_fraction:.0f} %): map and world disagree in frame or shape"
            )
