"""Simulated sensors, each a small class: ``reading = sensor.read(world, pose, rng)``.

* :class:`Lidar` — ranges with Gaussian noise and dropouts, cast against the world's segments.
* :class:`SemanticCamera` — the semantic pseudo-laser of paper 004 §2: per beam in
  the camera's field of view, the range to the nearest surface and the class of
  the object hit, through a detector with misses, wrong classes and false positives.
* :class:`Odometry` — the true motion increment through the rot1-trans-rot2 noise model.

All return :mod:`filters.robot_data.scans` containers or plain arrays, so filters never see the simulator.
"""

from __future__ import annotations

import math

import numpy as np

from filters.mapping.grid import NO_CLASS
from filters.motion.odometry import OdometryMotionConfig, OdometryMotionModel
from filters.robot_data.scans import LaserScan, SemanticScan

from .config import CameraParams, LidarParams
from .layouts import CLASS_NAMES
from .world import World


def beam_angles(n_beams: int, fov_rad: float) -> np.ndarray:
    """Robot-frame angles of ``n_beams`` evenly spaced over ``fov_rad``, centred on the heading.

    A full circle does not repeat its first beam.
    """
    if fov_rad >= 2 * np.pi - 1e-9:
        return -np.pi + 2 * np.pi * np.arange(n_beams) / n_beams
    if n_beams == 1:
        return np.zeros(1)
    return np.linspace(-fov_rad / 2, fov_rad / 2, n_beams)


class Lidar:
    """A planar lidar at the robot centre (see :class:`~semreloc_env.config.LidarParams`)."""

    def __init__(self, params: LidarParams):
        self.params = params
        self.angles = beam_angles(int(params.n_beams), params.fov_rad)

    def true_ranges(self, world: World, pose: np.ndarray) -> np.ndarray:
        """Noise-free ranges ``(B,)`` from ``pose``; ``range_max_m`` where nothing is hit."""
        ranges, _ = world.scene.cast(pose[:2], pose[2] + self.angles, self.params.range_max_m)
        return ranges

    def read(self, world: World, pose: np.ndarray, rng: np.random.Generator) -> LaserScan:
        """One noisy scan. Draws: B normals (noise), then B uniforms (dropouts)."""
        p = self.params
        r = self.true_ranges(world, pose)
        hit = r < p.range_max_m
        noisy = r + p.noise_std_m * rng.standard_normal(r.shape)
        dropped = rng.random(r.shape) < p.dropout_prob
        noisy = np.where(hit & ~dropped, np.clip(noisy, 0.0, p.range_max_m), p.range_max_m)
        return LaserScan(noisy, self.angles, p.range_max_m)


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """``[(start, stop), ...]`` of the contiguous True runs of a 1D bool array."""
    d = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)))


class SemanticCamera:
    """The semantic pseudo-laser (see :class:`~semreloc_env.config.CameraParams`).

    Per frame: cast the beams; group beams by the object they hit first; each
    object seen is detected with probability ``1 - miss_rate`` and then given a
    wrong class with probability ``wrong_class_rate``. As in paper 004, only the
    *nearest contiguous run* of beams on a detected object carries its class (an
    object split by an occluder keeps one run). With probability
    ``false_positive_rate`` a spurious detection labels a random run of 1-4 wall beams.
    Beams outside ``[range_min_m, range_max_m)`` read ``range_max_m`` and carry no class.
    """

    def __init__(self, params: CameraParams):
        self.params = params
        self.angles = beam_angles(int(params.n_beams), params.fov_rad)

    def true_hits(self, world: World, pose: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Noise-free ranges ``(S,)`` and the object index hit per beam (``-1``: wall / nothing / out of range)."""
        p = self.params
        ranges, seg = world.scene.cast(pose[:2], pose[2] + self.angles, p.range_max_m)
        in_range = (ranges >= p.range_min_m) & (ranges < p.range_max_m)
        obj = np.where((seg >= 0) & in_range, world.scene.owner[np.maximum(seg, 0)], -1)
        return np.where(in_range, ranges, p.range_max_m), obj

    def read(self, world: World, pose: np.ndarray, rng: np.random.Generator) -> SemanticScan:
        """One labelled scan. Draws, in order: S normals (noise); per visible object
        (ascending index) one uniform for the miss and one for the wrong class, plus
        one integer if the class is wrong; one uniform for a false positive (plus
        three integers if one occurs)."""
        p = self.params
        ranges, obj = self.true_hits(world, pose)
        hit = ranges < p.range_max_m
        noisy = np.where(
            hit, np.clip(ranges + p.noise_std_m * rng.standard_normal(ranges.shape), 0, p.range_max_m), p.range_max_m
        )
        labels = np.full(ranges.shape, NO_CLASS, dtype=np.int64)
        n_classes = len(CLASS_NAMES)
        obj_l = obj.tolist()  # a few dozen beams: plain Python beats array calls here
        visible = sorted(set(obj_l) - {-1})
        runs_of: dict[int, list[tuple[int, int]]] = {}  # object -> its contiguous runs of beams
        start = 0
        for i in range(1, len(obj_l) + 1):
            if i == len(obj_l) or obj_l[i] != obj_l[start]:
                runs_of.setdefault(obj_l[start], []).append((start, i))
                start = i
        r_l = ranges.tolist()
        for k in visible:
            detected = rng.random() >= p.miss_rate
            wrong = rng.random() < p.wrong_class_rate
            label = world.layout.objects[k].label
            if wrong:
                label = 1 + (label - 1 + int(rng.integers(1, n_classes))) % n_classes
            if not detected:
                continue
            a, b = min(runs_of[k], key=lambda run: min(r_l[run[0] : run[1]]))
            labels[a:b] = label
        if rng.random() < p.false_positive_rate:
            wall_runs = _runs(hit & (obj < 0))
            start_run = int(rng.integers(0, max(len(wall_runs), 1)))
            length = int(rng.integers(1, 5))
            cls = int(rng.integers(1, n_classes + 1))
            if wall_runs:
                a, b = wall_runs[start_run]
                labels[a : min(b, a + length)] = cls
        return SemanticScan(noisy, self.angles, labels, p.range_max_m)


class Odometry:
    """Wheel odometry: the true increment between two poses, corrupted by the rot1-trans-rot2 model.

    The noise is drawn with the very model the filters assume
    (:class:`filters.motion.odometry.OdometryMotionModel`), applied to one pose at the origin,
    so simulator and filter cannot disagree on its form, only on its alphas.
    """

    def __init__(self, params: OdometryMotionConfig):
        self.params = params
        self._model = OdometryMotionModel(params)
        self._origin = np.zeros(3)

    def read(self, prev_pose: np.ndarray, pose: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """Noisy robot-frame increment ``(dx, dy, dtheta)`` from ``prev_pose`` to ``pose``.

        Draws 3 normals (:meth:`~filters.motion.odometry.OdometryMotionModel.sample_pose`).
        """
        return self._model.sample_pose(self._origin, _relative(prev_pose, pose), rng)


def _relative(pose_from: np.ndarray, pose_to: np.ndarray) -> tuple[float, float, float]:
    """:func:`filters.pose.relative` of two ``(3,)`` poses in scalar arithmetic (the same numbers)."""
    ax, ay, ath = (float(v) for v in pose_from)
    bx, by, bth = (float(v) for v in pose_to)
    dx, dy = bx - ax, by - ay
    c, s = math.cos(ath), math.sin(ath)
    return (c * dx + s * dy, -s * dx + c * dy, (bth - ath + math.pi) % (2.0 * math.pi) - math.pi)
