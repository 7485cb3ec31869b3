import math

import numpy as np
import pytest

from filters.motion.odometry import OdometryMotionConfig
from filters.pose import compose, relative
from semreloc_env.config import CameraParams, LidarParams, PhysicsParams, RobotParams
from semreloc_env.layouts import layout_from_dict
from semreloc_env.sensors import Lidar, Odometry, SemanticCamera
from semreloc_env.world import build_world

ROOM = {"name": "room", "outer": [[0, 0], [4, 0], [4, 4], [0, 4]]}


def square_room(objects=()):
    return build_world(layout_from_dict({**ROOM, "objects": list(objects)}))


def test_lidar_ranges_match_hand_computed_distances_in_a_square_room():
    world = square_room()
    lidar = Lidar(LidarParams(n_beams=8, range_max_m=10.0, noise_std_m=0.0, dropout_prob=0.0))
    pose = np.array([1.0, 1.5, 0.0])
    scan = lidar.read(world, pose, np.random.default_rng(0))
    # beams at -pi, -3pi/4, ..., 3pi/4 from heading 0
    d_w, d_e, d_s, d_n = 1.0, 3.0, 1.5, 2.5
    expected = {
        -math.pi: d_w,
        -math.pi / 2: d_s,
        0.0: d_e,
        math.pi / 2: d_n,
        -3 * math.pi / 4: min(d_w, d_s) * math.sqrt(2),
        -math.pi / 4: min(d_e, d_s) * math.sqrt(2),
        math.pi / 4: min(d_e, d_n) * math.sqrt(2),
        3 * math.pi / 4: min(d_w, d_n) * math.sqrt(2),
    }
    for a, r in zip(scan.angles, scan.ranges):
        assert r == pytest.approx(expected[min(expected, key=lambda k: abs(k - a))], abs=1e-9)
    # rotating the robot rotates the beams: heading pi/2, beam 0 points north
    rot = lidar.read(world, np.array([1.0, 1.5, math.pi / 2]), np.random.default_rng(0))
    assert rot.ranges[np.argmin(np.abs(rot.angles))] == pytest.approx(d_n)


def test_lidar_noise_and_dropouts_and_max_range():
    world = square_room()
    lidar = Lidar(LidarParams(n_beams=360, range_max_m=2.4, noise_std_m=0.05, dropout_prob=0.2))
    pose = np.array([2.0, 2.0, 0.0])
    rng = np.random.default_rng(0)
    r = np.stack([lidar.read(world, pose, rng).ranges for _ in range(20)])
    assert np.all((r >= 0) & (r <= 2.4))
    t = Lidar(LidarParams(n_beams=360, range_max_m=10.0, noise_std_m=0.0)).true_ranges(world, pose)
    near = np.broadcast_to(t < 2.2, r.shape)
    resid = (r - t[None, :])[near & (r < 2.4)]
    assert abs(resid.mean()) < 0.01 and resid.std() == pytest.approx(0.05, rel=0.1)
    assert np.mean(r[near] == 2.4) == pytest.approx(0.2, abs=0.03)  # dropout rate
    assert np.all(r[:, t >= 2.4] == 2.4)  # beyond range: no return


def _camera(**kw):
    base = dict(
        n_beams=71,
        fov_rad=math.radians(70),
        noise_std_m=0.0,
        miss_rate=0.0,
        wrong_class_rate=0.0,
        false_positive_rate=0.0,
    )
    return SemanticCamera(CameraParams(**{**base, **kw}))


def test_semantic_camera_labels_the_object_hit():
    cab = {"class": "cabinet", "center": [3.0, 2.0], "size": [0.4, 1.0]}
    world = square_room([cab])
    cam = _camera()
    scan = cam.read(world, np.array([1.0, 2.0, 0.0]), np.random.default_rng(0))
    labelled = scan.labels == 4
    # the cabinet face x=2.8, y in [1.5, 2.5] subtends atan(0.5/1.8) each side
    half = math.atan2(0.5, 1.8)
    inside = np.abs(scan.angles) < half - 1e-6
    assert np.all(labelled[inside]) and not np.any(labelled[np.abs(scan.angles) > half + 1e-6])
    assert np.allclose(scan.ranges[inside], 1.8 / np.cos(scan.angles[inside]))
    assert np.all(scan.labels[~labelled] == 0)


def test_only_the_nearest_contiguous_run_carries_the_class():
    # a long cabinet split into two visible runs by a chair in front of its middle
    cab = {"class": "cabinet", "center": [3.5, 2.0], "size": [0.2, 3.0]}
    chair = {"class": "chair", "center": [2.0, 2.0], "size": [0.3, 0.3]}
    world = square_room([cab, chair])
    scan = _camera().read(world, np.array([0.6, 2.0 - 0.3, 0.0]), np.random.default_rng(0))
    cab_runs = np.flatnonzero(scan.labels == 4)
    assert cab_runs.size > 0
    assert np.all(np.diff(cab_runs) == 1), "one contiguous run only"
    _, owner = _camera().true_hits(world, np.array([0.6, 1.7, 0.0]))
    all_cab = np.flatnonzero(owner == 0)
    assert all_cab.size > cab_runs.size  # the other run lost its label
    # the labelled run is the nearer one
    other = np.setdiff1d(all_cab, cab_runs)
    assert scan.ranges[cab_runs].min() < scan.ranges[other].min()
    assert np.any(scan.labels == 2)  # the chair


def test_detector_miss_wrong_class_and_false_positive_rates():
    cab = {"class": "cabinet", "center": [3.0, 2.0], "size": [0.4, 1.0]}
    world = square_room([cab])
    pose = np.array([1.0, 2.0, 0.0])
    cam = _camera(miss_rate=0.3, wrong_class_rate=0.2, false_positive_rate=0.0)
    rng = np.random.default_rng(3)
    seen = np.array([np.unique(cam.read(world, pose, rng).labels[30:40]) for _ in range(2000)], dtype=object)
    labels = np.array([s.max() for s in seen])
    assert np.mean(labels == 0) == pytest.approx(0.3, abs=0.04)
    detected = labels[labels > 0]
    assert np.mean(detected != 4) == pytest.approx(0.2, abs=0.04)
    fp = _camera(false_positive_rate=0.5)
    empty = square_room()
    n_fp = sum(np.any(fp.read(empty, pose, rng).labels > 0) for _ in range(1000))
    assert n_fp / 1000 == pytest.approx(0.5, abs=0.05)


def test_camera_range_limits():
    world = square_room()
    cam = _camera(range_min_m=0.5, range_max_m=1.0)
    scan = cam.read(world, np.array([2.0, 2.0, 0.0]), np.random.default_rng(0))
    assert np.all(scan.ranges == 1.0)  # the wall is 2 m away: beyond range, no return
    near = cam.read(world, np.array([3.7, 2.0, 0.0]), np.random.default_rng(0))
    assert np.all(near.ranges[np.abs(near.angles) < 0.1] == 1.0)  # 0.3 m: closer than range_min


def test_odometry_noise_statistics_match_the_model():
    cfg = OdometryMotionConfig(alpha1=0.05, alpha2=0.02, alpha3=0.04, alpha4=0.01)
    odo = Odometry(cfg)
    rng = np.random.default_rng(0)
    start = np.array([1.0, 1.0, 0.3])
    end = np.array([1.0 + 0.2 * math.cos(0.5), 1.0 + 0.2 * math.sin(0.5), 0.3 + 0.4])
    true = relative(start, end)
    samples = np.array([odo.read(start, end, rng) for _ in range(20000)])
    rot1, trans = math.atan2(true[1], true[0]), math.hypot(true[0], true[1])
    rot2 = true[2] - rot1
    sd_trans = math.sqrt(cfg.alpha3 * trans**2 + cfg.alpha4 * (rot1**2 + rot2**2))
    sd_rot1 = math.sqrt(cfg.alpha1 * rot1**2 + cfg.alpha2 * trans**2)
    got_trans = np.hypot(samples[:, 0], samples[:, 1])
    got_rot1 = np.arctan2(samples[:, 1], samples[:, 0])
    # a noisy translation below zero flips the direction by pi: rare, left out of the spread
    flipped = np.abs(got_rot1 - rot1) > 1.0
    assert flipped.mean() < 1e-3
    got_rot1 = got_rot1[~flipped]
    assert got_trans.mean() == pytest.approx(trans, abs=3 * sd_trans / math.sqrt(20000) + 1e-4)
    assert got_trans.std() == pytest.approx(sd_trans, rel=0.05)
    assert got_rot1.std() == pytest.approx(sd_rot1, rel=0.05)
    sd_dth = math.sqrt(sd_rot1**2 + (cfg.alpha1 * rot2**2 + cfg.alpha2 * trans**2))
    assert samples[:, 2].mean() == pytest.approx(true[2], abs=0.005)
    assert samples[:, 2].std() == pytest.approx(sd_dth, rel=0.05)


def test_wheel_odometry_reads_no_slide_along_a_wall():
    """An outside reviewer's case: a 1.7 cm slide across the heading (a push along a wall) read as a quarter turn, a
    step and a quarter turn back, with about 1 m of translation noise; the wheels' reading (SemReloc-v22) sees only
    the slide's part along the heading, and an arc without slip reads as the true odometry does."""
    from semreloc_env.envs.base import default_odometry_noise

    cfg = default_odometry_noise()
    start = np.array([1.0, 0.6, -1.25])
    slid = start + np.array([0.017, 0.0, 0.0])  # along the wall, 72 deg off the heading
    seen = {}
    for reads in (True, False):
        odo = Odometry(cfg, reads_slides=reads)
        rng = np.random.default_rng(0)
        seen[reads] = np.array([odo.read(start, slid, rng) for _ in range(2000)])
    far_true = np.percentile(np.hypot(seen[True][:, 0], seen[True][:, 1]), 95)
    far_wheels = np.percentile(np.hypot(seen[False][:, 0], seen[False][:, 1]), 95)
    assert far_true > 0.2 and far_wheels < 0.02  # the slide read as up to tens of cm before, now a few mm
    along = 0.017 * math.cos(1.25)
    assert seen[False][:, 0].mean() == pytest.approx(along, abs=5e-4)  # what the wheels rolled
    arc = compose(start, np.array([0.05 * math.sin(0.1) / 0.1, 0.05 * (1 - math.cos(0.1)) / 0.1, 0.1]))
    a = Odometry(cfg, reads_slides=True).read(start, arc, np.random.default_rng(5))
    b = Odometry(cfg, reads_slides=False).read(start, arc, np.random.default_rng(5))
    np.testing.assert_allclose(a, b, atol=1e-12)  # an arc without slip reads the same either way


def test_wheel_odometry_reads_the_simulators_free_arcs_as_they_are():
    """A reviewer's check: `World.drive` moves along the heading at each substep's start, so a free arc's chord
    points at dtheta (n - 1) / (2 n), not dtheta / 2; read along dtheta / 2 a 30-step arc dead-reckoned 1 cm off."""
    import gymnasium as gym

    from filters.pose import relative_floats
    from semreloc_env.sensors import wheel_increment

    for substeps in (5, 2, 1):
        env = gym.make("SemReloc-v22", layout="open_hall", map_source="perfect", physics={"substeps": substeps})
        env.reset(seed=0, options={"pose": [3.5, 7.5, 0.3]})  # 3 m from anything
        world = env.unwrapped.world
        assert env.unwrapped.odometry.substeps == substeps
        for v, w in [(0.5, 1.0), (-0.3, 1.0), (0.3, -1.5), (0.0, 1.0)]:
            est = world.pose.copy()
            for _ in range(30):
                prev = world.pose.copy()
                assert not world.drive(v, w)  # free: no wall within reach
                est = compose(est, np.array(wheel_increment(relative_floats(prev, world.pose), substeps)))
            np.testing.assert_allclose(est, world.pose, atol=1e-9)


def test_dead_reckoning_drifts():
    odo = Odometry(OdometryMotionConfig(alpha1=0.02, alpha2=0.02, alpha3=0.02, alpha4=0.01))
    rng = np.random.default_rng(1)
    from filters.pose import compose

    finals = []
    for _ in range(50):
        est = np.zeros(3)
        truth = np.zeros(3)
        for _ in range(100):
            nxt = compose(truth, np.array([0.05, 0.0, 0.02]))
            est = compose(est, odo.read(truth, nxt, rng))
            truth = nxt
        finals.append(np.hypot(*(est[:2] - truth[:2])))
    assert np.median(finals) > 0.02  # drift is real ...
    assert np.median(finals) < 1.0  # ... and modest for a good encoder


def test_robot_never_enters_walls_or_objects():
    from semreloc_env.layouts import get_layout

    world = build_world(get_layout("lab"), RobotParams(radius_m=0.25, max_linear_mps=1.0), PhysicsParams(substeps=3))
    rng = np.random.default_rng(0)
    worst = np.inf
    bumps = 0
    for _ in range(10):
        world.set_pose(world.sample_free_pose(rng))
        for _ in range(300):
            bumps += world.drive(rng.uniform(0.3, 1.0), rng.uniform(-0.5, 0.5))
            worst = min(worst, world.clearance(world.pose[:2]))
            assert world.is_free(world.pose[:2], margin_m=-1e-4)
    assert bumps > 20  # the random drive did hit things ...
    assert worst >= 0.25 - 1e-4  # ... and never went in (0.1 mm numerical tolerance)


def test_compiled_drive_is_the_reference_bit_for_bit():
    # World.drive runs `_drive_kernel`; drive_reference is the Python it replaced: the same poses and contacts, from
    # free starts, from starts touching a wall and facing it, and from poses written onto walls and corners (which
    # set_pose refuses, but which take the projection's every branch), in the lab, a gap narrower than the robot
    # and a zig-zag wall
    import copy

    from semreloc_env.layouts import get_layout

    walls = [[[2.0, 0.0], [2.0, 1.8]], [[2.0, 2.15], [2.0, 4.0]], [[0.5, 3.5], [1.0, 0.5], [1.5, 3.5], [1.7, 0.8]]]
    odd = layout_from_dict({**ROOM, "walls": walls})  # a 0.35 m gap for a 0.4 m robot, acute corners
    rng = np.random.default_rng(1)
    counts = {"contacts": 0, "blocked": 0}

    def same_drives(world, n):
        fast, ref = copy.deepcopy(world), copy.deepcopy(world)
        for _ in range(n):
            v = rng.choice([-0.5, 0.5, rng.uniform(-0.5, 0.5), 0.0, 1e-300])  # 0: stay on a wall, a corner
            omega = rng.choice([0.0, rng.uniform(-1.2, 1.2)])
            before = ref.pose
            hit = ref.drive_reference(v, omega)
            assert fast.drive(v, omega) is hit
            assert fast.pose.tobytes() == ref.pose.tobytes() and fast.body.angle == ref.body.angle
            counts["contacts"] += hit
            counts["blocked"] += hit and bool(np.all(ref.pose[:2] == before[:2]))

    for layout in (get_layout("lab"), odd):
        world = build_world(layout)
        a, e, r = world.scene.a, world.scene.e, world.robot_params.radius_m
        for _ in range(30):  # free starts
            world.set_pose(world.sample_free_pose(rng, margin_m=0.0))
            same_drives(world, 20)
        for _ in range(150):  # touching a wall (at the radius, give or take a rounding), facing it
            i, t, ang = rng.integers(len(a)), rng.choice([0.0, 1.0, rng.uniform()]), rng.uniform(-math.pi, math.pi)
            gap = rng.choice([world._skin, 0.0, 1e-12, 2 * world._skin, 1e-6])
            xy = a[i] + t * e[i] + (r + gap) * np.array([math.cos(ang), math.sin(ang)])
            world.body.position, world.body.angle = (float(xy[0]), float(xy[1])), ang + math.pi
            same_drives(world, 10)
        for _ in range(300):  # on a vertex, on a segment, or into a wall
            i = rng.integers(len(a))
            xy = rng.choice([a[i], a[i] + 0.5 * e[i], a[i] + rng.uniform() * e[i] + rng.normal(0, r, 2)])
            world.body.position, world.body.angle = (float(xy[0]), float(xy[1])), float(rng.uniform(-4, 4))
            same_drives(world, 8)
    assert counts["contacts"] > 2000 and counts["blocked"] > 500, counts  # 2899 and 892 with these seeds


def test_set_pose_rejects_blocked_and_bad_poses_without_moving():
    world = square_room([{"class": "chair", "center": [2.0, 2.0], "size": [0.5, 0.5]}])
    world.set_pose([1.0, 1.0, 0.0])
    for bad in ([2.0, 2.0, 0.0], [0.1, 2.0, 0.0], [9.0, 9.0, 0.0], [np.nan, 1.0, 0.0], [1.0, 1.0]):
        with pytest.raises(ValueError):
            world.set_pose(bad)
        assert world.pose.tolist() == [1.0, 1.0, 0.0]


def test_speeds_that_could_tunnel_through_walls_are_rejected():
    with pytest.raises(ValueError, match="substep"):
        build_world(layout_from_dict(ROOM), RobotParams(max_linear_mps=20.0), PhysicsParams(substeps=2))


def test_extra_obstacles_of_either_winding():
    concave_cw = [[1.0, 1.0], [1.0, 3.0], [2.0, 2.0], [3.0, 3.0], [3.0, 1.0]]  # clockwise, concave
    world = build_world(layout_from_dict(ROOM), extra_obstacles=[np.array(concave_cw)])
    assert not world.is_free([2.0, 1.5])


def test_world_without_free_space():
    tiny = layout_from_dict({"outer": [[0, 0], [0.3, 0], [0.3, 0.3], [0, 0.3]]})
    with pytest.raises(ValueError, match="no free space"):
        build_world(tiny).sample_free_pose(np.random.default_rng(0), max_tries=100)


def test_config_validation():
    with pytest.raises(ValueError):
        LidarParams(n_beams=0)
    with pytest.raises(ValueError):
        CameraParams(range_min_m=5.0, range_max_m=4.0)
    with pytest.raises(ValueError):
        CameraParams(miss_rate=1.5)
    with pytest.raises(ValueError):
        RobotParams(radius_m=-1)


def test_simulated_scans_skip_the_checks_but_are_the_scans_the_constructor_makes():
    # the sensors build their scans with from_simulator (no checks, no copies): the same fields, owned and read-only
    from filters.robot_data.scans import LaserScan, SemanticScan
    from semreloc_env.layouts import get_layout

    world = build_world(get_layout("lab"))
    lidar, camera = Lidar(LidarParams(dropout_prob=0.2)), SemanticCamera(CameraParams(false_positive_rate=0.5))
    rng = np.random.default_rng(4)
    for _ in range(20):
        world.set_pose(world.sample_free_pose(rng))
        made = [lidar.read(world, world.pose, rng), camera.read(world, world.pose, rng)]
        checked = [
            LaserScan(made[0].ranges, made[0].angles, made[0].range_max_m),
            SemanticScan(made[1].ranges, made[1].angles, made[1].labels, made[1].range_max_m),
        ]
        for a, b in zip(made, checked):
            assert type(a) is type(b)
            for name in ("ranges", "angles", "labels", "sensor_pose"):
                if hasattr(b, name):
                    x, y = getattr(a, name), getattr(b, name)
                    assert x.dtype == y.dtype and x.shape == y.shape and np.array_equal(x, y)
                    assert not x.flags.writeable
            for name in ("range_max_m", "range_min_m"):
                if hasattr(b, name):
                    assert type(getattr(a, name)) is float and getattr(a, name) == getattr(b, name)
    assert made[0].ranges.base is None and made[1].labels.base is None  # the scan's own arrays
    assert made[0].angles is lidar.angles and not lidar.angles.flags.writeable  # shared, and no one can change it


def test_a_push_out_of_one_wall_never_leaves_the_robot_inside_another_it_did_not_test():
    # a review: the segments were gathered within r + v dt of the start, but a push out of a thin V of walls carried
    # the robot 0.95 m (v dt = 0.90) to 1.25 mm inside a segment never tested; set_pose(world.pose) then failed
    import copy

    layout = layout_from_dict(
        {
            "outer": [[0, 0], [10, 0], [10, 10], [0, 10]],
            "walls": [
                [[4.318, 1.5316], [5.1125, 2.3111], [4.6607, 0.9677]],
                [[3.6845, 0.9844], [2.8393, 2.0709], [3.7382, 1.7013]],
            ],
        }
    )
    world = build_world(
        layout, RobotParams(radius_m=0.3, max_linear_mps=8.991), PhysicsParams(control_hz=10.0, substeps=3)
    )
    world.set_pose([4.897735371604556, 0.7837833429290477, -3.389898171694593])
    ref = copy.deepcopy(world)
    world.drive(8.991, 0.0)
    ref.drive_reference(8.991, 0.0)
    assert np.array_equal(world.pose, ref.pose)
    assert world.clearance(world.pose[:2]) >= 0.3 - 1e-9
    world.set_pose(world.pose)  # a pose of a running episode is a legal start


def _noisy_ranges_numpy(r, noise, std, range_max, u=None, dropout_prob=0.0):
    """The NumPy code `semreloc_env.sensors.noisy_ranges` replaced (the lidar's and the camera's)."""
    keep = r < range_max
    if u is not None:
        keep = keep & ~(u < dropout_prob)
    return np.where(keep, np.clip(r + std * noise, 0.0, range_max), range_max)


def test_noisy_ranges_are_numpys_bits_on_adversarial_values():
    from hypothesis import given, settings
    from hypothesis import strategies as st
    from hypothesis.extra.numpy import arrays

    from semreloc_env.sensors import noisy_ranges

    special = st.sampled_from([0.0, -0.0, 1e-320, -1e-320, 8.0, np.nextafter(8.0, 0), np.nan, np.inf, -np.inf, 1e308])
    values = st.one_of(special, st.floats(allow_nan=True, allow_infinity=True))

    @settings(max_examples=300, deadline=None)
    @given(
        r=arrays(np.float64, 12, elements=values),
        noise=arrays(np.float64, 12, elements=values),
        u=arrays(np.float64, 12, elements=st.floats(0.0, 1.0)),
        std=st.sampled_from([0.0, 0.02, 1.0, 1e300]),
        dropout=st.sampled_from([0.0, 0.05, 1.0]),
    )
    def check(r, noise, u, std, dropout):
        with np.errstate(all="ignore"):
            for args in ((), (u, dropout)):
                got = noisy_ranges(r, noise, std, 8.0, *args)
                want = _noisy_ranges_numpy(r, noise, std, 8.0, *args)
                assert got.tobytes() == want.tobytes()  # -0.0 and NaN included

    check()
    # (P, B) arrays, as read_many passes them
    rng = np.random.default_rng(3)
    r = rng.uniform(-1.0, 9.0, (4, 7))
    noise, u = rng.standard_normal((4, 7)), rng.random((4, 7))
    got = noisy_ranges(r, noise, 0.3, 8.0, u, 0.2)
    assert got.shape == (4, 7) and got.tobytes() == _noisy_ranges_numpy(r, noise, 0.3, 8.0, u, 0.2).tobytes()
    with pytest.raises(ValueError, match="shape"):
        noisy_ranges(r, noise[:, :3], 0.3, 8.0)  # the kernel reads as many draws as ranges
    with pytest.raises(ValueError, match="shape"):
        noisy_ranges(r, noise, 0.3, 8.0, u[:2], 0.2)


def test_camera_hits_are_the_numpy_selection():
    from semreloc_env.sensors import camera_hits

    rng = np.random.default_rng(5)
    owner = np.array([-1, 0, 0, 1, -1, 2], dtype=np.int64)
    for shape in ((40,), (3, 13)):
        r = rng.choice([0.0, -0.0, 0.1, 0.2, 0.5, 4.9, 5.0, np.nan, np.inf, 7.0], size=shape)
        seg = rng.integers(-1, owner.size, size=shape)
        got_r, got_obj = camera_hits(r, seg, owner, 0.1, 5.0)
        in_range = (r >= 0.1) & (r < 5.0)  # the NumPy code camera_hits replaced
        want_obj = np.where((seg >= 0) & in_range, owner[np.maximum(seg, 0)], -1)
        want_r = np.where(in_range, r, 5.0)
        assert got_r.tobytes() == want_r.tobytes() and got_r.shape == shape
        assert got_obj.dtype == want_obj.dtype and np.array_equal(got_obj, want_obj)
    for bad in (np.array([0, 6]), np.array([-2, 0]), np.array([0])):
        with pytest.raises(ValueError, match="segment indices"):
            camera_hits(np.array([1.0, 2.0]), bad, owner, 0.1, 5.0)  # the kernel does not check bounds
