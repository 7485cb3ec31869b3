"""Drawing of worlds, scans and beliefs with matplotlib; imported lazily by the envs.

Colours of the semantic classes follow paper 004: door cyan, chair green,
trash bin red, cabinet blue.
"""

from __future__ import annotations

import math
import time
import warnings
from typing import Any

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Circle, Patch, Polygon

from .layouts import CLASS_NAMES, Layout

CLASS_COLORS = {"door": "#00c8c8", "chair": "#20a020", "trash_bin": "#e02020", "cabinet": "#2040e0"}
"""Paper 004's colours per class."""


PARTICLE_COLOR = "#aa00aa"
"""Particles: translucent magenta arrows."""
ESTIMATE_COLOR = "#8c564b"
"""The filter's estimate: a brown dashed circle (the true pose is a solid black one)."""
LIDAR_COLOR = "#ff9900"


def class_color(label: int) -> str:
    """Colour of scan label ``label`` (``0``: grey)."""
    return CLASS_COLORS[CLASS_NAMES[label - 1]] if label > 0 else "#999999"


def draw_layout(ax, layout: Layout, extra_obstacles=()) -> None:
    """Walls in black, blocks filled dark grey, objects filled in their class colour, extra obstacles hatched grey."""
    for block in layout.blocks:
        ax.add_patch(Polygon(block, closed=True, facecolor="#555555", edgecolor="none"))
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


def draw_scans(ax, pose: np.ndarray, lidar=None, semantic=None) -> list:
    """Lidar beams (thin orange) and semantic beams (class colours; unlabelled grey); returns the artists."""
    artists = []
    if lidar is not None:
        ok = lidar.valid
        ends = _beam_ends(pose, lidar.ranges[ok], lidar.angles[ok])
        segs = np.stack([np.broadcast_to(pose[:2], ends.shape), ends], axis=1)
        artists.append(ax.add_collection(LineCollection(segs, colors=LIDAR_COLOR, linewidths=0.5, alpha=0.6)))
        artists += ax.plot(ends[:, 0], ends[:, 1], ".", color="#ff6600", ms=2)
    if semantic is not None:  # a labelled beam is drawn even at range_max_m (its noisy range clipped there)
        ok = (semantic.ranges < semantic.range_max_m) | (semantic.labels > 0)
        ends = _beam_ends(pose, semantic.ranges[ok], semantic.angles[ok])
        segs = np.stack([np.broadcast_to(pose[:2], ends.shape), ends], axis=1)
        colors = [class_color(int(k)) for k in semantic.labels[ok]]
        widths = [1.5 if k > 0 else 0.4 for k in semantic.labels[ok]]
        artists.append(ax.add_collection(LineCollection(segs, colors=colors, linewidths=widths, alpha=0.9)))
    return artists


def draw_pose(
    ax, pose: np.ndarray, color: str, radius: float = 0.2, label: str | None = None, linestyle: str = "-"
) -> list:
    """A circle with a heading tick; returns the artists."""
    circle = ax.add_patch(Circle(pose[:2], radius, fill=False, color=color, lw=1.5, ls=linestyle, label=label))
    tick = ax.plot(
        [pose[0], pose[0] + 1.5 * radius * np.cos(pose[2])],
        [pose[1], pose[1] + 1.5 * radius * np.sin(pose[2])],
        color=color,
        lw=1.5,
        ls=linestyle,
    )
    return [circle, *tick]


def draw_particles(ax, particles: np.ndarray, max_points: int = 3000) -> list:
    """Every k-th particle as an arrow, ``k = max(1, n // max_points)`` (so up to about ``1.5 * max_points``);
    returns the artists."""
    p = particles[:: max(1, len(particles) // max_points)]
    arrows = ax.quiver(
        p[:, 0], p[:, 1], np.cos(p[:, 2]), np.sin(p[:, 2]), color=PARTICLE_COLOR, alpha=0.35, scale=60, width=0.002
    )
    return [arrows]


def backend_shows_windows() -> bool:
    """Whether pyplot's current backend is an interactive one (Agg and the file backends show no window)."""
    import matplotlib.pyplot as plt

    try:
        from matplotlib.backends import BackendFilter, backend_registry  # matplotlib >= 3.9
    except ImportError:  # older matplotlib
        from matplotlib.rcsetup import non_interactive_bk as still
    else:
        still = backend_registry.list_builtin(BackendFilter.NON_INTERACTIVE)
    return plt.get_backend().lower() not in {b.lower() for b in still}


MIN_WIDTH_IN = 6.0
"""Narrowest frame (inches; 480 px at the default dpi): the title's and the legend's room around a tall,
narrow layout."""
LEGEND_IN = 0.45
"""Height (inches) below the map for the legend (`legend_handles`)."""
TITLE_IN = 0.3
"""Height (inches) above the map for the title."""


def legend_handles() -> list:
    """The legend's entries: true pose, estimate, particles, lidar, and the classes' colours (objects and
    semantic beams; grey: a camera beam on no object)."""
    return [
        Line2D([], [], color="k", lw=1.5, label="true pose"),
        Line2D([], [], color=ESTIMATE_COLOR, lw=1.5, ls="--", label="estimate"),
        Line2D([], [], color=PARTICLE_COLOR, lw=1.0, alpha=0.6, label="particles"),
        Line2D([], [], color=LIDAR_COLOR, lw=1.0, label="lidar"),
        *(Patch(color=CLASS_COLORS[name], label=name.replace("_", " ")) for name in CLASS_NAMES),
        Line2D([], [], color=class_color(0), lw=1.0, label="no class"),
    ]


class Renderer:
    """Draws env states to RGB arrays (``rgb_array``) or a window (``human``).

    The static layout (walls, objects, extra obstacles) is drawn once and cached as a pixel
    background; each frame restores it and draws only what moves (particles, scans, landmarks,
    poses, title). The background is redrawn only when the extra obstacles change.

    Args:
        layout: the world drawn.
        human: draw into a pyplot window (paced to ``fps``) instead of an off-screen canvas.
        dpi: pixels per inch of the figure (the map 8 in on its longer side, `TITLE_IN` above it for the title,
            `LEGEND_IN` below it for the legend, 0.1 in on the sides, at least `MIN_WIDTH_IN` wide: a frame's
            size depends on the layout's aspect, and is fixed while the layout is; its height and width in
            pixels are even).
        fps: frames per second in ``human`` mode: `draw` sleeps until ``1 / fps`` s have passed
            since the previous frame (None: no pacing). On a backend that shows no window (Agg, as on a
            machine without a display) ``human`` mode warns once and neither shows nor paces frames.
    """

    def __init__(self, layout: Layout, human: bool = False, dpi: int = 80, fps: float | None = None):
        if fps is not None and not fps > 0:
            raise ValueError(f"fps must be > 0 or None, got {fps!r}")
        self.layout = layout
        self.human = human
        self.fps = fps
        x0, x1, y0, y1 = layout.bounds()
        scale = 8.0 / max(x1 - x0, y1 - y0)
        # at least MIN_WIDTH_IN wide, so that the title fits above a tall, narrow layout
        size = (max((x1 - x0) * scale + 0.2, MIN_WIDTH_IN), (y1 - y0) * scale + TITLE_IN + LEGEND_IN + 0.05)
        # even pixel counts: video encoders' 4:2:0 chroma (what browsers and players decode) needs them
        size = tuple((2 * math.ceil(v * dpi / 2) + 0.25) / dpi for v in size)
        self._was_interactive = None
        self.shows_window = False
        """Whether `draw` shows frames in a window (``human`` mode on an interactive backend)."""
        if human:  # a window: pyplot manages it
            import matplotlib
            import matplotlib.pyplot as plt

            self._was_interactive = matplotlib.is_interactive()
            plt.ion()
            self.fig, self.ax = plt.subplots(figsize=size, dpi=dpi)
            self.shows_window = backend_shows_windows()
            if not self.shows_window:
                warnings.warn(
                    f"render_mode='human': matplotlib's backend {plt.get_backend()!r} shows no window (no display?), "
                    "so frames are drawn but neither shown nor paced; use render_mode='rgb_array' for the frames, "
                    "or an interactive backend (MPLBACKEND)",
                    UserWarning,
                    stacklevel=2,
                )
            with warnings.catch_warnings():  # matplotlib's own warning says the same, less clearly
                warnings.filterwarnings("ignore", message=".*non-interactive.*", category=UserWarning)
                self.fig.show()
        else:  # off-screen: a figure pyplot does not track, freed with the renderer
            self.fig = Figure(figsize=size, dpi=dpi)
            FigureCanvasAgg(self.fig)
            self.ax = self.fig.add_subplot()
        self._background = None
        self._background_key: tuple | None = None
        self._dynamic: list = []
        self._last_frame_t: float | None = None
        self.background_draws = 0
        """How often the static background was drawn (1 unless the extra obstacles changed)."""

    def _draw_background(self, extra_obstacles) -> None:
        ax = self.ax
        ax.clear()
        draw_layout(ax, self.layout, extra_obstacles)
        ax.set_xticks([])
        ax.set_yticks([])
        ax.set_title(" ", fontsize=9)  # reserves the title's room in the layout
        h, w = self.fig.get_figheight(), self.fig.get_figwidth()
        self.fig.subplots_adjust(left=0.1 / w, right=1 - 0.1 / w, top=1 - TITLE_IN / h, bottom=(LEGEND_IN + 0.05) / h)
        if not self.fig.legends:
            self.fig.legend(
                handles=legend_handles(), loc="lower center", ncol=5, fontsize=7, frameon=False, handlelength=1.5
            )
        self.fig.canvas.draw()
        self._background = self.fig.canvas.copy_from_bbox(self.fig.bbox)
        self.background_draws += 1

    def draw(self, state: dict[str, Any]) -> np.ndarray:
        """Draw one state: layout, particles (magenta), scans, landmarks (crosses), true pose (solid black),
        estimate (dashed brown); the legend is part of the background."""
        ax = self.ax
        for artist in self._dynamic:
            artist.remove()
        self._dynamic = []
        extra = state.get("extra_obstacles", ())
        key = (id(state["layout"]), tuple(np.asarray(p, dtype=float).tobytes() for p in extra))
        if key != self._background_key:
            self.layout = state["layout"]
            self._draw_background(extra)
            self._background_key = key
        dynamic = []
        if state.get("particles") is not None:
            dynamic += draw_particles(ax, state["particles"])
        dynamic += draw_scans(ax, state["pose"], state.get("lidar"), state.get("semantic"))
        if state.get("landmarks") is not None:  # {"means": (M, 2), "classes": (M,) labels}: crosses in class colours
            lm = state["landmarks"]
            for (x, y), k in zip(np.asarray(lm["means"]).reshape(-1, 2), lm["classes"]):
                dynamic += ax.plot(x, y, "x", color=class_color(int(k)), ms=8, mew=2)
        radius = float(state.get("robot_radius_m", 0.2))
        dynamic += draw_pose(ax, state["pose"], "k", radius=radius, label="true pose")
        if state.get("estimate") is not None:
            est = np.asarray(state["estimate"])
            dynamic += draw_pose(ax, est, ESTIMATE_COLOR, radius=radius, label="estimate", linestyle="--")
        self._dynamic = dynamic
        ax.title.set_text(state.get("title") or " ")
        canvas = self.fig.canvas
        canvas.restore_region(self._background)
        for artist in [*dynamic, ax.title]:
            ax.draw_artist(artist)
        frame = np.asarray(canvas.buffer_rgba())[..., :3].copy()
        if self.human:
            canvas.blit(self.fig.bbox)
            canvas.flush_events()
            self._pace()
        return frame

    def _pace(self) -> None:
        if not self.shows_window:  # nobody is watching: no reason to wait
            return
        now = time.monotonic()
        if self.fps is not None and self._last_frame_t is not None:
            wait = 1.0 / self.fps - (now - self._last_frame_t)
            if wait > 0:
                time.sleep(wait)
                now += wait
        self._last_frame_t = now

    def close(self) -> None:
        if self.human:
            import matplotlib.pyplot as plt

            plt.close(self.fig)
            if self._was_interactive is False:  # human mode turned pyplot's interactive mode on for the process
                plt.ioff()
                self._was_interactive = None
