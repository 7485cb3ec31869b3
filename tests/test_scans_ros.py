"""ROS-style LaserScan construction, sensor mounting pose in mapping and the likelihood model, no-return policy."""

import math

import numpy as np
import pytest

from filters.localization.likelihood_field import LikelihoodFieldModel
from filters.localization.likelihood_reference import log_likelihood_reference
from filters.mapping.grid import GridMap
from filters.mapping.occupancy import OccupancyMapper, OccupancyParams
from filters.pose import compose
from filters.robot_data.scans import LaserScan, SemanticScan


def test_from_ros_reading_rules():
    r = [1.0, math.inf, math.nan, -math.inf, 0.05, 12.0, 3.0]
    s = LaserScan.from_ros(r, angle_min=-0.3, angle_increment=0.1, range_min=0.1, range_max=10.0)
    # NaN, -inf and 0.05 < range_min are dropped; inf and 12 > range_max become no-return beams
    np.testing.assert_allclose(s.ranges, [1.0, 10.0, 10.0, 3.0])
    np.testing.assert_allclose(s.angles, [-0.3, -0.2, 0.2, 0.3])
    np.testing.assert_array_equal(s.valid, [True, False, False, True])
    assert s.range_min_m == 0.1 and s.range_max_m == 10.0
    np.testing.assert_array_equal(s.sensor_pose, [0.0, 0.0, 0.0])
    rev = LaserScan.from_ros([1.0, 2.0], angle_min=1.0, angle_increment=-0.5, range_min=0.0, range_max=5.0)
    np.testing.assert_allclose(rev.angles, [1.0, 0.5])


@pytest.mark.parametrize(
    "kw, match",
    [
        ({"angle_increment": 0.0}, "angle_increment must be non-zero"),
        ({"angle_min": math.nan}, "angle_min"),
        ({"range_max": 0.0}, "range_max"),
        ({"range_min": 6.0}, "range_min"),
        ({"range_min": -1.0}, "range_min"),
        ({"sensor_pose": (0.0, 1.0)}, "sensor_pose"),
    ],
)
def test_from_ros_bad_arguments(kw, match):
    args = {"angle_min": 0.0, "angle_increment": 0.1, "range_min": 0.0, "range_max": 5.0}
    args.update(kw)
    with pytest.raises(ValueError, match=match):
        LaserScan.from_ros([1.0, 2.0], **args)


def test_direct_constructor_still_strict():
    with pytest.raises(ValueError, match="NaN or inf"):
        LaserScan(np.array([math.inf]), np.zeros(1), 5.0)
    with pytest.raises(ValueError, match="range_min_m"):
        LaserScan(np.ones(1), np.zeros(1), 5.0, range_min_m=5.0)
    with pytest.raises(ValueError, match="sensor_pose"):
        SemanticScan(np.ones(1), np.zeros(1), np.zeros(1, int), 5.0, sensor_pose=(0, 0, math.nan))


def _room_grid() -> GridMap:
    occ = np.zeros((60, 80), np.float32)
    occ[0, :] = occ[-1, :] = occ[:, 0] = occ[:, -1] = 1.0
    occ[20:30, 40:45] = 1.0
    sem = np.zeros((1, 60, 80), np.float32)
    sem[0, 20:30, 40:45] = 1.0
    return GridMap(occ, 0.1, (-1.0, -2.0), semantic=sem, class_names=("box",))


@pytest.mark.parametrize("backend", ["numba", "numpy"])
def test_sensor_pose_in_likelihood_equals_moved_robot(backend):
    grid = _room_grid()
    model = LikelihoodFieldModel(grid, backend=backend)
    rng = np.random.default_rng(0)
    poses = np.column_stack([rng.uniform(0, 5, 50), rng.uniform(-1, 3, 50), rng.uniform(-3, 3, 50)])
    angles = np.linspace(-2.0, 2.0, 40)
    ranges = rng.uniform(0.3, 4.0, 40)
    off = np.array([0.25, -0.1, 0.4])
    mounted = LaserScan(ranges, angles, 8.0, sensor_pose=off)
    centred = LaserScan(ranges, angles, 8.0)
    sem_m = SemanticScan(ranges, angles, np.ones(40, int), 8.0, sensor_pose=off)
    sem_c = SemanticScan(ranges, angles, np.ones(40, int), 8.0)
    got = model.log_likelihood(poses, mounted, sem_m)
    want = model.log_likelihood(compose(poses, off), centred, sem_c)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-9)
    # the offset matters, and kernel and reference agree with it
    assert np.max(np.abs(got - model.log_likelihood(poses, centred, sem_c))) > 1.0
    ref = log_likelihood_reference(model, poses, mounted, sem_m)
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-9)


def test_range_min_beams_are_skipped_by_the_likelihood():
    model = LikelihoodFieldModel(_room_grid())
    s = LaserScan(np.array([0.05, 1.0, 2.0]), np.array([0.0, 0.5, 1.0]), 8.0, range_min_m=0.1)
    assert model.beams(s, None).n_lidar == 2


def test_sensor_pose_in_mapping_equals_moved_robot():
    angles = np.linspace(-1.5, 1.5, 31)
    ranges = np.full(31, 2.0)
    ranges[5] = 10.0  # no return
    off = np.array([0.3, 0.1, -0.5])
    pose = np.array([1.0, 1.0, 0.3])
    a = OccupancyMapper((60, 60), 0.1, (-1.0, -1.0))
    a.update(pose, LaserScan(ranges, angles, 10.0, sensor_pose=off))
    b = OccupancyMapper((60, 60), 0.1, (-1.0, -1.0))
    b.update(compose(pose, off), LaserScan(ranges, angles, 10.0))
    np.testing.assert_array_equal(a.logodds, b.logodds)
    c = OccupancyMapper((60, 60), 0.1, (-1.0, -1.0))
    c.update(pose, LaserScan(ranges, angles, 10.0))
    assert np.any(c.logodds != a.logodds)


def test_range_min_beams_do_not_update_the_map():
    m = OccupancyMapper((1, 40), 0.1)
    m.update(np.array([0.05, 0.05, 0.0]), LaserScan(np.array([0.05]), np.zeros(1), 3.0, range_min_m=0.1))
    assert not m.logodds.any()


def test_no_return_policy():
    """clear_no_return=False drops only no-return beams; a real return beyond max_range_m clears up to it."""
    pose = np.array([0.05, 0.05, 0.0])
    params = OccupancyParams(max_range_m=1.0, clear_no_return=False)
    far = OccupancyMapper((1, 40), 0.1, params=params)
    far.update(pose, LaserScan(np.array([2.5]), np.zeros(1), 3.0))  # return at 2.5 m, limit 1 m
    lo = far.logodds[0]
    assert np.all(lo[:11] < 0) and not lo[11:].any()  # cleared up to 1.0 m, nothing marked
    none = OccupancyMapper((1, 40), 0.1, params=params)
    none.update(pose, LaserScan(np.array([3.0]), np.zeros(1), 3.0))  # no return: no update at all
    assert not none.logodds.any()
    cleared = OccupancyMapper((1, 40), 0.1, params=OccupancyParams(max_range_m=1.0))
    cleared.update(pose, LaserScan(np.array([3.0]), np.zeros(1), 3.0))  # default: no return clears to the limit
    np.testing.assert_array_equal(cleared.logodds, far.logodds)


def test_scans_and_maps_own_their_arrays():
    # a new user's trial: a ROS-style loop that reuses one buffer changed every scan built from it, and a
    # GridMap made the caller's array read-only and kept a view of it
    angles = np.linspace(-np.pi, np.pi, 60, endpoint=False)
    buf = np.ones(60)
    scan = LaserScan(buf, angles, 8.0)
    buf[:5] = np.nan
    buf[5:10] = -3.0
    assert np.all(scan.ranges == 1.0) and buf.flags.writeable
    labels = np.ones(60, np.int64)
    sem = SemanticScan(np.full(60, 2.0), angles, labels, 4.5)
    labels[:] = 0
    assert np.all(sem.labels == 1)
    occ = np.zeros((10, 10), np.float32)
    grid = GridMap(occ, 0.1)
    assert occ.flags.writeable
    occ[0, 0] = 1.0
    assert grid.occupancy[0, 0] == 0.0 and not grid.occupied_mask().any()
    assert GridMap(grid.occupancy, 0.1).occupancy is grid.occupancy  # a map's own array is not copied again
    mount = np.array([0.1, 0.0, 0.0])
    mounted = LaserScan(np.ones(60), angles, 8.0, sensor_pose=mount)
    mount[0] = 7.0
    assert mounted.sensor_pose[0] == 0.1
    assert LaserScan(np.ones(60), angles, 5.0, range_min_m=np.int64(0)).range_min_m == 0.0
    with pytest.raises(ValueError, match="range_min_m"):
        LaserScan(np.ones(60), angles, 5.0, range_min_m=True)
    with pytest.raises(ValueError, match="range_max_m must be a number, got str"):
        LaserScan(np.ones(60), angles, "5")


def test_simulated_scans_check_pose_and_rng():
    from filters.simulators.grid_raycast import simulate_lidar

    grid = GridMap(np.zeros((20, 20), np.float32), 0.1)
    angles = np.linspace(-1, 1, 8)
    with pytest.raises(ValueError, match="pose must be 3 finite numbers"):
        simulate_lidar(grid, [np.nan, 1.0, 0.0], angles, 5.0)
    with pytest.raises(TypeError, match="needs rng"):
        simulate_lidar(grid, [1.0, 1.0, 0.0], angles, 5.0, noise_std_m=0.1)


def test_from_ros_checks_its_numbers_as_the_constructor_does():
    # a new user's trial: range_max=True became 1.0 m, and a 2-D ranges array was flattened silently
    with pytest.raises(ValueError, match="range_max must be a number, got bool"):
        LaserScan.from_ros([1.0, 2.0], 0.0, 0.1, 0.0, True)
    with pytest.raises(ValueError, match=r"ranges must be 1-D .* got shape \(2, 2\)"):
        LaserScan.from_ros([[1.0, 2.0], [3.0, 4.0]], 0.0, 0.1, 0.0, 10.0)
