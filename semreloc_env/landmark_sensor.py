"""Range-bearing landmark observations from the semantic pseudo-laser (for landmark SLAM, paper 000).

Each detected object is a *labelled contiguous run* of the camera's beams (the
`SemanticCamera` labels the nearest run of every object it
detects). One run gives one observation ``(range m, bearing rad)`` in the robot frame, its class
label, and -- for tests and known-association SLAM -- the index of the true object hit.

How a run becomes a point (`LandmarkSensorParams`):

1. Runs are split where the label changes or where consecutive ranges jump by more than
   ``split_jump_m`` (two same-class objects side by side in the image are two detections).
2. ``point="mean"`` (default): the mean of the run's beam end points; ``point="middle"``: the end
   point of the run's middle beam (the mean of the two middle ones for an even run).
3. That surface point is pushed further along its viewing ray by the class's ``class_depth_m``
   (a class-size prior, "half the typical depth" of the class), so the landmark approximates the
   object's centre, which does not depend on the viewpoint -- a surface point does. Set all depths to
   0 to observe the surface point itself.

The detector's noise, misses, wrong classes and false positives come from the camera; this module
adds nothing random. Runs with fewer than ``min_beams`` beams are dropped (most false positives are
1-4 beams); ``skip_fov_edges`` drops runs touching the first or last beam (objects cut by the image
border give biased points). The defaults were chosen on measurements (docs/semslam.md): on the lab,
the observations' residuals against the true object centroids seen from the true pose have range
mean -0.05 m and std 0.13 m (per object from 0.02 m to -0.28 m: a cabinet seen end-on) and bearing std 0.03 rad;
keeping border runs raises the bearing std to 0.2 rad.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from filters.pose import wrap_angle
from filters.robot_data.scans import SemanticScan

from .config import MAX_RANGE_M
from .layouts import CLASS_NAMES
from .sensors import SemanticCamera
from .world import World

POINTS = ("mean", "middle")


@dataclass(frozen=True)
class LandmarkSensorParams:
    """How labelled runs become landmark observations (see the module docstring).

    Attributes:
        point: ``"mean"`` of the run's end points or ``"middle"`` beam's end point.
        class_depth_m: metres added to the range along the viewing ray, per class in
            `CLASS_NAMES` order (door, chair, trash_bin, cabinet).
        split_jump_m: a range jump above this between neighbouring beams splits a run.
        min_beams: runs with fewer beams are dropped.
        skip_fov_edges: drop runs that touch the first or last beam of the field of view.
    """

    point: str = "mean"
    class_depth_m: tuple[float, ...] = (0.05, 0.25, 0.2, 0.3)
    split_jump_m: float = 0.3
    min_beams: int = 2
    skip_fov_edges: bool = True

    def __post_init__(self) -> None:
        if self.point not in POINTS:
            raise ValueError(f"LandmarkSensorParams.point must be one of {POINTS}, got {self.point!r}")
        depth = tuple(float(d) for d in self.class_depth_m)
        if len(depth) != len(CLASS_NAMES) or not all(0 <= d <= MAX_RANGE_M for d in depth):
            raise ValueError(
                f"LandmarkSensorParams.class_depth_m needs {len(CLASS_NAMES)} values in [0, {MAX_RANGE_M:g}] m "
                f"({', '.join(CLASS_NAMES)}), got {self.class_depth_m!r}"
            )
        object.__setattr__(self, "class_depth_m", depth)
        if not (self.split_jump_m > 0):
            raise ValueError(f"LandmarkSensorParams.split_jump_m must be > 0, got {self.split_jump_m!r}")
        if int(self.min_beams) != self.min_beams or self.min_beams < 1:
            raise ValueError(f"LandmarkSensorParams.min_beams must be an integer >= 1, got {self.min_beams!r}")


def labelled_runs(scan: SemanticScan, split_jump_m: float) -> list[tuple[int, int]]:
    """``[(start, stop), ...]`` beam index ranges of the labelled runs of ``scan`` (see the module docstring)."""
    labels = scan.labels
    runs: list[tuple[int, int]] = []
    start = None
    for i in range(labels.size + 1):
        cut = (
            i == labels.size
            or labels[i] == 0
            or (
                start is not None
                and (labels[i] != labels[i - 1] or abs(scan.ranges[i] - scan.ranges[i - 1]) > split_jump_m)
            )
        )
        if cut and start is not None:
            runs.append((start, i))
            start = None
        if i < labels.size and labels[i] != 0 and start is None:
            start = i
    return runs


def extract_landmarks(
    scan: SemanticScan, params: LandmarkSensorParams | None = None, beam_objects: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Landmark observations of one semantic scan.

    Args:
        scan: the camera's labelled scan (robot-frame beam angles, ranges in m).
        params: extraction settings (default `LandmarkSensorParams`).
        beam_objects: optional ``(B,)`` true object index per beam (``SemanticCamera.true_hits``; -1 none).

    Returns:
        ``z (K, 2)`` float64 rows ``(range m, bearing rad in [-pi, pi))``, ``classes (K,)`` int64 labels
        ``1..4``, ``true_ids (K,)`` int64: the object index most beams of the run hit (ties: the lowest),
        ``-1`` for a run on no object (a false positive on a wall) or when ``beam_objects`` is None.
        Observations are ordered by their first beam.
    """
    p = params if params is not None else LandmarkSensorParams()
    if beam_objects is not None:
        beam_objects = np.asarray(beam_objects, dtype=np.int64)
        if beam_objects.shape != scan.ranges.shape:
            raise ValueError(f"beam_objects must have shape {scan.ranges.shape}, got {beam_objects.shape}")
    z, classes, ids = [], [], []
    last = scan.labels.size - 1
    for a, b in labelled_runs(scan, p.split_jump_m):
        if b - a < p.min_beams or (p.skip_fov_edges and (a == 0 or b - 1 == last)):
            continue
        r, ang = scan.ranges[a:b], scan.angles[a:b]
        ends = np.stack([r * np.cos(ang), r * np.sin(ang)], axis=1)
        if p.point == "mean":
            pt = ends.mean(axis=0)
        else:
            mid = (a + b - 1) / 2.0
            pt = ends[[int(np.floor(mid)) - a, int(np.ceil(mid)) - a]].mean(axis=0)
        label = int(scan.labels[a])
        rng_m = float(np.hypot(*pt))
        z.append((rng_m + p.class_depth_m[label - 1], float(wrap_angle(np.arctan2(pt[1], pt[0])))))
        classes.append(label)
        if beam_objects is None:
            ids.append(-1)
        else:
            vals, counts = np.unique(beam_objects[a:b], return_counts=True)
            ids.append(int(vals[np.argmax(counts)]))
    return (
        np.asarray(z, dtype=np.float64).reshape(-1, 2),
        np.asarray(classes, dtype=np.int64),
        np.asarray(ids, dtype=np.int64),
    )


class LandmarkSensor:
    """The semantic camera read as landmark observations: ``z, classes, true_ids = sensor.read(world, pose, scan)``.

    ``scan`` is the camera's reading at ``pose``; the true object per beam comes from the camera's
    noise-free `true_hits` (no random draws).
    """

    def __init__(self, camera: SemanticCamera, params: LandmarkSensorParams | None = None):
        self.camera = camera
        self.params = params if params is not None else LandmarkSensorParams()

    def read(self, world: World, pose: np.ndarray, scan: SemanticScan) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        _, beam_objects = self.camera.true_hits(world, pose)
        return extract_landmarks(scan, self.params, beam_objects)
