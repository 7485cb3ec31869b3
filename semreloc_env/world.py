"""The pymunk simulation of a layout: static walls and objects, a differential-drive robot.

Build a fresh world on every reset with :func:`build_world` (leftover bodies make
pymunk runs nondeterministic). Sensors cast rays against :attr:`World.scene`, the
segments read back from the very pymunk shapes the robot collides with.
"""

from __future__ import annotations

import math

import numpy as np
import pymunk
from pymunk.autogeometry import convex_decomposition

from filters.pose import wrap_angle

from .config import PhysicsParams, RobotParams
from .layouts import Layout, point_in_polygon
from .raycast import SegmentScene

_ROBOT_TYPE = 1


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


class World:
    """A layout in pymunk plus the robot. Poses are ``(x, y, theta)``, metres and radians.

    Use :func:`build_world`; then :meth:`set_pose` and :meth:`drive`.
    """

    def __init__(self, layout: Layout, robot: RobotParams, physics: PhysicsParams, extra_obstacles=()):
        self.layout = layout
        self.robot_params = robot
        self.physics = physics
        self.space = pymunk.Space()
        self.space.collision_slop = 0.002
        self.space.iterations = 20
        static = self.space.static_body
        segments, owners = [], []
        for a, b in layout.wall_segments():
            self.space.add(pymunk.Segment(static, tuple(a), tuple(b), 0.0))
            segments.append((a, b))
            owners.append(-1)
        max_step = robot.max_linear_mps * physics.dt_s / physics.substeps
        if max_step >= robot.radius_m:
            raise ValueError(
                f"the robot would move {max_step:.3f} m per physics substep, not less than its radius "
                f"{robot.radius_m} m: it could pass through thin walls; raise physics.substeps or control_hz"
            )
        polygons = [np.asarray(o.polygon) for o in layout.objects]
        self._obstacles = polygons + [_counter_clockwise(np.asarray(p, dtype=np.float64)) for p in extra_obstacles]
        for i, poly in enumerate(self._obstacles):
            for part in _convex_parts(poly):
                self.space.add(pymunk.Poly(static, part))
            owner = i if i < len(polygons) else -1  # extra obstacles carry no class
            for a, b in zip(poly, np.roll(poly, -1, axis=0)):
                segments.append((a, b))
                owners.append(owner)
        self.scene = SegmentScene(np.asarray(segments, dtype=np.float64), np.asarray(owners, dtype=np.int64))
        self.body = pymunk.Body(1.0, math.inf)
        self.shape = pymunk.Circle(self.body, robot.radius_m)
        self.shape.collision_type = _ROBOT_TYPE
        self.shape.friction = 0.0
        self.space.add(self.body, self.shape)

    # ---------------------------------------------------------------- poses
    @property
    def pose(self) -> np.ndarray:
        """True robot pose ``(3,)`` float64."""
        x, y = self.body.position
        return np.array([x, y, wrap_angle(self.body.angle)], dtype=np.float64)

    def clearance(self, xy: np.ndarray) -> float:
        """Distance (m) from a point to the nearest wall or obstacle edge."""
        return float(self.scene.distance_to(np.asarray(xy, dtype=np.float64)).min())

    def is_free(self, xy: np.ndarray, margin_m: float = 0.0) -> bool:
        """True if the robot disc at ``xy`` fits inside the outer wall, outside every obstacle."""
        return bool(self.free_points(np.asarray(xy, dtype=np.float64)[None], margin_m)[0])

    def free_points(self, xy: np.ndarray, margin_m: float = 0.0) -> np.ndarray:
        """Vectorised :meth:`is_free`: bool ``(P,)`` for points ``(P, 2)``."""
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        ok = point_in_polygon(xy, np.asarray(self.layout.outer))
        solid_at = getattr(self.layout, "solid_at", None)  # worlds built from maps: occupied cells are solid
        if solid_at is not None:
            ok[ok] &= ~solid_at(xy[ok])
        for poly in self._obstacles:
            ok &= ~point_in_polygon(xy, poly)
        ok[ok] &= self.scene.distances(xy[ok]).min(axis=1) >= self.robot_params.radius_m + margin_m
        return ok

    def set_pose(self, pose) -> None:
        """Teleport the robot. Raises ValueError (state unchanged) for a non-finite or blocked pose."""
        p = np.asarray(pose, dtype=np.float64).reshape(-1)
        if p.shape != (3,) or not np.all(np.isfinite(p)):
            raise ValueError(f"a pose must be three finite numbers (x, y, theta), got {pose!r}")
        if not self.is_free(p[:2]):
            raise ValueError(
                f"pose {p.tolist()} is not free: the robot (radius {self.robot_params.radius_m} m) "
                "would overlap a wall or object, or lie outside the outer wall"
            )
        self.body.position = (float(p[0]), float(p[1]))
        self.body.angle = float(wrap_angle(p[2]))
        self.body.velocity = (0.0, 0.0)
        self.body.angular_velocity = 0.0
        self.space.reindex_shapes_for_body(self.body)

    def sample_free_pose(self, rng: np.random.Generator, margin_m: float = 0.1, max_tries: int = 10000) -> np.ndarray:
        """A uniformly random free pose (rejection sampling inside the outer wall's bounds)."""
        x0, x1, y0, y1 = self.layout.bounds()
        for _ in range(max_tries):
            xy = rng.uniform((x0, y0), (x1, y1))
            if self.is_free(xy, margin_m):
                return np.array([xy[0], xy[1], rng.uniform(-math.pi, math.pi)])
        raise ValueError(f"layout {self.layout.name!r} has no free space for the robot")

    # ---------------------------------------------------------------- motion
    def drive(self, v_mps: float, omega_rps: float) -> bool:
        """Drive with body-frame speed ``v`` and turn rate ``omega`` for one control step.

        The command is applied at every physics substep; pymunk stops the robot
        against obstacles. Returns True if the robot touched an obstacle.
        """
        dt = self.physics.dt_s / self.physics.substeps
        collided = False
        for _ in range(int(self.physics.substeps)):
            th = self.body.angle
            self.body.velocity = (v_mps * math.cos(th), v_mps * math.sin(th))
            self.body.angular_velocity = omega_rps
            self.space.step(dt)
            collided |= self._push_out()
        self.body.velocity = (0.0, 0.0)
        self.body.angular_velocity = 0.0
        return collided

    def _push_out(self, max_iters: int = 4) -> bool:
        """Move the robot out of any obstacle it overlaps; True if it did.

        Driving by velocity override leaves pymunk's soft contacts a little
        penetration each substep that accumulates; resolving the overlap by
        position keeps the disc out of walls to within floating-point error.
        """
        pushed = False
        for _ in range(max_iters):
            moved = False
            for info in self.space.shape_query(self.shape):
                cps = info.contact_point_set
                depth = min((pt.distance for pt in cps.points), default=0.0)
                if depth < 0:
                    self.body.position = self.body.position + cps.normal * depth
                    moved = True
            if not moved:
                break
            pushed = True
        if pushed:
            self.space.reindex_shapes_for_body(self.body)
        return pushed


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
