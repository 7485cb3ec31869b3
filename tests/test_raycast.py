"""The compiled ray caster against the NumPy reference, and the cheap sensor paths against their plain forms."""

import numpy as np
import pytest

from filters.mapping.grid import NO_CLASS
from filters.motion.odometry import OdometryMotionConfig, OdometryMotionModel
from filters.pose import relative
from semreloc_env.config import CameraParams
from semreloc_env.layouts import CLASS_NAMES, get_layout
from semreloc_env.raycast import SegmentScene
from semreloc_env.sensors import Odometry, SemanticCamera, _runs
from semreloc_env.world import build_world


@pytest.mark.parametrize("layout", ["lab", "twin_rooms", "procedural"])
def test_compiled_cast_agrees_with_the_numpy_reference(layout):
    world = build_world(get_layout(layout, seed=3))
    scene = world.scene
    x0, x1, y0, y1 = world.layout.bounds()
    rng = np.random.default_rng(0)
    for _ in range(200):
        origin = rng.uniform((x0 - 1, y0 - 1), (x1 + 1, y1 + 1))  # inside and outside the walls
        angles = rng.uniform(-4.0, 4.0, 45)
        for max_range in (0.3, 4.5, 8.0, 1e3):
            r, hit = scene.cast(origin, angles, max_range)
            r_ref, hit_ref = scene.cast_reference(origin, angles, max_range)
            assert np.max(np.abs(r - r_ref)) <= 1e-9
            assert np.array_equal(hit, hit_ref)
            assert np.all((r <= max_range) & (r >= 0)) and np.all((hit == -1) == (r == max_range))


def test_cast_many_equals_one_cast_per_origin_and_checks_shapes():
    scene = build_world(get_layout("lab")).scene
    rng = np.random.default_rng(1)
    origins = rng.uniform((1, 1), (14, 9), (7, 2))
    angles = rng.uniform(-np.pi, np.pi, (7, 30))
    angles[3] = rng.uniform(-1e4, 1e4, 30)  # far from [-pi, pi): cos and sin must still be NumPy's
    r, hit = scene.cast_many(origins, angles, 8.0)
    for k in range(7):  # one origin takes its own path (cos_sin, no shape checks): the same bits
        for origin in (origins[k], [*origins[k], 0.3], origins[k].tolist()):
            rk, hk = scene.cast(origin, angles[k], 8.0)
            assert r[k].tobytes() == rk.tobytes() and np.array_equal(hit[k], hk)
    with pytest.raises(ValueError, match="origins must be"):
        scene.cast_many(origins, angles[:3], 8.0)
    with pytest.raises(ValueError, match="origins must be"):
        scene.cast(origins[0], angles[:2], 8.0)  # 2-D angles for one origin
    with pytest.raises(ValueError, match="origins must be"):
        scene.cast(origins[0][:1], angles[0], 8.0)  # one coordinate


def test_cast_hits_a_segment_end_and_misses_parallel_segments():
    scene = SegmentScene(np.array([[[1.0, -1.0], [1.0, 1.0]], [[0.0, 0.5], [3.0, 0.5]]]), np.array([-1, 0]))
    r, hit = scene.cast(np.zeros(2), np.array([0.0, np.pi / 4, np.pi, np.pi / 2]), 5.0)
    assert r[0] == pytest.approx(1.0) and hit[0] == 0
    assert r[1] == pytest.approx(np.sqrt(0.5)) and hit[1] == 1  # the y = 0.5 line comes first
    assert r[2] == 5.0 and hit[2] == -1
    assert r[3] == pytest.approx(0.5) and hit[3] == 1


def test_single_pose_odometry_sample_equals_the_particle_array_path_bit_for_bit():
    model = OdometryMotionModel(OdometryMotionConfig(0.1, 0.05, 0.2, 0.01))
    rng = np.random.default_rng(0)
    for i in range(3000):
        pose = rng.uniform(-5, 5, 3)
        delta = rng.normal(0, 0.1, 3) * (i % 11 != 0)  # some zero increments
        if i % 7 == 0:
            delta[:2] = rng.normal(0, 0.003, 2)  # below min_trans_m
        seed = int(rng.integers(1 << 31))
        a = model.sample(pose[None], delta, np.random.default_rng(seed))[0]
        b = model.sample_pose(pose, delta, np.random.default_rng(seed))
        assert np.array_equal(a, b)
    with pytest.raises(ValueError, match="delta"):
        model.sample_pose(np.zeros(3), [0.1, np.nan, 0.0], rng)
    with pytest.raises(ValueError, match="pose"):
        model.sample_pose(np.zeros(2), [0.1, 0.0, 0.0], rng)


def test_odometry_sensor_equals_the_model_on_the_relative_increment():
    odo = Odometry(OdometryMotionConfig())
    rng = np.random.default_rng(2)
    for _ in range(500):
        prev = rng.uniform(-5, 5, 3)
        now = prev + rng.normal(0, 0.05, 3)
        seed = int(rng.integers(1 << 31))
        expected = OdometryMotionModel(odo.params).sample(
            np.zeros((1, 3)), relative(prev, now), np.random.default_rng(seed)
        )[0]
        assert np.array_equal(odo.read(prev, now, np.random.default_rng(seed)), expected)


def _camera_labels_plain(cam, world, pose, rng):
    """The detector as first written (array calls per object): the reference of the cheap loop."""
    p = cam.params
    ranges, obj = cam.true_hits(world, pose)
    hit = ranges < p.range_max_m
    rng.standard_normal(ranges.shape)
    labels = np.full(ranges.shape, NO_CLASS, dtype=np.int64)
    n_classes = len(CLASS_NAMES)
    for k in np.unique(obj[obj >= 0]):
        detected = rng.random() >= p.miss_rate
        wrong = rng.random() < p.wrong_class_rate
        label = world.layout.objects[k].label
        if wrong:
            label = 1 + (label - 1 + int(rng.integers(1, n_classes))) % n_classes
        if not detected:
            continue
        nearest = min(_runs(obj == k), key=lambda r: ranges[r[0] : r[1]].min())
        labels[nearest[0] : nearest[1]] = label
    if rng.random() < p.false_positive_rate:
        wall_runs = _runs(hit & (obj < 0))
        start_run = int(rng.integers(0, max(len(wall_runs), 1)))
        length = int(rng.integers(1, 5))
        cls = int(rng.integers(1, n_classes + 1))
        if wall_runs:
            a, b = wall_runs[start_run]
            labels[a : min(b, a + length)] = cls
    return labels


@pytest.mark.parametrize("layout", ["lab", "twin_rooms"])
def test_camera_detector_loop_equals_the_plain_version(layout):
    world = build_world(get_layout(layout))
    cam = SemanticCamera(CameraParams(miss_rate=0.3, wrong_class_rate=0.3, false_positive_rate=0.3))
    rng = np.random.default_rng(3)
    n_objects_seen = 0
    for _ in range(300):
        pose = world.sample_free_pose(rng)
        seed = int(rng.integers(1 << 31))
        scan = cam.read(world, pose, np.random.default_rng(seed))
        ref = _camera_labels_plain(cam, world, pose, np.random.default_rng(seed))
        assert np.array_equal(scan.labels, ref)
        n_objects_seen += int(np.any(ref > 0))
    assert n_objects_seen > 50  # the comparison exercised detections


def test_cast_agrees_with_pymunk_segment_queries_on_the_collision_shapes():
    import pymunk

    world = build_world(get_layout("lab"))
    world.shape.filter = pymunk.ShapeFilter(categories=1)
    not_robot = pymunk.ShapeFilter(mask=pymunk.ShapeFilter.ALL_MASKS() ^ 1)
    rng = np.random.default_rng(4)
    for _ in range(60):
        pose = world.sample_free_pose(rng)
        angles = rng.uniform(-np.pi, np.pi, 20)
        ranges, _ = world.scene.cast(pose[:2], angles, 8.0)
        for a, r in zip(angles, ranges):
            end = (pose[0] + 8.0 * np.cos(a), pose[1] + 8.0 * np.sin(a))
            q = world.space.segment_query_first(tuple(pose[:2]), end, 0.0, not_robot)
            assert (8.0 if q is None else q.alpha * 8.0) == pytest.approx(r, abs=1e-9)


def test_lazily_built_space_holds_the_robot_where_it_is():
    """The pymunk space, built after the robot moved or built before it moves, has the robot's
    shape at the world's pose."""
    import pymunk

    lay = get_layout("lab")
    for build_first in (False, True):
        world = build_world(lay)
        if build_first:
            world.space  # noqa: B018
        world.set_pose([3.0, 2.5, 0.0])
        for _ in range(5):
            world.drive(0.5, 0.2)
        x, y, _ = world.pose
        hit = world.space.point_query_nearest((x, y), 0.0, pymunk.ShapeFilter())
        assert hit is not None and hit.shape is world.shape
        bb = world.shape.bb
        assert (bb.left + bb.right) / 2 == pytest.approx(x) and (bb.bottom + bb.top) / 2 == pytest.approx(y)


@pytest.mark.parametrize("layout", ["lab", "procedural_sym"])
def test_compiled_free_space_test_equals_the_numpy_reference(layout):
    from semreloc_env.scenarios import changed_obstacles

    lay = get_layout(layout, seed=2)
    for extra in ([], changed_obstacles(lay, 1)):
        world = build_world(lay, extra_obstacles=extra)
        x0, x1, y0, y1 = lay.bounds()
        pts = np.random.default_rng(5).uniform((x0 - 1, y0 - 1), (x1 + 1, y1 + 1), (5000, 2))
        for margin in (0.0, 0.1):
            free = world.free_points(pts, margin)
            assert np.array_equal(free, world.free_points_reference(pts, margin))
            assert 0.3 < free.mean() < 0.7


def test_worlds_share_cached_static_geometry_but_not_their_pymunk_space():
    lay = get_layout("lab")
    a, b = build_world(lay), build_world(lay)
    assert a.geometry is b.geometry and a.scene is b.scene
    assert a._space is None  # built on first use
    assert a.space is not b.space
    before = b.pose
    a.set_pose([2.0, 2.0, 0.5])
    assert np.array_equal(b.pose, before) and np.allclose(a.pose, [2.0, 2.0, 0.5])


@pytest.mark.parametrize("cell_m", [0.25, 1.0, 7.0])
def test_bucket_grid_caster_equals_brute_force_on_random_segment_soups(cell_m):
    rng = np.random.default_rng(6)
    a = rng.uniform(0, 10, (300, 2))
    b = a + rng.normal(0, 1.5, (300, 2))
    b[:40, 1] = a[:40, 1]  # horizontal and vertical segments
    b[40:80, 0] = a[40:80, 0]
    scene = SegmentScene(np.stack([a, b], axis=1), np.full(300, -1))
    scene = SegmentScene(scene.segments, scene.owner, cell_m=cell_m)
    angles = np.concatenate([[0.0, np.pi / 2, np.pi, -np.pi / 2], rng.uniform(-np.pi, np.pi, 60)])
    origins = np.concatenate([rng.uniform(-3, 13, (150, 2)), a[:20], np.round(rng.uniform(0, 10, (20, 2)))])
    for o in origins:
        for max_range in (2.0, 50.0):
            r, hit = scene.cast(o, angles, max_range)
            r_ref, hit_ref = scene.cast_reference(o, angles, max_range)
            assert np.max(np.abs(r - r_ref)) <= 1e-9
            assert np.array_equal(hit, hit_ref)
    with pytest.raises(ValueError, match="cell_m"):
        SegmentScene(scene.segments, scene.owner, cell_m=0.0)


def test_compiled_motion_sample_equals_the_numpy_reference():
    model = OdometryMotionModel(OdometryMotionConfig(0.1, 0.05, 0.2, 0.01))
    rng = np.random.default_rng(8)
    poses = np.column_stack([rng.uniform(-5, 5, (3000, 2)), rng.uniform(-np.pi, np.pi, 3000)])
    for _ in range(20):
        delta = rng.normal(0, 0.1, 3)
        seed = int(rng.integers(1 << 31))
        a = model.sample(poses, delta, np.random.default_rng(seed))
        b = model.sample_reference(poses, delta, np.random.default_rng(seed))
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-12)
        assert np.all((a[:, 2] >= -np.pi) & (a[:, 2] < np.pi))


def test_compiled_near_equals_the_distance_to_every_segment():
    world = build_world(get_layout("procedural", seed=4))
    x0, x1, y0, y1 = world.layout.bounds()
    rng = np.random.default_rng(9)
    for _ in range(3000):
        p = rng.uniform((x0 - 1, y0 - 1), (x1 + 1, y1 + 1))
        reach = float(rng.uniform(0.0, 3.0))
        assert np.array_equal(world.scene.near(p, reach), world.scene.near_reference(p, reach))


def test_a_huge_scene_gets_coarser_buckets_not_a_memory_error():
    # 1 m buckets over 1e6 m would be 10^12 cells (an input audit found the MemoryError)
    from semreloc_env.raycast import _MAX_BUCKETS_PER_SIDE

    segs = np.array([[[0.0, -1.0], [0.0, 1.0]], [[1e6, -1.0], [1e6, 1.0]]])
    scene = SegmentScene(segs, np.array([0, 1]))
    _, _, _, _, cell, nx, ny = scene.bucket_grid
    assert nx <= _MAX_BUCKETS_PER_SIDE and ny <= _MAX_BUCKETS_PER_SIDE and cell > 400
    r, hit = scene.cast(np.array([10.0, 0.0]), np.array([np.pi, 0.0]), 2e6)
    np.testing.assert_allclose(r, [10.0, 1e6 - 10.0])
    assert hit.tolist() == [0, 1]
