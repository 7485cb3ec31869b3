"""Scenarios that change the world after mapping (paper 004's "environment changed" case)."""

from __future__ import annotations

import numpy as np

from .layouts import Layout
from .world import build_world

SCENARIOS = ("nominal", "changed")


def changed_obstacles(layout: Layout, seed: int = 0, n: int = 6, size_m: tuple[float, float] = (0.4, 0.8)) -> list:
    """``n`` box obstacles ``(4, 2)`` placed in free space, absent from any map of ``layout``.

    Deterministic in ``seed``. A box's centre is at least half its longer side + 0.7 m
    from every wall and object edge, and 1.5 m from the other boxes' centres, so the
    robot can usually drive around it (a corner may come to about 0.5 m of a wall).
    """
    rng = np.random.default_rng([seed, 4004])
    world = build_world(layout)
    boxes: list[np.ndarray] = []
    centres: list[np.ndarray] = []
    for _ in range(2000):
        if len(boxes) == n:
            break
        try:
            c = world.sample_free_pose(rng, margin_m=0.5)[:2]
        except ValueError:
            raise ValueError(
                f'scenario "changed": layout {layout.name!r} has no place for its unmapped obstacles (a free place '
                f'with 0.5 m to spare around the robot\'s disc); use the scenario "nominal" or a roomier layout'
            ) from None
        if any(np.linalg.norm(c - o) < 1.5 for o in centres):
            continue
        w, h = rng.uniform(*size_m, size=2)
        if world.clearance(c) < max(w, h) / 2 + 0.7:
            continue
        boxes.append(c + np.array([[-w, -h], [w, -h], [w, h], [-w, h]]) / 2)
        centres.append(c)
    return boxes
