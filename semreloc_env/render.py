"""Drawing of worlds, scans and beliefs with matplotlib; imported lazily by the envs.

Colours of the semantic classes follow paper 004: door cyan, chair green,
trash bin red, cabinet blue.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure
from matplotlib.patches import Circle, Polygon

from .layouts import CLASS_NAMES, Layout

CLASS_COLORS = {"door": "#00c8c8", "chair": "#20a020", "trash_bin": "#e02020", "cabinet": "#2040e0"}
"""Paper 004's colours per class."""


def class_color(label: int) -> str:
    """Colour of scan label ``label`` (``0``: grey)."""
    return CLASS_COLORS[CLASS_NAMES[label - 1]] if label > 0 else "#999999"


def draw_layout(ax, layout: Layout, extra_obstacles=()) -> None:
    """Walls in black, objects filled in their class colour, extra obstacles hatched grey."""
    ax.add_collection(LineCollection(layout.wall_segments(), colors="k", linewidths=2))
    for obj in layout.objects:
        ax.add_patch(Polygon(obj.polygon, closed=True, color=CLASS_COLORS[obj.cls], alpha=0.8))
    for poly in extra_obstacles:
        ax.add_patch(Polygon(np.asarray(poly), closed=True, facecolor="#777777", hatch="//", edgecolor="k"))
    x0, x1, y0, y1 = layout.bounds()
    ax.set_xlim(x0 - 0.3, x1 + 0.3)
    ax.set_ylim(y0 - 0.3, y1 + 0.3)
    ax.set_aspect("equal")


def _beam_ends(pose: np.ndarray, ranges: np.ndarray, angles: np.ndarray) -> np.ndarray:
    a = pose[2] + angles
    return np.stack([pose[0] + ranges * np.cos(a), pose[1] + ranges * np.sin(a)], axis=1)


def draw_scans(ax, pose: np.ndarray, lidar=None, semantic=None) -> None:
    """Lidar beams (thin orange) and semantic beams (class colours; unlabelled grey)."""
    if lidar is not None:
        ok = lidar.valid
        ends = _beam_ends(pose, lidar.ranges[ok], lidar.angles[ok])
        segs = np.stack([np.broadcast_to(pose[:2], ends.shape), ends], axis=1)
        ax.add_collection(LineCollection(segs, colors="#ff9900", linewidths=0.5, alpha=0.6))
        ax.plot(ends[:, 0], ends[:, 1], ".", color="#ff6600", ms=2)
    if semantic is not None:
        ok = semantic.ranges < semantic.range_max_m
        ends = _beam_ends(pose, semantic.ranges[ok], semantic.angles[ok])
        segs = np.stack([np.broadcast_to(pose[:2], ends.shape), ends], axis=1)
        colors = [class_color(int(k)) for k in semantic.labels[ok]]
        widths = [1.5 if k > 0 else 0.4 for k in semantic.labels[ok]]
        ax.add_collection(LineCollection(segs, colors=colors, linewidths=widths, alpha=0.9))


def draw_pose(ax, pose: np.ndarray, color: str, radius: float = 0.2, label: str | None = None) -> None:
    ax.add_patch(Circle(pose[:2], radius, fill=False, color=color, lw=1.5, label=label))
    ax.plot(
        [pose[0], pose[0] + 1.5 * radius * np.cos(pose[2])],
        [pose[1], pose[1] + 1.5 * radius * np.sin(pose[2])],
        color=color,
        lw=1.5,
    )


def draw_particles(ax, particles: np.ndarray, max_points: int = 3000) -> None:
    p = particles[:: max(1, len(particles) // max_points)]
    ax.quiver(p[:, 0], p[:, 1], np.cos(p[:, 2]), np.sin(p[:, 2]), color="#aa00aa", alpha=0.35, scale=60, width=0.002)


class Renderer:
    """Draws env states to RGB arrays (``rgb_array``) or a window (``human``)."""

    def __init__(self, layout: Layout, human: bool = False, dpi: int = 80):
        self.layout = layout
        self.human = human
        x0, x1, y0, y1 = layout.bounds()
        scale = 8.0 / max(x1 - x0, y1 - y0)
        size = ((x1 - x0) * scale + 0.4, (y1 - y0) * scale + 0.4)
        if human:  # a window: pyplot manages it
            import matplotlib.pyplot as plt

            plt.ion()
            self.fig, self.ax = plt.subplots(figsize=size, dpi=dpi)
            self.fig.show()
        else:  # off-screen: a figure pyplot does not track, freed with the renderer
            self.fig = Figure(figsize=size, dpi=dpi)
            FigureCanvasAgg(self.fig)
            self.ax = self.fig.add_subplot()

    def draw(self, state: dict[str, Any]) -> np.ndarray:
        """Draw one state: layout, particles, scans, landmarks (crosses), true pose (black), estimate (magenta)."""
        ax = self.ax
        ax.clear()
        draw_layout(ax, state["layout"], state.get("extra_obstacles", ()))
        if state.get("particles") is not None:
            draw_particles(ax, state["particles"])
        draw_scans(ax, state["pose"], state.get("lidar"), state.get("semantic"))
        if state.get("landmarks") is not None:  # {"means": (M, 2), "classes": (M,) labels}: crosses in class colours
            lm = state["landmarks"]
            for (x, y), k in zip(np.asarray(lm["means"]).reshape(-1, 2), lm["classes"]):
                ax.plot(x, y, "x", color=class_color(int(k)), ms=8, mew=2)
        draw_pose(ax, state["pose"], "k", label="true pose")
        if state.get("estimate") is not None:
            draw_pose(ax, np.asarray(state["estimate"]), "#aa00aa", label="estimate")
        if state.get("title"):
            ax.set_title(state["title"], fontsize=9)
        ax.set_xticks([])
        ax.set_yticks([])
        self.fig.tight_layout()
        self.fig.canvas.draw()
        frame = np.asarray(self.fig.canvas.buffer_rgba())[..., :3].copy()
        if self.human:
            import matplotlib.pyplot as plt

            plt.pause(0.001)
        return frame

    def close(self) -> None:
        if self.human:
            import matplotlib.pyplot as plt

            plt.close(self.fig)
