"""The pymunk simulation of a layout: static walls and objects, a differential-drive robot.

Build a fresh world on every reset with `build_world` (leftover bodies make
pymunk runs nondeterministic). Sensors cast rays against `World.scene`, the
segments of the very shapes in the pymunk space; the robot's motion (`World.drive`)
is resolved against the same segments by projection, so its state is its pose alone:
no solver cache, copies that never diverge, and a clearance never below the radius.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from dataclasses import dataclass

import numba
import numpy as np
import pymunk
from pymunk.autogeometry import convex_decomposition

from filters.numbers import is_real
from filters.pose import wrap_angle, wrap_float

from .config import PhysicsParams, RobotParams
from .layouts import Layout, point_in_polygon
from .raycast import SegmentScene

_ROBOT_TYPE = 1
_RESOLVE_ITERS = 16
"""Projections tried per substep before a blocked move is undone."""


def _crosses(p: np.ndarray, q: np.ndarray, a: np.ndarray, e: np.ndarray) -> bool:
    """True if the move ``p -> q`` properly crosses any segment ``a + s * e``, ``s in [0, 1]``."""
    d = q - p

    def cross(u, v):
        return u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]

    s1, s2 = cross(d, a - p), cross(d, a + e - p)
    s3, s4 = cross(e, p - a), cross(e, q - a)
    return bool(np.any((s1 * s2 < 0) & (s3 * s4 < 0)))


@numba.njit(cache=True, nogil=True)
def _drive_kernel(x, y, th, v, omega, dt, substeps, r, skin, a, e, iters):  # pragma: no cover - compiled
    """`World.drive`'s substeps against the segments ``a + s * e`` ``(M, 2)`` near the robot: ``(x, y, th,
    touched)``. The operations of `World.drive_reference` (and `World._resolve`, `_crosses`) one by one, in
    their order, so the same bits."""
    m = a.shape[0]
    ee = np.empty(m)
    for i in range(m):
        ee[i] = max(e[i, 0] * e[i, 0] + e[i, 1] * e[i, 1], 1e-300)
    collided = False
    for _ in range(substeps):
        nx = x + v * math.cos(th) * dt
        ny = y + v * math.sin(th) * dt
        th = th + omega * dt
        if m:
            px, py = nx, ny
            touched = False
            freed = False
            for _ in range(iters):
                k = -1
                dk = 0.0
                ck0 = ck1 = 0.0
                for i in range(m):
                    t = ((px - a[i, 0]) * e[i, 0] + (py - a[i, 1]) * e[i, 1]) / ee[i]
                    t = min(max(t, 0.0), 1.0)
                    c0 = a[i, 0] + t * e[i, 0]
                    c1 = a[i, 1] + t * e[i, 1]
                    d = math.hypot(px - c0, py - c1)
                    if k < 0 or d < dk:
                        k, dk, ck0, ck1 = i, d, c0, c1
                if dk >= r:
                    freed = True
                    break
                touched = True
                if dk > 1e-12:
                    n0, n1 = (px - ck0) / dk, (py - ck1) / dk
                else:  # on the segment: push back towards where the robot came from
                    sq = math.sqrt(ee[k])
                    n0, n1 = -e[k, 1] / sq, e[k, 0] / sq
                    if (x - ck0) * n0 + (y - ck1) * n1 < 0:
                        n0, n1 = -n0, -n1
                px = ck0 + n0 * (r + skin)
                py = ck1 + n1 * (r + skin)
            if not freed:
                px, py, touched = x, y, True
            elif touched:
                dx, dy = px - x, py - y
                for i in range(m):
                    ax, ay, ex, ey = a[i, 0], a[i, 1], e[i, 0], e[i, 1]
                    s1 = dx * (ay - y) - dy * (ax - x)
                    s2 = dx * (ay + ey - y) - dy * (ax + ex - x)
                    s3 = ex * (y - ay) - ey * (x - ax)
                    s4 = ex * (py - ay) - ey * (px - ax)
                    if s1 * s2 < 0 and s3 * s4 < 0:
                        px, py = x, y
                        break
            collided |= touched
            nx, ny = px, py
        x, y = nx, ny
    return x, y, th, collided


def _counter_clockwise(poly: np.ndarray) -> np.ndarray:
    x, y = poly[:, 0], poly[:, 1]
    area = np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)
    return poly if area > 0 else poly[::-1].copy()


def _convex_parts(poly: np.ndarray) -> list[list[tuple[float, float]]]:
    """Convex pieces of a simple polygon (pymunk polygons must be convex)."""
    pts = [tuple(map(float, p)) for p in poly]
    edges = np.roll(poly, -1, axis=0) - poly
    cross = edges[:, 0] * np.roll(edges[:, 1], -1) - edges[:, 1] * np.roll(edges[:, 0], -1)
    if np.all(cross >= -1e-12) or np.all(cross <= 1e-12):
        return [pts]
    return [list(part) for part in convex_decomposition(pts + [pts[0]], 1e-9)]


@dataclass(frozen=True, eq=False)
class StaticGeometry:
    """What a world's static part is built from, computed once per (layout, extra obstacles).

    Attributes:
        walls: ``(K, 2, 2)`` wall segments.
        obstacles: obstacle polygons (layout objects first, then the extra obstacles, counter-clockwise).
        blocks: the layout's block polygons (solid, no class).
        convex_parts: per obstacle, its convex pieces (pymunk polygons must be convex).
        scene: the segments every sensor casts against.
        ring_edges: ``(E, 4)`` edges ``(x0, y0, x1, y1)`` of the outer wall (ring 0), the obstacles,
            then the layout's blocks (solid too; their edges are among the ``walls``).
        ring_start: ``(n_rings + 1,)``: ring ``k``'s edges are ``ring_edges[ring_start[k]:ring_start[k + 1]]``.
        ring_bbox: ``(n_rings, 4)`` ``(x0, y0, x1, y1)`` of each ring.
        obstacle_buckets: CSR ``(start, items)`` of the rings ``k >= 1`` whose bounding box overlaps each
            cell of the scene's bucket grid (items are ring indices).
    """

    walls: np.ndarray
    obstacles: tuple[np.ndarray, ...]
    blocks: tuple[np.ndarray, ...]
    convex_parts: tuple[list[list[tuple[float, float]]], ...]
    scene: SegmentScene
    ring_edges: np.ndarray
    ring_start: np.ndarray
    ring_bbox: np.ndarray
    obstacle_buckets: tuple[np.ndarray, np.ndarray]


def _polygon_key(polys) -> tuple:
    return tuple((np.asarray(p, dtype=np.float64).shape, np.asarray(p, dtype=np.float64).tobytes()) for p in polys)


_geometry_cache: OrderedDict[tuple, StaticGeometry] = OrderedDict()


def static_geometry(layout: Layout, extra_obstacles=()) -> StaticGeometry:
    """The `StaticGeometry` of ``layout`` plus ``extra_obstacles`` (cached, 32 entries)."""
    key = (layout, _polygon_key(extra_obstacles))
    hit = _geometry_cache.get(key)
    if hit is not None:
        _geometry_cache.move_to_end(key)
        return hit
    walls = np.asarray(layout.wall_segments(), dtype=np.float64).reshape(-1, 2, 2)
    polygons = [np.asarray(o.polygon, dtype=np.float64) for o in layout.objects]
    obstacles = polygons + [_counter_clockwise(np.asarray(p, dtype=np.float64)) for p in extra_obstacles]
    segments, owners = [*walls], [-1] * len(walls)
    for i, poly in enumerate(obstacles):
        owner = i if i < len(polygons) else -1  # extra obstacles carry no class
        for a, b in zip(poly, np.roll(poly, -1, axis=0)):
            segments.append((a, b))
            owners.append(owner)
    # blocks' edges are walls (`Layout.wall_segments`); their insides are solid like the obstacles'
    blocks = [np.asarray(b, dtype=np.float64) for b in layout.blocks]
    rings = [np.asarray(layout.outer, dtype=np.float64)] + obstacles + blocks
    edges = np.concatenate([np.hstack([r, np.roll(r, -1, axis=0)]) for r in rings])
    ring_start = np.concatenate([[0], np.cumsum([len(r) for r in rings])]).astype(np.int64)
    ring_bbox = np.array([[*r.min(axis=0), *r.max(axis=0)] for r in rings], dtype=np.float64)
    scene = SegmentScene(np.asarray(segments, dtype=np.float64).reshape(-1, 2, 2), np.asarray(owners, np.int64))
    _, _, gx0, gy0, cell, nx, ny = scene.bucket_grid
    lists: list[list[int]] = [[] for _ in range(nx * ny)]
    for k in range(1, len(rings)):
        c0, r0 = (max(0, int(np.floor((v - g) / cell))) for v, g in zip(ring_bbox[k, :2], (gx0, gy0)))
        c1 = min(nx - 1, int(np.floor((ring_bbox[k, 2] - gx0) / cell)))
        r1 = min(ny - 1, int(np.floor((ring_bbox[k, 3] - gy0) / cell)))
        for r in range(r0, r1 + 1):
            for c in range(c0, c1 + 1):
                lists[r * nx + c].append(k)
    ob_start = np.concatenate([[0], np.cumsum([len(v) for v in lists])]).astype(np.int64)
    ob_items = np.array([k for v in lists for k in v], dtype=np.int64)
    geo = StaticGeometry(
        walls=walls,
        obstacles=tuple(obstacles),
        blocks=tuple(blocks),
        convex_parts=tuple(_convex_parts(p) for p in obstacles),
        scene=scene,
        ring_edges=np.ascontiguousarray(edges),
        ring_start=ring_start,
        ring_bbox=ring_bbox,
        obstacle_buckets=(ob_start, ob_items),
    )
    _geometry_cache[key] = geo
    while len(_geometry_cache) > 32:
        _geometry_cache.popitem(last=False)
    return geo


@numba.njit(cache=True, nogil=True, inline="always")
def _inside_ring(x, y, edges, lo, hi):  # pragma: no cover - compiled
    """Even-odd test of ``(x, y)`` against the edges ``lo:hi`` (the formula of ``point_in_polygon``)."""
    inside = False
    for k in range(lo, hi):
        x0 = edges[k, 0]
        y0 = edges[k, 1]
        x1 = edges[k, 2]
        y1 = edges[k, 3]
        if (y0 > y) != (y1 > y):
            if x < x0 + (y - y0) * (x1 - x0) / (y1 - y0):
                inside = not inside
    return inside


@numba.njit(cache=True, nogil=True)
def _free_kernel(
    xy,
    edges,
    ring_start,
    ring_bbox,
    ob_start,
    ob_items,
    a,
    e,
    seg_start,
    seg_items,
    gx0,
    gy0,
    cell,
    nx,
    ny,
    clearance,
    out,
):  # pragma: no cover - compiled
    """``out[p]``: point ``p`` inside ring 0, outside every obstacle ring, at least ``clearance``
    from every segment. The even-odd and distance formulas of
    `point_in_polygon` and `SegmentScene.distances`; only the
    obstacles and segments listed in the bucket cells near ``p`` are tested."""
    for p in range(xy.shape[0]):
        x = xy[p, 0]
        y = xy[p, 1]
        ok = _inside_ring(x, y, edges, ring_start[0], ring_start[1])
        cx = int(math.floor((x - gx0) / cell))
        cy = int(math.floor((y - gy0) / cell))
        if ok and 0 <= cx < nx and 0 <= cy < ny:
            c = cy * nx + cx
            for q in range(ob_start[c], ob_start[c + 1]):
                k = ob_items[q]
                bb = ring_bbox[k]
                if bb[0] <= x <= bb[2] and bb[1] <= y <= bb[3]:
                    if _inside_ring(x, y, edges, ring_start[k], ring_start[k + 1]):
                        ok = False
                        break
        if ok:
            c0 = max(0, int(math.floor((x - clearance - gx0) / cell)))
            c1 = min(nx - 1, int(math.floor((x + clearance - gx0) / cell)))
            r0 = max(0, int(math.floor((y - clearance - gy0) / cell)))
            r1 = min(ny - 1, int(math.floor((y + clearance - gy0) / cell)))
            for r in range(r0, r1 + 1):
                if not ok:
                    break
                for c in range(c0, c1 + 1):
                    if not ok:
                        break
                    k = r * nx + c
                    for q in range(seg_start[k], seg_start[k + 1]):
                        i = seg_items[q]
                        ex = e[i, 0]
                        ey = e[i, 1]
                        ee = max(ex * ex + ey * ey, 1e-18)
                        t = ((x - a[i, 0]) * ex + (y - a[i, 1]) * ey) / ee
                        t = min(max(t, 0.0), 1.0)
                        dx = a[i, 0] + t * ex - x
                        dy = a[i, 1] + t * ey - y
                        if math.sqrt(dx * dx + dy * dy) < clearance:
                            ok = False
                            break
        out[p] = ok


def as_pose(value, what: str = "pose") -> np.ndarray:
    """``value`` as a ``(3,)`` float64 pose; ValueError naming ``what`` unless it is three finite real numbers."""
    a = None if isinstance(value, (str, bytes, dict)) else np.asarray(value) if _array_like(value) else None
    if a is None or a.shape != (3,) or a.dtype.kind not in "iuf" or not np.all(np.isfinite(a)):
        raise ValueError(f"{what} must be three finite numbers (x m, y m, theta rad), got {value!r:.80}")
    return a.astype(np.float64)


def _array_like(value) -> bool:
    if isinstance(value, np.ndarray):
        return True
    if not isinstance(value, (list, tuple)):
        return False
    return all(is_real(v) for v in value)


def check_substep(robot: RobotParams, physics: PhysicsParams) -> None:
    """ValueError if the robot at full speed moves its radius or more per physics substep (it could
    pass through thin walls)."""
    max_step = robot.max_linear_mps * physics.dt_s / physics.substeps
    if max_step >= robot.radius_m:
        raise ValueError(
            f"the robot would move {max_step:.3f} m per physics substep, not less than its radius "
            f"{robot.radius_m} m: it could pass through thin walls; raise physics.substeps or control_hz"
        )


class World:
    """A layout in pymunk plus the robot. Poses are ``(x, y, theta)``, metres and radians.

    Use `build_world`; then `set_pose` and `drive`. The static geometry
    (segments, convex pieces) comes from `static_geometry`, cached per layout; each world's
    pymunk `space` is its own, built when first asked for.
    """

    def __init__(self, layout: Layout, robot: RobotParams, physics: PhysicsParams, extra_obstacles=()):
        self.layout = layout
        self.robot_params = robot
        self.physics = physics
        check_substep(robot, physics)
        geo = static_geometry(layout, extra_obstacles)
        self.geometry = geo
        self._obstacles = [*geo.obstacles, *geo.blocks]  # solid
        self.scene = geo.scene
        # pushed-out robots stop this far beyond their radius: a few ulps of the coordinates, at least 1 nm
        self._skin = 1e-9 + 8 * float(np.spacing(np.abs(self.scene.segments).max(initial=1.0)))
        self.body = pymunk.Body(1.0, math.inf)
        self.shape = pymunk.Circle(self.body, robot.radius_m)
        self.shape.collision_type = _ROBOT_TYPE
        self.shape.friction = 0.0
        self._space: pymunk.Space | None = None

    @property
    def space(self) -> pymunk.Space:
        """The pymunk space: the static geometry as segments and convex polygons, and the robot.

        Built on first use: `drive` and the sensors work on the cached `geometry` (the same shapes),
        so an episode that never queries pymunk does not pay ~1-3 ms per reset to build it.
        """
        if self._space is None:
            space = pymunk.Space()
            space.collision_slop = 0.002
            space.iterations = 20
            static = space.static_body
            shapes = [pymunk.Segment(static, tuple(a), tuple(b), 0.0) for a, b in self.geometry.walls]
            shapes += [pymunk.Poly(static, part) for parts in self.geometry.convex_parts for part in parts]
            space.add(*shapes, self.body, self.shape)
            self._space = space
        return self._space

    def _reindex(self) -> None:
        if self._space is not None:
            self._space.reindex_shapes_for_body(self.body)

    # ---------------------------------------------------------------- poses
    @property
    def pose(self) -> np.ndarray:
        """True robot pose ``(3,)`` float64."""
        x, y = self.body.position
        return np.array([x, y, wrap_float(self.body.angle)], dtype=np.float64)

    def clearance(self, xy: np.ndarray) -> float:
        """Distance (m) from a point to the nearest wall or obstacle edge."""
        return float(self.scene.distance_to(np.asarray(xy, dtype=np.float64)).min())

    def is_free(self, xy: np.ndarray, margin_m: float = 0.0) -> bool:
        """True if the robot disc at ``xy`` fits inside the outer wall, outside every obstacle."""
        return bool(self.free_points(np.asarray(xy, dtype=np.float64)[None], margin_m)[0])

    def free_points(self, xy: np.ndarray, margin_m: float = 0.0) -> np.ndarray:
        """Vectorised `is_free`: bool ``(P,)`` for points ``(P, 2)``; compiled (`free_points_reference`)."""
        xy = np.ascontiguousarray(np.asarray(xy, dtype=np.float64).reshape(-1, 2))
        g = self.geometry
        out = np.empty(xy.shape[0], dtype=np.bool_)
        clearance = float(self.robot_params.radius_m + margin_m)
        ob_start, ob_items = g.obstacle_buckets
        seg_start, seg_items, gx0, gy0, cell, nx, ny = g.scene.bucket_grid
        _free_kernel(
            xy, g.ring_edges, g.ring_start, g.ring_bbox, ob_start, ob_items, g.scene._a, g.scene._e,
            seg_start, seg_items, gx0, gy0, cell, nx, ny, clearance, out,
        )  # fmt: skip
        solid_at = getattr(self.layout, "solid_at", None)  # worlds built from maps: occupied cells are solid
        if solid_at is not None and out.any():
            out[out] &= ~solid_at(xy[out])
        return out

    def free_points_reference(self, xy: np.ndarray, margin_m: float = 0.0) -> np.ndarray:
        """`free_points` in plain NumPy (the reference the compiled test is checked against)."""
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        ok = point_in_polygon(xy, np.asarray(self.layout.outer))
        solid_at = getattr(self.layout, "solid_at", None)  # worlds built from maps: occupied cells are solid
        if solid_at is not None:
            ok[ok] &= ~solid_at(xy[ok])
        for poly in self._obstacles:
            ok &= ~point_in_polygon(xy, poly)
        ok[ok] &= self.scene.distances(xy[ok]).min(axis=1) >= self.robot_params.radius_m + margin_m
        return ok

    def not_free_reason(self, xy: np.ndarray) -> str:
        """Why the robot may not stand at ``xy`` (for error messages); "" where it may (`is_free`)."""
        xy = np.asarray(xy, dtype=np.float64).reshape(2)
        if self.is_free(xy):
            return ""
        solid_at = getattr(self.layout, "solid_at", None)
        if solid_at is not None and bool(solid_at(xy[None])[0]):
            return "it lies on a map cell that is not known free (occupied or unknown, or off the map)"
        return (
            f"the robot (radius {self.robot_params.radius_m} m) would overlap a wall, object or block, or lie "
            "outside the outer wall"
        )

    def set_pose(self, pose) -> None:
        """Teleport the robot. Raises ValueError (state unchanged) for a non-finite or blocked pose."""
        p = as_pose(pose, "pose")
        reason = self.not_free_reason(p[:2])
        if reason:
            raise ValueError(f"pose {p.tolist()} is not free: {reason}")
        self.body.position = (float(p[0]), float(p[1]))
        self.body.angle = float(wrap_angle(p[2]))
        self.body.velocity = (0.0, 0.0)
        self.body.angular_velocity = 0.0
        self._reindex()

    def sample_free_pose(self, rng: np.random.Generator, margin_m: float = 0.1, max_tries: int = 10000) -> np.ndarray:
        """A uniformly random free pose where the robot fits with ``margin_m`` to spare (rejection sampling
        inside the outer wall's bounds). ValueError if ``max_tries`` draws found none."""
        x0, x1, y0, y1 = self.layout.bounds()
        for _ in range(max_tries):
            xy = rng.uniform((x0, y0), (x1, y1))
            if self.is_free(xy, margin_m):
                return np.array([xy[0], xy[1], rng.uniform(-math.pi, math.pi)])
        raise ValueError(
            f"layout {self.layout.name!r} has no free space for the robot: no place found where it fits "
            f"(radius {self.robot_params.radius_m} m) with {margin_m} m to spare ({max_tries} random tries); "
            "give a start pose (reset option pose) or make the layout roomier"
        )

    # ---------------------------------------------------------------- motion
    def drive(self, v_mps: float, omega_rps: float) -> bool:
        """Drive with body-frame speed ``v`` and turn rate ``omega`` for one control step.

        Per physics substep the robot moves ``v * dt`` along its heading at the substep's
        start and turns ``omega * dt`` (the integration pymunk does for a free body); a
        disc that would then overlap a wall or obstacle is projected back out along the
        contact normals (frictionless sliding). If that does not free it within
        ``_RESOLVE_ITERS`` projections, or the projection would cross a wall, as in a gap
        narrower than the robot, the substep's translation is undone. So the robot's
        clearance never drops below its radius (to ``_SKIN_M``), and the outcome is a
        function of the pose alone: copies (``copy.deepcopy``, pickle) of a world in
        contact evolve identically. Returns True if the robot touched an obstacle.

        Compiled (`_drive_kernel`); `drive_reference` is the same in Python, the same bits. The speeds are
        taken as Python floats (float64), whatever their type.
        """
        phys = self.physics
        r = self.robot_params.radius_m
        x, y = self.body.position
        th0 = float(self.body.angle)

        def run(near):
            return _drive_kernel(
                float(x), float(y), th0, float(v_mps), float(omega_rps), phys.dt_s / phys.substeps,
                int(phys.substeps), float(r), float(self._skin), self.scene.a[near], self.scene.e[near], _RESOLVE_ITERS,
            )  # fmt: skip

        x, y, th, collided = self._with_every_segment_reached(float(x), float(y), float(v_mps), run)
        self._place(x, y, th)
        return bool(collided)

    def _with_every_segment_reached(self, x: float, y: float, v_mps: float, run) -> tuple:
        """``run(near)`` (a control step from ``(x, y)`` that tests the segments ``near``, returning ``(x, y, th,
        collided)``) with ``near`` every segment within reach of the start, and again with more while the step
        ends within the robot's radius of a segment it did not test: a push out of one wall can carry the robot
        farther than ``v * dt`` (a review found 0.95 m against 0.90 at the substep limit), up to one it never saw."""
        r = self.robot_params.radius_m
        budget = abs(v_mps) * self.physics.dt_s
        near = self.scene.near(np.array([x, y]), r + budget + 2 * self._skin)
        while True:
            out = run(near)
            if math.hypot(out[0] - x, out[1] - y) <= budget + self._skin:
                return out  # within reach of the start: every segment within r of the end was tested
            missed = np.setdiff1d(self.scene.near(np.array([out[0], out[1]]), r), near)
            if not missed.size:
                return out
            near = np.union1d(near, missed)

    def drive_reference(self, v_mps: float, omega_rps: float) -> bool:
        """`drive` in Python and NumPy (the reference the compiled kernel is tested against)."""
        v_mps, omega_rps = float(v_mps), float(omega_rps)
        phys = self.physics
        dt = phys.dt_s / phys.substeps
        x0, y0 = (float(c) for c in self.body.position)
        th0 = float(self.body.angle)

        def run(near):
            x, y, th, collided = x0, y0, th0, False
            for _ in range(int(phys.substeps)):
                nx = x + v_mps * math.cos(th) * dt
                ny = y + v_mps * math.sin(th) * dt
                th = th + omega_rps * dt
                if len(near):
                    (nx, ny), hit = self._resolve(np.array([x, y]), np.array([nx, ny]), near)
                    collided |= hit
                x, y = float(nx), float(ny)
            return x, y, th, collided

        x, y, th, collided = self._with_every_segment_reached(x0, y0, v_mps, run)
        self._place(x, y, th)
        return collided

    def _place(self, x: float, y: float, th: float) -> None:
        """The robot at ``(x, y)`` with body angle ``th`` (not wrapped), at rest."""
        self.body.position = (x, y)
        self.body.angle = th
        self.body.velocity = (0.0, 0.0)
        self.body.angular_velocity = 0.0
        self._reindex()

    def _resolve(self, prev: np.ndarray, p: np.ndarray, near: np.ndarray) -> tuple[np.ndarray, bool]:
        """``(position, touched)``: ``p`` pushed out of the segments ``near`` (indices), or ``prev``."""
        r = self.robot_params.radius_m
        a, e = self.scene.a[near], self.scene.e[near]
        ee = np.maximum(np.sum(e * e, axis=1), 1e-300)
        touched = False
        for _ in range(_RESOLVE_ITERS):
            t = np.clip(np.sum((p - a) * e, axis=1) / ee, 0.0, 1.0)
            closest = a + t[:, None] * e
            off = p - closest
            d = np.hypot(off[:, 0], off[:, 1])
            k = int(np.argmin(d))
            if d[k] >= r:
                break
            touched = True
            if d[k] > 1e-12:
                n = off[k] / d[k]
            else:  # on the segment: push back towards where the robot came from
                n = np.array([-e[k, 1], e[k, 0]]) / math.sqrt(ee[k])
                back = prev - closest[k]  # written out: np.dot would go through BLAS, whose fused multiply-add
                n = n if back[0] * n[0] + back[1] * n[1] >= 0 else -n  # rounds otherwise (and per library)
            p = closest[k] + n * (r + self._skin)
        else:
            return prev, True
        if touched and _crosses(prev, p, a, e):
            return prev, True
        return p, touched


def build_world(
    layout: Layout,
    robot: RobotParams | None = None,
    physics: PhysicsParams | None = None,
    extra_obstacles=(),
) -> World:
    """Build a fresh pymunk world for ``layout``.

    Args:
        extra_obstacles: polygons ``(V, 2)`` added to the world but not to the
            layout (so not to any map built from it): the "environment changed"
            scenario of paper 004.
    """
    return World(layout, robot or RobotParams(), physics or PhysicsParams(), extra_obstacles)
