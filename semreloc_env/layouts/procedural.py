"""A procedural layout generator: rooms on both sides of a corridor, furnished, from a seed."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

# A class swap that keeps footprints (used by symmetric layouts): same shape, other class.
_TWIN_CLASS = {"door": "cabinet", "cabinet": "door", "chair": "trash_bin", "trash_bin": "chair"}


@dataclass(frozen=True)
class ProceduralParams:
    """Knobs of :func:`procedural_layout` (metres).

    Attributes:
        rooms_per_side: inclusive range of the number of rooms on each corridor side.
        room_width_m: range of room widths along the corridor.
        room_depth_m: range of room depth (away from the corridor).
        corridor_width_m: range of corridor width.
        doorway_m: doorway width.
        objects_per_room: inclusive range of furniture pieces per room.
        symmetric: make the walls and furniture footprints invariant under a half
            turn about the centre, with furniture classes swapped between the
            twins, so lidar cannot tell the halves apart and semantics can.
    """

    rooms_per_side: tuple[int, int] = (2, 4)
    room_width_m: tuple[float, float] = (3.0, 5.0)
    room_depth_m: tuple[float, float] = (3.0, 4.5)
    corridor_width_m: tuple[float, float] = (1.6, 2.4)
    doorway_m: float = 1.0
    objects_per_room: tuple[int, int] = (1, 3)
    symmetric: bool = False


def _room_furniture(rng: np.random.Generator, x0: float, x1: float, depth: float, door_x: float, n: int) -> list:
    """Furniture for a south room ``[x0, x1] x [0, depth]`` whose doorway is centred at ``door_x``."""
    placed: list[tuple[float, float, float, float]] = []
    out = []
    for _ in range(n):
        for _attempt in range(30):
            cls = str(rng.choice(["chair", "trash_bin", "cabinet", "door"]))
            if cls in ("cabinet", "door"):  # against the back (outer) wall
                w = float(rng.uniform(0.8, 1.4)) if cls == "cabinet" else 1.0
                h = 0.6 if cls == "cabinet" else 0.1
                cx = float(rng.uniform(x0 + w / 2 + 0.05, x1 - w / 2 - 0.05))
                cy = h / 2
            else:
                w = h = 0.5 if cls == "chair" else 0.4
                cx = float(rng.uniform(x0 + 0.8, x1 - 0.8))
                cy = float(rng.uniform(0.8, depth - 1.2))
                if abs(cx - door_x) < 1.2 and cy > depth - 1.6:
                    continue  # keep the doorway clear
            box = (cx - w / 2 - 0.6, cx + w / 2 + 0.6, cy - h / 2 - 0.6, cy + h / 2 + 0.6)
            if any(not (box[1] < p[0] or p[1] < box[0] or box[3] < p[2] or p[3] < box[2]) for p in placed):
                continue
            placed.append((cx - w / 2, cx + w / 2, cy - h / 2, cy + h / 2))
            out.append({"class": cls, "center": [cx, cy], "size": [w, h]})
            break
    return out


def _widths_summing_to(rng: np.random.Generator, length: float, width_range: tuple[float, float]) -> np.ndarray:
    """Room widths within ``width_range`` that add up to ``length`` (as many rooms as fit)."""
    lo, hi = width_range
    n = int(rng.integers(math.ceil(length / hi - 1e-9), math.floor(length / lo + 1e-9) + 1))
    w = rng.uniform(lo, hi, size=n)
    w *= length / w.sum()
    if w.min() < lo or w.max() > hi:  # the rescaling pushed one out of range: equal widths fit
        w = np.full(n, length / n)
    return w


def procedural_layout(rng: np.random.Generator, params: ProceduralParams | None = None) -> dict:
    """Generate a furnished corridor-and-rooms layout (dict form) from ``rng``.

    The same generator state gives the same layout. Validate it with
    :func:`semreloc_env.layouts.layout_from_dict` (``get_layout`` does).
    """
    p = params or ProceduralParams()
    n = int(rng.integers(p.rooms_per_side[0], p.rooms_per_side[1] + 1))
    south_w = rng.uniform(*p.room_width_m, size=n)
    length = float(south_w.sum())
    depth = float(rng.uniform(*p.room_depth_m))
    corridor = float(rng.uniform(*p.corridor_width_m))
    height = 2 * depth + corridor
    south_x = np.concatenate([[0.0], np.cumsum(south_w)])
    if p.symmetric:
        north_x = length - south_x[::-1]
    else:
        north_x = np.concatenate([[0.0], np.cumsum(_widths_summing_to(rng, length, p.room_width_m))])
        north_x[-1] = length
    half = p.doorway_m / 2

    def doors(xs):
        return [float(rng.uniform(a + half + 0.3, b - half - 0.3)) for a, b in zip(xs[:-1], xs[1:])]

    south_doors = doors(south_x)
    north_doors = [length - d for d in south_doors[::-1]] if p.symmetric else doors(north_x)

    def wall_with_gaps(y, gaps):
        xs = [0.0] + [v for g in gaps for v in (g - half, g + half)] + [length]
        return [[[xs[i], y], [xs[i + 1], y]] for i in range(0, len(xs), 2)]

    walls = wall_with_gaps(depth, south_doors) + wall_with_gaps(depth + corridor, north_doors)
    walls += [[[x, 0.0], [x, depth]] for x in south_x[1:-1]]
    walls += [[[x, depth + corridor], [x, height]] for x in north_x[1:-1]]

    objects = []
    for a, b, d in zip(south_x[:-1], south_x[1:], south_doors):
        objects += _room_furniture(
            rng, a, b, depth, d, int(rng.integers(p.objects_per_room[0], p.objects_per_room[1] + 1))
        )
    if p.symmetric:
        objects += [
            {
                "class": _TWIN_CLASS[o["class"]],
                "center": [length - o["center"][0], height - o["center"][1]],
                "size": o["size"],
            }
            for o in list(objects)
        ]
    else:
        for a, b, d in zip(north_x[:-1], north_x[1:], north_doors):
            k = int(rng.integers(p.objects_per_room[0], p.objects_per_room[1] + 1))
            for o in _room_furniture(rng, length - b, length - a, depth, length - d, k):
                objects.append({**o, "center": [length - o["center"][0], height - o["center"][1]]})
    return {
        "name": "procedural_sym" if p.symmetric else "procedural",
        "outer": [[0.0, 0.0], [length, 0.0], [length, height], [0.0, height]],
        "walls": walls,
        "objects": objects,
    }
