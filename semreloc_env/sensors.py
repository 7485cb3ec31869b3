"""Simulated sensors, each a small class: ``reading = sensor.read(world, pose, rng)``.

* `Lidar` — ranges with Gaussian noise and dropouts, cast against the world's segments.
* `SemanticCamera` — the semantic pseudo-laser of paper 004 §2: per beam in
  the camera's field of view, the range to the nearest surface and the class of
  the object hit, through a detector with misses, wrong classes and false positives.
* `Odometry` — the true motion increment through the rot1-trans-rot2 noise model.

All return `filters.robot_data.scans` containers or plain arrays, so filters never see the simulator.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from filters.arrays import frozen_array
from filters.mapping.grid import NO_CLASS
from filters.motion.odometry import OdometryMotionConfig, OdometryMotionModel
from filters.pose import relative_floats
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


@numba.njit(cache=True, nogil=True)
def _noisy_ranges(r, noise, u, dropout_prob, std, range_max, out):  # pragma: no cover - compiled
    """``out[i] = clip(r[i] + std * noise[i], 0, range_max)`` where ``r[i] < range_max`` and not ``u[i] <
    dropout_prob`` (``u`` empty: no dropouts), else ``range_max``: NumPy's ``np.where(hit & ~dropped,
    np.clip(r + std * noise, 0.0, range_max), range_max)`` in one pass, the same bits (``np.clip`` keeps NaN and
    ``-0.0``; the tests hold the two equal on adversarial values). Flat float64 arrays of one length (``u``: that
    length or empty); `noisy_ranges` checks them."""
    for i in range(r.shape[0]):
        if r[i] < range_max and not (u.shape[0] and u[i] < dropout_prob):
            v = r[i] + std * noise[i]
            if v < 0.0:  # np.clip's order: NaN and -0.0 stay as they are
                v = 0.0
            if v > range_max:
                v = range_max
            out[i] = v
        else:
            out[i] = range_max


_NO_DROPOUTS = np.zeros(0)


@numba.njit(cache=True, nogil=True)
def _camera_hits(r, seg, owner, range_min, range_max, out_r, out_obj):  # pragma: no cover - compiled
    """`camera_hits` in one pass (flat arrays)."""
    for i in range(r.shape[0]):
        if range_min <= r[i] < range_max:
            out_r[i] = r[i]
            out_obj[i] = owner[seg[i]] if seg[i] >= 0 else -1
        else:
            out_r[i] = range_max
            out_obj[i] = -1


def camera_hits(
    r: np.ndarray, seg: np.ndarray, owner: np.ndarray, range_min: float, range_max: float
) -> tuple[np.ndarray, np.ndarray]:
    """``(ranges, objects)`` of cast ranges ``r`` and hit segments ``seg`` (any shape; ``-1``: none): the range where
    it lies in ``[range_min, range_max)``, else ``range_max``, and the object owning the segment hit in range
    (``owner[seg]``), else ``-1``. ValueError for a ``seg`` of another shape or outside ``[-1, len(owner))``."""
    r = np.asarray(r, dtype=np.float64)
    seg = np.asarray(seg, dtype=np.int64)
    if seg.shape != r.shape or (seg.size and not -1 <= seg.min() <= seg.max() < owner.shape[0]):
        raise ValueError(f"seg must hold segment indices in [-1, {owner.shape[0]}) in the ranges' shape {r.shape}")
    out_r = np.empty(r.shape)
    out_obj = np.empty(r.shape, np.int64)
    _camera_hits(
        r.reshape(-1), seg.reshape(-1), owner, float(range_min), float(range_max), out_r.reshape(-1),
        out_obj.reshape(-1),
    )  # fmt: skip
    return out_r, out_obj


def noisy_ranges(r: np.ndarray, noise: np.ndarray, std: float, range_max: float, u=None, dropout_prob=0.0):
    """Noisy ranges of the true ranges ``r`` (any shape, float64): ``r + std * noise`` clipped to ``[0, range_max]``
    where ``r < range_max`` and the beam is not dropped (``u < dropout_prob``; ``u`` None: none is), else
    ``range_max``. ``noise`` and ``u`` are the caller's draws, shaped as ``r`` (ValueError otherwise)."""
    r = np.asarray(r, dtype=np.float64)
    noise = np.asarray(noise, dtype=np.float64)
    u = _NO_DROPOUTS if u is None else np.asarray(u, dtype=np.float64)
    if noise.shape != r.shape or (u.size and u.shape != r.shape):
        raise ValueError(f"noise and u must have the ranges' shape {r.shape}, got {noise.shape} and {u.shape}")
    out = np.empty(r.shape)
    _noisy_ranges(
        r.reshape(-1), noise.reshape(-1), u.reshape(-1), float(dropout_prob), float(std), float(range_max),
        out.reshape(-1),
    )  # fmt: skip
    return out


class Lidar:
    """A planar lidar at the robot centre (see `LidarParams`)."""

    def __init__(self, params: LidarParams):
        self.params = params
        self.angles = frozen_array(beam_angles(int(params.n_beams), params.fov_rad), np.float64)  # shared by its scans

    def true_ranges(self, world: World, pose: np.ndarray) -> np.ndarray:
        """Noise-free ranges ``(B,)`` from ``pose``; ``range_max_m`` where nothing is hit."""
        ranges, _ = world.scene.cast(pose[:2], pose[2] + self.angles, self.params.range_max_m)
        return ranges

    def read(self, world: World, pose: np.ndarray, rng: np.random.Generator) -> LaserScan:
        """One noisy scan. Draws: B normals (noise), then B uniforms (dropouts)."""
        p = self.params
        r = self.true_ranges(world, pose)
        noise = rng.standard_normal(r.shape)
        noisy = noisy_ranges(r, noise, p.noise_std_m, p.range_max_m, rng.random(r.shape), p.dropout_prob)
        return LaserScan.from_simulator(noisy, self.angles, p.range_max_m)  # noisy: fresh, finite, in [0, max]

    def read_many(self, world: World, poses: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """Noisy ranges ``(P, B)`` from ``poses (P, 3)`` in one pass (beam angles: `angles`).

        The same model as `read`; draws ``(P, B)`` normals, then ``(P, B)`` uniforms (so
        for ``P = 1`` exactly the draws of `read`).
        """
        p = self.params
        poses = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
        r, _ = world.scene.cast_many(poses[:, :2], poses[:, 2:3] + self.angles, p.range_max_m)
        noise = rng.standard_normal(r.shape)
        return noisy_ranges(r, noise, p.noise_std_m, p.range_max_m, rng.random(r.shape), p.dropout_prob)


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """``[(start, stop), ...]`` of the contiguous True runs of a 1D bool array."""
    d = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)))


class SemanticCamera:
    """The semantic pseudo-laser (see `CameraParams`).

    Per frame: cast the beams; group beams by the object they hit first; each
    object seen is detected with probability ``1 - miss_rate`` and then given a
    wrong class with probability ``wrong_class_rate``. As in paper 004, only the
    *nearest contiguous run* of beams on a detected object carries its class (an
    object split by an occluder keeps one run; runs do not wrap round a full-circle camera's seam).
    With probability ``false_positive_rate`` a spurious detection labels the first 1-4 beams of a
    randomly drawn run of wall beams. Beams outside ``[range_min_m, range_max_m)`` read
    ``range_max_m`` and carry no class; a labelled beam's noisy depth is clipped to ``range_max_m``
    and keeps its label.
    """

    def __init__(self, params: CameraParams):
        self.params = params
        self.angles = frozen_array(beam_angles(int(params.n_beams), params.fov_rad), np.float64)  # shared by its scans

    def true_hits(self, world: World, pose: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Noise-free ranges ``(S,)`` and the object index hit per beam (``-1``: wall / nothing / out of range)."""
        p = self.params
        ranges, seg = world.scene.cast(pose[:2], pose[2] + self.angles, p.range_max_m)
        return camera_hits(ranges, seg, world.scene.owner, p.range_min_m, p.range_max_m)

    def read(self, world: World, pose: np.ndarray, rng: np.random.Generator) -> SemanticScan:
        """One labelled scan. Draws, in order: S normals (noise); per visible object
        (ascending index) one uniform for the miss and one for the wrong class, plus
        one integer if the class is wrong; one uniform for a false positive (plus
        three integers if one occurs)."""
        p = self.params
        ranges, obj = self.true_hits(world, pose)
        noisy = noisy_ranges(ranges, rng.standard_normal(ranges.shape), p.noise_std_m, p.range_max_m)
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
            wall_runs = _runs((ranges < p.range_max_m) & (obj < 0))
            start_run = int(rng.integers(0, max(len(wall_runs), 1)))
            length = int(rng.integers(1, 5))
            cls = int(rng.integers(1, n_classes + 1))
            if wall_runs:
                a, b = wall_runs[start_run]
                labels[a : min(b, a + length)] = cls
        return SemanticScan.from_simulator(noisy, self.angles, labels, p.range_max_m)

    def read_many(self, world: World, poses: np.ndarray, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """Noisy ranges and labels ``(P, S)`` from ``poses (P, 3)`` in one pass (for mapping runs).

        The detector model of `read` (misses, wrong classes, false positives, nearest run
        per object), with the draws made up front: ``(P, S)`` normals (noise), then ``(P, S, 2)``
        uniforms (miss and wrong class of the k-th visible object of each frame, ascending
        index), ``(P, S)`` class shifts, ``(P, 4)`` uniforms for the false positive (occurs,
        run, length, class). Not the draw order of `read`, so frames differ from it.
        """
        p = self.params
        poses = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
        r, seg = world.scene.cast_many(poses[:, :2], poses[:, 2:3] + self.angles, p.range_max_m)
        ranges, obj = camera_hits(r, seg, world.scene.owner, p.range_min_m, p.range_max_m)
        hit = ranges < p.range_max_m
        noisy = noisy_ranges(ranges, rng.standard_normal(ranges.shape), p.noise_std_m, p.range_max_m)
        n_classes = len(CLASS_NAMES)
        u_obj = rng.random(ranges.shape + (2,))
        shift = rng.integers(1, n_classes, size=ranges.shape) if n_classes > 1 else np.ones(ranges.shape, np.int64)
        u_fp = rng.random((ranges.shape[0], 4))
        obj_label = np.array([o.label for o in world.layout.objects] + [0], dtype=np.int64)
        labels = np.zeros(ranges.shape, np.int64)
        _detector_kernel(
            obj, ranges, hit, obj_label, u_obj, shift, u_fp, p.miss_rate, p.wrong_class_rate,
            p.false_positive_rate, n_classes, labels,
        )  # fmt: skip
        return noisy, labels


@numba.njit(cache=True, nogil=True)
def _detector_kernel(
    obj, ranges, hit, obj_label, u_obj, shift, u_fp, miss, wrong_rate, fp_rate, n_classes, labels
):  # pragma: no cover - compiled
    """Labels ``(P, S)`` of `SemanticCamera.read_many` from its pre-drawn random numbers."""
    n_frames, n_beams = obj.shape
    for f in range(n_frames):
        k = 0  # index of the visible object, ascending object index
        last = -1
        while True:
            nxt = -1  # smallest object index > last seen in this frame
            for b in range(n_beams):
                o = obj[f, b]
                if o > last and (nxt < 0 or o < nxt):
                    nxt = o
            if nxt < 0:
                break
            last = nxt
            detected = u_obj[f, k, 0] >= miss
            label = obj_label[nxt]
            if u_obj[f, k, 1] < wrong_rate:
                label = 1 + (label - 1 + shift[f, k]) % n_classes
            k += 1
            if not detected:
                continue
            best_a = -1  # the nearest contiguous run of beams on this object
            best_b = -1
            best_r = np.inf
            b = 0
            while b < n_beams:
                if obj[f, b] == nxt:
                    a = b
                    rmin = ranges[f, b]
                    while b < n_beams and obj[f, b] == nxt:
                        rmin = min(rmin, ranges[f, b])
                        b += 1
                    if rmin < best_r:
                        best_r = rmin
                        best_a = a
                        best_b = b
                else:
                    b += 1
            for q in range(best_a, best_b):
                labels[f, q] = label
        if u_fp[f, 0] < fp_rate:
            n_runs = 0  # runs of wall beams (hit, no object)
            b = 0
            while b < n_beams:
                if hit[f, b] and obj[f, b] < 0:
                    n_runs += 1
                    while b < n_beams and hit[f, b] and obj[f, b] < 0:
                        b += 1
                else:
                    b += 1
            if n_runs > 0:
                target = min(int(u_fp[f, 1] * n_runs), n_runs - 1)
                length = 1 + min(int(u_fp[f, 2] * 4), 3)
                cls = 1 + min(int(u_fp[f, 3] * n_classes), n_classes - 1)
                run = 0
                b = 0
                while b < n_beams:
                    if hit[f, b] and obj[f, b] < 0:
                        a = b
                        while b < n_beams and hit[f, b] and obj[f, b] < 0:
                            b += 1
                        if run == target:
                            for q in range(a, min(b, a + length)):
                                labels[f, q] = cls
                        run += 1
                    else:
                        b += 1


class Odometry:
    """Wheel odometry: the robot's increment between two poses, corrupted by the rot1-trans-rot2 model.

    The noise is drawn with the very model the filters assume
    (`filters.motion.odometry.OdometryMotionModel`), applied to one pose at the origin,
    so simulator and filter cannot disagree on its form, only on its alphas.

    ``reads_slides``: whether the reading includes a sideways slide (a push along a wall). A differential drive's wheels
    cannot roll sideways, so their encoders never see one: with ``reads_slides=False`` (`SemReloc-v19` and later,
    `SemSlam-v2`) the increment is the true one projected on the direction a step without slip moves along
    (`wheel_increment`), the turn as it is: a step without slip reads as it is, a slide across that direction reads as
    nothing. (Wheels that spin against a wall and read motion the robot did not make are not modelled.) With ``True``
    (`SemReloc-v18` and older, `SemSlam-v1` and `-v0`) the reading is the true increment, slides included; the
    rot1-trans-rot2 model then reads a 1.7 cm slide across the heading as a quarter turn, a step and a quarter turn
    back, with about 1 m of translation noise (docs/relocalizer.md, "SemReloc-v19").

    ``substeps``: the simulator's physics substeps per control step (`semreloc_env.world.World.drive` moves along the
    heading at each substep's start, so a step without slip moves along ``dtheta (substeps - 1) / (2 substeps)``);
    None for a continuous arc (``dtheta / 2``).
    """

    def __init__(self, params: OdometryMotionConfig, reads_slides: bool = True, substeps: int | None = None):
        self.params = params
        self.reads_slides = bool(reads_slides)
        self.substeps = substeps
        self._model = OdometryMotionModel(params)
        self._origin = np.zeros(3)

    def read(self, prev_pose: np.ndarray, pose: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """Noisy robot-frame increment ``(dx m, dy m, dtheta rad)`` from ``prev_pose`` to ``pose``.

        Draws 3 normals (`sample_pose`).
        """
        delta = relative_floats(prev_pose, pose)
        if not self.reads_slides:
            delta = wheel_increment(delta, self.substeps)
        return self._model.sample_pose(self._origin, delta, rng)


def wheel_increment(delta: tuple[float, float, float], substeps: int | None = None) -> tuple[float, float, float]:
    """What a differential drive's wheels read of the robot-frame increment ``delta = (dx m, dy m, dtheta rad)``: its
    part along the direction a step without slip moves along, with the turn as it is (see `Odometry`).

    That direction is ``dtheta / 2`` for a continuous arc (``substeps`` None) and ``dtheta (n - 1) / (2 n)`` for
    ``n = substeps`` straight moves, each along the heading at its start, as `semreloc_env.world.World.drive`
    integrates a control step."""
    dx, dy, dth = delta
    half = 0.5 * dth if substeps is None else dth * (substeps - 1) / (2.0 * substeps)
    c, s = math.cos(half), math.sin(half)
    along = dx * c + dy * s
    return along * c, along * s, dth
