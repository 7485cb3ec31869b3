"""Look-alike places: the pose elsewhere in a world whose all-round view is most like a given pose's.

A kidnapping to a random place is rarely hard for the relocalizer (the scans give it away at once); the hard
case is a teleport to a place that looks the same, which outside testers made by hand for each layout (the
image of the pose under the layout's symmetry). `lookalike_pose` finds such a place in any world: it compares
the true all-round view (ranges of the world's walls, objects and blocks, and the class of each object hit
within the camera's range) at the pose with the views at a few thousand free places, over every heading at once
(a circular cross-correlation), and refines the best few.

The view is the world's exact geometry, not a sensor reading: no noise, no dropouts, the lidar's full circle
and class labels all round (the camera sees 70 deg at a time; a robot that turns sees the rest), also of objects
nearer than the camera's minimum range. Views are compared on rays at fixed world angles (1 deg apart by default), so
a heading is found to the ray spacing and ``mismatch_m`` is that of the views at the found heading rounded to it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from filters.numbers import is_int, is_real

__all__ = [
    "KIDNAP_MIN_DISTANCE_M",
    "Lookalike",
    "NoPlaceError",
    "all_round_views",
    "exact_views",
    "lookalike_kidnap",
    "lookalike_pose",
    "view_mismatch",
]

KIDNAP_MIN_DISTANCE_M = 3.0
"""How far from the pose a look-alike kidnapping (`lookalike_kidnap`) goes at least (m), or half, a quarter, ... of
it down to 0.375 m where no free place lies that far (a cluttered room of 3 m x 2.5 m has none 3 m from most
poses)."""


class NoPlaceError(ValueError):
    """`lookalike_pose` found no free place as far from the pose as asked."""


@dataclass(frozen=True)
class Lookalike:
    """What `lookalike_pose` found.

    Attributes:
        pose: ``(3,)`` ``[x, y, theta]`` (m, rad in ``[-pi, pi)``).
        mismatch_m: root mean square, over the view's beams, of the range difference (m) with a beam whose
            class differs counted as ``label_weight_m``: 0 for a place that looks exactly the same.
        distance_m: distance from the given pose (m).
    """

    pose: np.ndarray
    mismatch_m: float
    distance_m: float


def exact_views(
    world, positions: np.ndarray, angles: np.ndarray, max_range_m: float, camera_range_m: float
) -> tuple[np.ndarray, np.ndarray]:
    """The exact views from ``positions`` ``(R, 2)`` (m) along world-frame ``angles`` ``(R, B)`` (rad).

    Returns:
        ``ranges`` ``(R, B)`` float64 (m; ``max_range_m`` where nothing is hit) and ``labels`` ``(R, B)`` int64:
        the class label (1..4) of the object a ray hits within ``camera_range_m``, else 0.
    """
    xy = np.asarray(positions, dtype=np.float64).reshape(-1, 2)
    ranges, hit = world.scene.cast_many(xy, angles, max_range_m)
    object_labels = np.array([0, *(o.label for o in world.layout.objects)], dtype=np.int64)
    owner = np.where(hit >= 0, world.scene.owner[np.maximum(hit, 0)], -1)  # -1: a wall, a block or nothing
    labels = object_labels[np.where(owner >= 0, owner + 1, 0)]
    labels[ranges >= camera_range_m] = 0
    return ranges, labels


def all_round_views(
    world, positions: np.ndarray, max_range_m: float, camera_range_m: float, n_beams: int = 360
) -> tuple[np.ndarray, np.ndarray]:
    """`exact_views` from ``positions`` ``(R, 2)`` (m) on rays at the same world angles ``2 pi k / n_beams - pi``
    for every position: ``(R, n_beams)`` ranges and labels."""
    xy = np.asarray(positions, dtype=np.float64).reshape(-1, 2)
    angles = np.linspace(-math.pi, math.pi, n_beams, endpoint=False)
    return exact_views(world, xy, np.broadcast_to(angles, (len(xy), n_beams)), max_range_m, camera_range_m)


def _mismatch_by_shift(
    ref_r: np.ndarray, ref_l: np.ndarray, r: np.ndarray, lab: np.ndarray, n_classes: int, label_weight_m: float
) -> np.ndarray:
    """``(R, B)``: mean over beams of the squared view difference (m^2) of each view in ``r, lab`` ``(R, B)``
    against the reference view turned by every shift ``s`` (candidate beam ``k + s`` against reference beam ``k``)."""
    n = ref_r.size
    fa = np.conj(np.fft.rfft(ref_r))
    corr = np.fft.irfft(fa[None, :] * np.fft.rfft(r, axis=1), n=n, axis=1)
    sq = np.sum(ref_r**2) + np.sum(r**2, axis=1)[:, None] - 2.0 * corr
    same = np.zeros_like(sq)
    for c in range(n_classes + 1):
        a = (ref_l == c).astype(np.float64)
        if not a.any():
            continue
        b = (lab == c).astype(np.float64)
        same += np.fft.irfft(np.conj(np.fft.rfft(a))[None, :] * np.fft.rfft(b, axis=1), n=n, axis=1)
    return (np.maximum(sq, 0.0) + label_weight_m**2 * (n - same)) / n


def view_mismatch(
    world,
    pose,
    other,
    max_range_m: float = 8.0,
    camera_range_m: float = 4.5,
    n_beams: int = 360,
    label_weight_m: float = 2.0,
) -> float:
    """How unlike ``pose``'s all-round view ``other``'s is, in `lookalike_pose`'s measure (``mismatch_m``: m, 0
    for the same view), each seen from its own heading (``other``'s heading rounded to the views' beam spacing)."""
    p, q = (np.asarray(x, dtype=np.float64).reshape(3) for x in (pose, other))
    r, lab = all_round_views(world, np.stack([p[:2], q[:2]]), max_range_m, camera_range_m, n_beams)
    n_classes = max((o.label for o in world.layout.objects), default=0)
    cost = _mismatch_by_shift(r[0], lab[0], r[1:], lab[1:], n_classes, label_weight_m)[0]
    shift = round(math.remainder(q[2] - p[2], 2.0 * math.pi) * n_beams / (2.0 * math.pi)) % n_beams
    return math.sqrt(float(cost[shift]))


def lookalike_pose(
    world,
    pose,
    rng: np.random.Generator,
    *,
    min_distance_m: float = 3.0,
    max_range_m: float = 8.0,
    camera_range_m: float = 4.5,
    candidates: int = 3000,
    n_beams: int = 360,
    margin_m: float = 0.1,
    label_weight_m: float = 2.0,
    refine: int = 8,
) -> Lookalike:
    """The free pose at least ``min_distance_m`` from ``pose`` whose all-round view (`all_round_views`) differs
    least from ``pose``'s: ``candidates`` free places drawn uniformly with ``rng``, each at its best heading,
    then the ``refine`` best moved about by up to 0.25 m, then 0.05 m (40 draws each) where that fits better.

    Args:
        world: a `semreloc_env.world.World` (``env.unwrapped.world``).
        pose: ``[x, y, theta]`` (m, rad).
        max_range_m: how far the view's ranges reach (the lidar's range).
        camera_range_m: how far its classes reach (the camera's range).
        margin_m: room to spare around the robot's disc at the pose found (`World.free_points`).
        label_weight_m: a beam whose object class differs counts as this range difference.

    Raises:
        ValueError: bad arguments; `NoPlaceError` (a ValueError): no free place ``min_distance_m`` or more away
            among the draws.
    """
    p = np.asarray(pose, dtype=np.float64).reshape(-1)
    if p.shape != (3,) or not np.all(np.isfinite(p)):
        raise ValueError(f"pose must be three finite numbers [x, y, theta], got {pose!r:.80}")
    lengths = {"min_distance_m": min_distance_m, "max_range_m": max_range_m, "camera_range_m": camera_range_m,
               "margin_m": margin_m, "label_weight_m": label_weight_m}  # fmt: skip
    for name, v in lengths.items():
        if not (is_real(v) and math.isfinite(v) and v >= 0):
            raise ValueError(f"{name} must be a finite number >= 0, got {v!r:.60}")
    for name, v, least in (("candidates", candidates, 1), ("n_beams", n_beams, 8), ("refine", refine, 0)):
        if not is_int(v) or v < least:
            raise ValueError(f"{name} must be an integer >= {least}, got {v!r:.60}")
    ref_r, ref_l = all_round_views(world, p[None, :2], max_range_m, camera_range_m, n_beams)
    ref_r, ref_l = ref_r[0], ref_l[0]
    x0, x1, y0, y1 = world.layout.bounds()
    xy = rng.uniform((x0, y0), (x1, y1), size=(4 * candidates, 2))
    xy = xy[world.free_points(xy, margin_m) & (np.hypot(*(xy - p[:2]).T) >= min_distance_m)][:candidates]
    if not len(xy):
        raise NoPlaceError(
            f"no free place {min_distance_m} m or more from {p[:2].tolist()} among {4 * candidates} random draws"
        )
    n_classes = max((o.label for o in world.layout.objects), default=0)

    def best(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        r, lab = all_round_views(world, points, max_range_m, camera_range_m, n_beams)
        cost = _mismatch_by_shift(ref_r, ref_l, r, lab, n_classes, label_weight_m)
        shift = np.argmin(cost, axis=1)
        return cost[np.arange(len(points)), shift], shift

    cost, shift = best(xy)
    for i in np.argsort(cost)[:refine]:
        for step in (0.25, 0.05):
            around = xy[i] + rng.uniform(-step, step, size=(40, 2))
            around = around[world.free_points(around, margin_m) & (np.hypot(*(around - p[:2]).T) >= min_distance_m)]
            if len(around):
                c, s = best(around)
                j = int(np.argmin(c))
                if c[j] < cost[i]:
                    xy[i], cost[i], shift[i] = around[j], c[j], s[j]
    i = int(np.argmin(cost))
    theta = math.remainder(p[2] + 2.0 * math.pi * int(shift[i]) / n_beams, 2.0 * math.pi)
    theta = -math.pi if theta >= math.pi else theta
    distance = float(np.hypot(*(xy[i] - p[:2])))
    return Lookalike(np.array([xy[i, 0], xy[i, 1], theta]), math.sqrt(float(cost[i])), distance)


def lookalike_kidnap(world, pose, rng: np.random.Generator, *, max_range_m: float, camera_range_m: float) -> Lookalike:
    """Where a look-alike kidnapping of a robot at ``pose`` goes: `lookalike_pose` at least `KIDNAP_MIN_DISTANCE_M`
    away, or half as far, a quarter, ... down to 0.375 m where no free place lies that far. The target of the
    envs' reset option ``kidnap_pose="lookalike"`` and of ``evaluate_relocalizer``'s ``*_lookalike_kidnap`` rows.
    Each try draws from ``rng`` as it was given (its state is set back before a nearer try).

    Raises:
        NoPlaceError: no free place even 0.375 m away among the draws.
    """
    least = KIDNAP_MIN_DISTANCE_M
    state = rng.bit_generator.state
    while True:
        rng.bit_generator.state = state
        try:
            return lookalike_pose(
                world, pose, rng, min_distance_m=least, max_range_m=max_range_m, camera_range_m=camera_range_m
            )
        except NoPlaceError:
            if least < 0.5:
                raise
            least /= 2.0
