"""The mapping run of paper 004 §2: drive through a layout with known poses, build the maps.

The robot visits a lattice of free waypoints (since version 6 also waypoints in passages that fall
between the lattice's rows and columns), turning on the spot at each first visit so
the forward camera sees every direction. The tour is greedy: from the current waypoint,
a breadth-first search over the lattice (straight 8-neighbour hops that stay free) finds
the nearest unvisited waypoint (ties: lowest boustrophedon index), and the robot drives
that lattice path. A waypoint the lattice cannot reach starts a new leg (the poses are
known, so the drive may jump). Time and memory grow with the number of waypoints (the
layout's area), not its square: no all-pairs shortest paths.

At every pose the simulated lidar and semantic camera (with their noise, misses and false
detections) feed the log-odds occupancy and Bayesian semantic mappers of
`filters.mapping.occupancy`, in chunks of poses so memory stays bounded. The result
disagrees with the layout as a map built on a robot does.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from scipy.spatial import cKDTree

from filters.mapping.grid import GridMap
from filters.mapping.occupancy import (
    OccupancyMapper,
    OccupancyParams,
    SemanticMapper,
    SemanticParams,
    drop_unsupported_class_cells,
)

from .config import CameraParams, LidarParams
from .layouts import CLASS_NAMES, Layout, LayoutError
from .rasterize import raster_geometry
from .sensors import Lidar, SemanticCamera
from .world import build_world

MAPPING_RUN_VERSIONS = ("2", "3", "4", "5", "6")
"""The mapping runs an env can ask for (`build_maps`' ``version``; each keys its own cached maps):

* ``"2"`` (``SemReloc-v7`` and before): a camera beam without a return lowers every class along the
  camera's whole range. The camera reads an object nearer than its minimum range (0.5 m) as no
  return, so where the drive passes that close to an object its beams cleared the object and the
  space behind it: a cabinet against a wall could lose all its class cells, or some of them, as its
  twin elsewhere kept them, and the relocalizer then preferred the twin's place.
* ``"3"`` (``SemReloc-v8`` and ``-v9``): the camera's no-return beams update nothing (as the lidar's already did).
* ``"4"`` (``SemReloc-v10``): version 3, then class cells that no confidently marked cell of their
  class backs up are dropped (`filters.mapping.occupancy.drop_unsupported_class_cells` with
  `STRAY_SUPPORT_P` and `STRAY_RADIUS_M`): the camera's whole-object mislabels left 1-20 stray
  class cells per map, on other objects' surfaces, where the relocalizer matched them.
* ``"5"`` (``SemReloc-v11``): version 4, then the lidar's no-return beams clear the cells no beam
  observed, up to the first surface (`filters.mapping.occupancy.OccupancyMapper.clear_unobserved`): space
  that returns cross too rarely to mark free (near and beyond the lidar's range from every surface: the middle
  of a large hall) was left unknown, so the relocalizer could neither start nor inject particles there.
  Elsewhere the maps are version 4's but for unknown cells the pass reaches (docs/maps.md, "Unobserved space").
* ``"6"`` (``SemReloc-v12`` to ``-v17``): version 5 on a drive that also enters passages between its lattice's rows and
  columns (`mapping_drive`'s ``narrow``): a corridor about 1 m wide could get no waypoint, so its walls were
  mapped only from its ends, in dashes that differed between two identical corridors, and the relocalizer
  read the difference as evidence for one of them (docs/maps.md, "Narrow passages").
"""
MAPPING_RUN_VERSION = MAPPING_RUN_VERSIONS[-1]
"""The newest mapping run. Add a version when its output changes for the same inputs."""

STRAY_SUPPORT_P, STRAY_RADIUS_M = 0.9, 0.1
"""Version 4 keeps a class cell only if a cell of its class within this distance (m) has at least this
probability (docs/maps.md, "Stray class cells"). Changing them needs a new version: the map cache's keys
(`semreloc_env.maps.map_key`) hold the version, not these."""

CHUNK_POSES = 2048
"""Poses sensed and integrated per batch by `build_maps` (bounds its memory)."""


@numba.njit(cache=True, nogil=True)
def _greedy_tour(indptr, indices, n):  # pragma: no cover - compiled
    """Visit order of nodes ``0..n-1`` of a graph (CSR): ``(nodes, driven)`` arrays.

    From node 0, repeatedly breadth-first search to the nearest unvisited node (neighbours
    in ascending index order, so ties go to the lowest index) and append the path to it
    (``driven = True``); when none is reachable, jump to the lowest unvisited node
    (``driven = False``). Each search stops at its first unvisited node.
    """
    visited = np.zeros(n, np.bool_)
    stamp = np.full(n, -1, np.int64)  # BFS epoch that reached a node (no clearing between searches)
    parent = np.empty(n, np.int64)
    queue = np.empty(n, np.int64)
    out_nodes = np.empty(4 * n + 8, np.int64)
    out_driven = np.empty(4 * n + 8, np.bool_)
    m = 0
    cur = 0
    visited[0] = True
    n_visited = 1
    out_nodes[0] = 0
    out_driven[0] = False
    m = 1
    lowest = 0  # every node below this is visited
    epoch = 0
    while n_visited < n:
        epoch += 1
        head = 0
        tail = 0
        queue[tail] = cur
        tail += 1
        stamp[cur] = epoch
        found = -1
        while head < tail and found < 0:
            u = queue[head]
            head += 1
            for q in range(indptr[u], indptr[u + 1]):
                v = indices[q]
                if stamp[v] != epoch:
                    stamp[v] = epoch
                    parent[v] = u
                    if not visited[v]:
                        found = v
                        break
                    queue[tail] = v
                    tail += 1
        if found >= 0:
            k = 0  # the path back to cur, reversed into the output
            v = found
            while v != cur:
                queue[k] = v
                k += 1
                v = parent[v]
            if m + k > out_nodes.shape[0]:
                grow = max(out_nodes.shape[0], k)
                out_nodes = np.concatenate((out_nodes, np.empty(grow, np.int64)))
                out_driven = np.concatenate((out_driven, np.empty(grow, np.bool_)))
            for j in range(k - 1, -1, -1):
                out_nodes[m] = queue[j]
                out_driven[m] = True
                m += 1
                if not visited[queue[j]]:
                    visited[queue[j]] = True
                    n_visited += 1
            cur = found
        else:
            while visited[lowest]:
                lowest += 1
            if m + 1 > out_nodes.shape[0]:
                out_nodes = np.concatenate((out_nodes, np.empty(out_nodes.shape[0], np.int64)))
                out_driven = np.concatenate((out_driven, np.empty(out_driven.shape[0], np.bool_)))
            cur = lowest
            visited[cur] = True
            n_visited += 1
            out_nodes[m] = cur
            out_driven[m] = False
            m += 1
    return out_nodes[:m], out_driven[:m]


FILL_STEP_FRACTION = 0.25
"""Version 6's narrow-passage waypoints are picked from a lattice this fraction of the waypoint spacing."""
FILL_COVER_FRACTION = 1.0
"""A feasible point farther than this fraction of the spacing from every waypoint is not covered (on an open
floor no point is farther than ``sqrt(2) / 2 = 0.71`` of it from the lattice's nearest waypoint)."""


@numba.njit(cache=True, nogil=True)
def _greedy_cover(xy, r):  # pragma: no cover - compiled
    """Mask of the points (in order) kept by a greedy pass: a point is kept when it lies farther than ``r`` from
    every point kept before it. The kept points are filed in ``r``-sized cells, so a point is compared with those
    of the 3 x 3 cells around its own only (no two kept points share much of a cell): linear in the points."""
    n = xy.shape[0]
    keep = np.zeros(n, np.bool_)
    if n == 0:
        return keep
    cell = r * (1.0 + 1e-6)  # a hair wider than r: a point within r of another is in a neighbouring cell
    x0, y0 = xy[:, 0].min(), xy[:, 1].min()
    nx = int((xy[:, 0].max() - x0) / cell) + 1
    ny = int((xy[:, 1].max() - y0) / cell) + 1
    head = np.full(nx * ny, -1, np.int64)  # per cell: the last point kept in it, then `nxt` back through the rest
    nxt = np.full(n, -1, np.int64)
    r2 = r * r
    for i in range(n):
        cx = int((xy[i, 0] - x0) / cell)
        cy = int((xy[i, 1] - y0) / cell)
        far = True
        for gy in range(max(cy - 1, 0), min(cy + 2, ny)):
            for gx in range(max(cx - 1, 0), min(cx + 2, nx)):
                j = head[gy * nx + gx]
                while j >= 0 and far:
                    dx = xy[i, 0] - xy[j, 0]
                    dy = xy[i, 1] - xy[j, 1]
                    if dx * dx + dy * dy <= r2:
                        far = False
                    j = nxt[j]
        if far:
            keep[i] = True
            c = cy * nx + cx
            nxt[i] = head[c]
            head[c] = i
    return keep


def _boustrophedon(free: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(rows, cols)`` of the True cells of ``free`` ``(Y, X)``: even rows left to right, odd rows right to left."""
    ny, nx = free.shape
    cols = np.where((np.arange(ny) % 2 == 0)[:, None], np.arange(nx)[None, :], np.arange(nx)[::-1])
    jj = np.repeat(np.arange(ny), nx)
    ii = cols.ravel()
    keep = free[jj, ii]
    return jj[keep], ii[keep]


def _feasible_lattice(world, layout: Layout, step_m: float):
    """``(points (V, 2), feasible (Y, X), rows (V,), cols (V,))``: the points of a ``step_m`` lattice over the
    layout's bounds where the robot fits with 0.1 m to spare, in boustrophedon order (`_boustrophedon`)."""
    x0, x1, y0, y1 = layout.bounds()
    xs = np.arange(x0 + step_m / 2, x1, step_m)
    ys = np.arange(y0 + step_m / 2, y1, step_m)
    gx, gy = np.meshgrid(xs, ys)
    free = world.free_points(np.stack([gx.ravel(), gy.ravel()], 1), margin_m=0.1).reshape(gy.shape)
    jj, ii = _boustrophedon(free)
    return np.stack([xs[ii], ys[jj]], axis=1), free, jj, ii


def _narrow_waypoints(world, layout: Layout, pts: np.ndarray, spacing_m: float) -> np.ndarray:
    """``(U, 2)`` extra waypoints where the lattice ``pts`` leaves feasible floor uncovered (version 6).

    Passages narrower than about ``spacing_m`` plus the robot's clearance can fall between the lattice's rows
    and columns: a 1 m corridor got no waypoint, so the drive never entered it and mapped its walls only from
    its ends, in dashes (docs/maps.md, "Narrow passages"). Feasible points of a `FILL_STEP_FRACTION` lattice
    farther than `FILL_COVER_FRACTION` of the spacing from every waypoint are kept greedily, in boustrophedon
    order, each farther than that from the ones kept before it.
    """
    fine, _, _, _ = _feasible_lattice(world, layout, spacing_m * FILL_STEP_FRACTION)
    r = spacing_m * FILL_COVER_FRACTION
    if len(pts):
        dist, _ = cKDTree(pts).query(fine, distance_upper_bound=r)
        fine = fine[~np.isfinite(dist)]
    return fine[_greedy_cover(np.ascontiguousarray(fine), r)]


def _lattice(layout: Layout, spacing_m: float, narrow: bool = False):
    """Free waypoints ``(V, 2)`` in boustrophedon order and the CSR adjacency of free straight hops.

    ``narrow`` (version 6): `_narrow_waypoints` follow the lattice's, each joined by straight free hops to every
    waypoint within ``sqrt(2) * spacing_m`` (the lattice's own diagonal hop)."""
    world = build_world(layout)
    pts, free, jj, ii = _feasible_lattice(world, layout, spacing_m)
    extra = _narrow_waypoints(world, layout, pts, spacing_m) if narrow else np.zeros((0, 2))
    if ii.size + len(extra) == 0:
        step = spacing_m * FILL_STEP_FRACTION if narrow else spacing_m
        hint = "" if narrow else " (the mapping run's version 6 also looks between the lattice's points)"
        raise LayoutError(
            f"layout {layout.name!r} has no free space for a mapping run: no point of its {step:g} m waypoint "
            f"lattice has the robot's disc 0.1 m clear of every wall and object{hint}; the mapping run drives a "
            f"robot of the default radius, {world.robot_params.radius_m:g} m, whatever robot the env is given (a "
            "smaller robot: map_source='perfect')"
        )
    index = np.full(free.shape, -1, np.int64)
    index[jj, ii] = np.arange(ii.size)
    a_parts, b_parts = [], []
    for di, dj in ((1, 0), (0, 1), (1, 1), (1, -1)):
        ni, nj = ii + di, jj + dj
        ok = (ni >= 0) & (ni < free.shape[1]) & (nj >= 0) & (nj < free.shape[0])
        nb = np.full(ii.shape, -1, np.int64)
        nb[ok] = index[nj[ok], ni[ok]]
        has = nb >= 0
        a_parts.append(np.flatnonzero(has))
        b_parts.append(nb[has])
    if len(extra):
        n0 = len(pts)
        pts = np.concatenate([pts, extra])
        near = cKDTree(pts).query_pairs(math.sqrt(2.0) * spacing_m * (1 + 1e-9), output_type="ndarray")
        near = near[near[:, 1] >= n0]  # pairs with a new waypoint (query_pairs gives i < j)
        near = near[np.lexsort((near[:, 1], near[:, 0]))]
        a_parts.append(near[:, 0])
        b_parts.append(near[:, 1])
    a, b = np.concatenate(a_parts), np.concatenate(b_parts)
    t = np.linspace(0.0, 1.0, 9)
    ok = np.ones(a.size, bool)
    for lo in range(0, a.size, 65536):  # bounded temporaries
        sl = slice(lo, lo + 65536)
        samples = pts[a[sl]][:, None, :] + t[None, :, None] * (pts[b[sl]] - pts[a[sl]])[:, None, :]
        ok[sl] = world.free_points(samples.reshape(-1, 2)).reshape(-1, len(t)).all(axis=1)
    a, b = a[ok], b[ok]
    src, dst = np.concatenate([a, b]), np.concatenate([b, a])
    order = np.lexsort((dst, src))  # neighbours of each node in ascending index
    src, dst = src[order], dst[order]
    indptr = np.zeros(len(pts) + 1, np.int64)
    np.add.at(indptr, src + 1, 1)
    return pts, np.cumsum(indptr), np.ascontiguousarray(dst)


def mapping_path(
    layout: Layout, spacing_m: float = 0.6, step_m: float = 0.2, turns: int = 8, narrow: bool = False
) -> np.ndarray:
    """Known poses ``(P, 3)`` of a mapping drive covering the layout's free space.

    Waypoints: a ``spacing_m`` lattice of poses with at least robot-radius + 0.1 m
    clearance; the greedy nearest-unvisited tour of the module docstring over straight
    8-neighbour hops that stay free, sampled every ``step_m`` with the heading along the
    hop; at each waypoint's first visit the robot turns through ``turns`` headings starting
    from its arrival heading (0 after a jump). Every free waypoint is visited. ``narrow`` (the mapping run's
    version 6): waypoints are added where passages between the lattice's rows and columns have none
    (`_narrow_waypoints`).
    """
    return mapping_drive(layout, spacing_m, step_m, turns, narrow)[0]


LIDAR_TURN_STRIDE = 4
"""During the turn on the spot, the 360 deg lidar is integrated at every 4th heading only: it
sees the same surfaces from every heading, so more scans would only cost time (the camera,
70 deg wide, is integrated at every heading)."""


def mapping_drive(
    layout: Layout, spacing_m: float = 0.6, step_m: float = 0.2, turns: int = 8, narrow: bool = False
) -> tuple[np.ndarray, np.ndarray]:
    """``(poses (P, 3), lidar_due (P,) bool)``: `mapping_path` and where the lidar is integrated
    (every pose except the turn headings between each `LIDAR_TURN_STRIDE`-th)."""
    if not (isinstance(turns, int) and turns >= 1) or not (spacing_m > 0 and step_m > 0):
        raise ValueError(f"need spacing_m > 0, step_m > 0 and an int turns >= 1, got {spacing_m}, {step_m}, {turns}")
    pts, indptr, indices = _lattice(layout, spacing_m, narrow)
    nodes, driven = _greedy_tour(indptr, indices, len(pts))
    prev, nxt, drv = nodes[:-1], nodes[1:], driven[1:]
    d = pts[nxt] - pts[prev]
    heading = np.where(drv, np.arctan2(d[:, 1], d[:, 0]), 0.0)
    n_sub = np.where(drv, np.maximum(1, np.ceil(np.linalg.norm(d, axis=1) / step_m)).astype(np.int64), 1)
    first = np.zeros(len(nodes), bool)
    _, first_at = np.unique(nodes, return_index=True)
    first[first_at] = True
    # per hop: n_sub - 1 intermediate poses, then turns poses (first visit) or one pose at the waypoint
    n_end = np.where(first[1:], turns, 1)
    counts = (n_sub - 1) + n_end
    hop = np.repeat(np.arange(len(nxt)), counts)
    k = np.arange(hop.size) - np.repeat(np.cumsum(counts) - counts, counts)  # index within the hop
    inter = k < (n_sub - 1)[hop]
    frac = np.where(inter, (k + 1) / n_sub[hop], 1.0)
    xy = pts[prev][hop] + frac[:, None] * d[hop]
    q = np.where(inter, 0, k - (n_sub - 1)[hop])  # turn index at the waypoint
    th = heading[hop] + np.where(first[1:][hop], 2 * math.pi * q / turns, 0.0)
    start = np.column_stack([np.repeat(pts[0][None], turns, 0), 2 * math.pi * np.arange(turns) / turns])
    out = np.concatenate([start, np.column_stack([xy, th])])
    out[:, 2] = (out[:, 2] + math.pi) % (2 * math.pi) - math.pi
    q_all = np.concatenate([np.arange(turns), q])
    return out, q_all % LIDAR_TURN_STRIDE == 0


def narrow_drive(version: str) -> bool:
    """Whether the mapping run's ``version`` drives into narrow passages too (`mapping_drive`'s ``narrow``: 6 on)."""
    return int(version) >= 6


def build_maps(
    layout: Layout,
    lidar: LidarParams | None = None,
    camera: CameraParams | None = None,
    rng: np.random.Generator | None = None,
    resolution_m: float = 0.05,
    version: str = MAPPING_RUN_VERSION,
) -> GridMap:
    """Run the mapping drive on ``layout`` and return the occupancy + semantic map.

    Sensors are simulated with their configured noise; ``rng`` (default: seed 0)
    drives that noise, so the same generator gives the same map. The raster is that of
    `rasterize`. ``version``: one of `MAPPING_RUN_VERSIONS` (default the newest).
    """
    if version not in MAPPING_RUN_VERSIONS:
        raise ValueError(f"mapping run version must be one of {MAPPING_RUN_VERSIONS}, got {version!r}")
    rng = rng if rng is not None else np.random.default_rng(0)
    lidar_s = Lidar(lidar or LidarParams())
    camera_s = SemanticCamera(camera or CameraParams())
    world = build_world(layout)
    shape, origin = raster_geometry(layout, resolution_m)
    # the simulated lidar's dropouts read as "no return" in front of real walls: they must not clear
    occ = OccupancyMapper(shape, resolution_m, origin, OccupancyParams(clear_no_return=False))
    # ... nor the camera's, which also reads an object nearer than its minimum range as no return
    sem = SemanticMapper(shape, resolution_m, origin, CLASS_NAMES, SemanticParams(clear_no_return=version == "2"))
    poses, lidar_due = mapping_drive(layout, narrow=narrow_drive(version))
    rmax = lidar_s.params.range_max_m
    no_returns = []  # version 5's second pass: (lidar poses, no-return mask) per chunk
    for lo in range(0, len(poses), CHUNK_POSES):
        chunk = poses[lo : lo + CHUNK_POSES]
        lchunk = chunk[lidar_due[lo : lo + CHUNK_POSES]]
        ranges = lidar_s.read_many(world, lchunk, rng)
        occ.update_arrays(lchunk, ranges, lidar_s.angles, rmax)
        s_ranges, labels = camera_s.read_many(world, chunk, rng)
        sem.update_arrays(chunk, s_ranges, labels, camera_s.angles, camera_s.params.range_max_m)
        if version not in ("2", "3", "4"):
            no_returns.append((lchunk, ranges >= rmax))
    for lchunk, none in no_returns:
        occ.clear_unobserved_arrays(lchunk, np.where(none, rmax, 0.0), lidar_s.angles, rmax)
    grid = occ.to_grid(sem)
    if version not in ("2", "3"):
        grid = drop_unsupported_class_cells(grid, STRAY_SUPPORT_P, STRAY_RADIUS_M)
    return grid
