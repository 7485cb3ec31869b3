"""The mapping run of paper 004 §2: drive through a layout with known poses, build the maps.

The robot visits a lattice of free waypoints in boustrophedon order (shortest
lattice paths around walls), turning on the spot at each waypoint so the forward
camera sees every direction. At every pose the simulated lidar and semantic
camera (with their noise, misses and false detections) feed the log-odds
occupancy and Bayesian semantic mappers of :mod:`filters.mapping.occupancy`. The result
disagrees with the layout as a map built on a robot does.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import shortest_path

from filters.mapping.grid import GridMap
from filters.mapping.occupancy import OccupancyMapper, OccupancyParams, SemanticMapper

from .config import CameraParams, LidarParams
from .layouts import CLASS_NAMES, Layout
from .rasterize import rasterize
from .sensors import Lidar, SemanticCamera
from .world import build_world


def mapping_path(layout: Layout, spacing_m: float = 0.6, step_m: float = 0.2, turns: int = 8) -> np.ndarray:
    """Known poses ``(P, 3)`` of a mapping drive covering the layout's free space.

    Waypoints: a ``spacing_m`` lattice of poses with at least robot-radius + 0.1 m
    clearance, visited in boustrophedon order; between waypoints the path follows
    the shortest lattice route (straight 8-neighbour hops that stay free), sampled
    every ``step_m`` with the heading along the path; at each waypoint's first visit
    the robot turns through ``turns`` headings. A waypoint the lattice cannot reach
    from the current one starts a new leg (the poses are known, so the drive may jump):
    every free waypoint is visited.
    """
    world = build_world(layout)
    x0, x1, y0, y1 = layout.bounds()
    xs = np.arange(x0 + spacing_m / 2, x1, spacing_m)
    ys = np.arange(y0 + spacing_m / 2, y1, spacing_m)
    gx, gy = np.meshgrid(xs, ys)
    free = world.free_points(np.stack([gx.ravel(), gy.ravel()], 1), margin_m=0.1).reshape(gy.shape)
    nodes, index = [], {}
    for j in range(len(ys)):
        order = range(len(xs)) if j % 2 == 0 else range(len(xs) - 1, -1, -1)
        for i in order:
            if free[j, i]:
                index[(i, j)] = len(nodes)
                nodes.append((i, j))
    if not nodes:
        raise ValueError(f"layout {layout.name!r} has no free space for a mapping run")
    pts = np.array([(xs[i], ys[j]) for i, j in nodes])

    # candidate edges to the 8-neighbours; keep those whose straight hop stays free
    pairs = [
        (k, index[(i + di, j + dj)])
        for (i, j), k in index.items()
        for di, dj in ((1, 0), (0, 1), (1, 1), (1, -1))
        if (i + di, j + dj) in index
    ]
    a, b = (np.array(v, dtype=np.int64) for v in zip(*pairs)) if pairs else (np.zeros(0, int), np.zeros(0, int))
    t = np.linspace(0.0, 1.0, 9)
    samples = pts[a][:, None, :] + t[None, :, None] * (pts[b] - pts[a])[:, None, :]
    ok = world.free_points(samples.reshape(-1, 2)).reshape(len(a), len(t)).all(axis=1)
    a, b = a[ok], b[ok]
    d = np.linalg.norm(pts[a] - pts[b], axis=1)
    rows, cols, dists = np.concatenate([a, b]), np.concatenate([b, a]), np.concatenate([d, d])
    graph = csr_matrix((dists, (rows, cols)), shape=(len(nodes), len(nodes)))
    _, pred = shortest_path(graph, directed=False, return_predecessors=True)

    # the route: (node, reached by driving) pairs; a node the lattice cannot reach from the
    # current one (a doorway no straight hop crosses) starts a new leg: the poses are known,
    # so the drive need not be continuous, and every free waypoint gets visited
    route: list[tuple[int, bool]] = [(0, False)]
    visited = {0}
    for k in range(1, len(nodes)):
        if k in visited:
            continue
        cur = route[-1][0]
        hop, back = [], k
        while back != cur and back >= 0:
            hop.append(back)
            back = pred[cur, back]
        steps = [(h, True) for h in hop[::-1]] if back >= 0 else [(k, False)]
        route += steps
        visited.update(h for h, _ in steps)

    def look_around(p, heading):
        return [np.array([p[0], p[1], heading + 2 * math.pi * q / turns]) for q in range(turns)]

    poses: list[np.ndarray] = look_around(pts[0], 0.0)
    seen = {0}
    for (a, _), (b, driven) in zip(route[:-1], route[1:]):
        pa, pb = pts[a], pts[b]
        heading = math.atan2(pb[1] - pa[1], pb[0] - pa[0]) if driven else 0.0
        if driven:
            n = max(1, int(np.ceil(np.linalg.norm(pb - pa) / step_m)))
            poses += [np.array([*(pa + t * (pb - pa)), heading]) for t in np.arange(1, n) / n]
        if b not in seen:  # first visit: look around
            seen.add(b)
            poses += look_around(pb, heading)
        else:
            poses.append(np.array([pb[0], pb[1], heading]))
    out = np.array(poses)
    out[:, 2] = (out[:, 2] + math.pi) % (2 * math.pi) - math.pi
    return out


def build_maps(
    layout: Layout,
    lidar: LidarParams | None = None,
    camera: CameraParams | None = None,
    rng: np.random.Generator | None = None,
    resolution_m: float = 0.05,
) -> GridMap:
    """Run the mapping drive on ``layout`` and return the occupancy + semantic map.

    Sensors are simulated with their configured noise; ``rng`` (default: seed 0)
    drives that noise, so the same generator gives the same map.
    """
    rng = rng if rng is not None else np.random.default_rng(0)
    lidar_s = Lidar(lidar or LidarParams())
    camera_s = SemanticCamera(camera or CameraParams())
    world = build_world(layout)
    template = rasterize(layout, resolution_m)
    # the simulated lidar's dropouts read as "no return" in front of real walls: they must not clear
    occ = OccupancyMapper.like(template, OccupancyParams(clear_no_return=False))
    sem = SemanticMapper.like(template, CLASS_NAMES)
    poses = mapping_path(layout)
    lidar_scans, camera_scans = [], []
    for pose in poses:
        lidar_scans.append(lidar_s.read(world, pose, rng))
        camera_scans.append(camera_s.read(world, pose, rng))
    occ.update_many(poses, lidar_scans)
    sem.update_many(poses, camera_scans)
    return occ.to_grid(sem)
