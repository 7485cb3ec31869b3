"""semreloc_env.lookalike: the place that looks most like a pose (the target of look-alike kidnappings)."""

import math

import gymnasium as gym
import numpy as np
import pytest

import semreloc_env  # noqa: F401
from agents.relocalizer_eval import twin_image
from semreloc_env.layouts import CLASS_NAMES
from semreloc_env.lookalike import all_round_views, lookalike_pose, view_mismatch

# two closed 10 m x 5 m rooms side by side, the same chair and bin in each: every view in one is seen in the other
TWO_SAME_ROOMS = {
    "outer": [[0, 0], [20, 0], [20, 5], [0, 5]],
    "walls": [[[10, 0], [10, 5]]],
    "objects": [
        {"class": "chair", "center": [3, 1], "size": [0.5, 0.5]},
        {"class": "trash_bin", "center": [7, 3.5], "size": [0.4, 0.4]},
        {"class": "chair", "center": [13, 1], "size": [0.5, 0.5]},
        {"class": "trash_bin", "center": [17, 3.5], "size": [0.4, 0.4]},
    ],
}


def _world(layout):
    env = gym.make("SemReloc-v22", layout=layout, map_source="perfect").unwrapped
    env.reset(seed=0)
    return env.world


def test_an_exact_lookalike_is_found_with_its_heading():
    world = _world(TWO_SAME_ROOMS)
    for pose in ([2.0, 3.0, 0.4], [15.5, 2.0, -2.0]):
        found = lookalike_pose(world, pose, np.random.default_rng(0))
        shifted = pose[0] + (10.0 if pose[0] < 10 else -10.0)
        assert found.mismatch_m < 0.15 and abs(found.distance_m - 10.0) < 0.1
        assert math.dist(found.pose[:2], [shifted, pose[1]]) < 0.1
        assert abs(math.remainder(found.pose[2] - pose[2], 2 * math.pi)) < math.radians(2)
        assert -math.pi <= found.pose[2] < math.pi and world.is_free(found.pose[:2])
        assert view_mismatch(world, pose, found.pose) == pytest.approx(found.mismatch_m, abs=0.02)
        assert view_mismatch(world, pose, pose) == 0.0


def test_in_twin_rooms_the_lookalike_is_the_half_turned_image_and_classes_count():
    world = _world("twin_rooms")
    for k in range(3):
        pose = world.sample_free_pose(np.random.default_rng(k), 0.3)
        found = lookalike_pose(world, pose, np.random.default_rng(1))
        twin = twin_image("twin_rooms", pose)
        assert math.dist(found.pose[:2], twin[:2]) < 0.1
        # the same shapes, other classes: the mismatch is the label term's, well above an exact look-alike's
        assert 0.3 < found.mismatch_m <= view_mismatch(world, pose, twin) + 0.05
    a = lookalike_pose(world, pose, np.random.default_rng(5))
    b = lookalike_pose(world, pose, np.random.default_rng(5))
    assert np.array_equal(a.pose, b.pose) and a.mismatch_m == b.mismatch_m  # seeded


def test_views_see_object_classes_within_the_camera_range_only():
    world = _world(TWO_SAME_ROOMS)
    r, lab = all_round_views(world, np.array([[3.0, 2.0]]), 8.0, 4.5, n_beams=360)
    down = 90  # the ray at -pi/2 (beam k at angle 2 pi k / 360 - pi) hits the chair 0.75 m below
    assert r.shape == lab.shape == (1, 360) and r[0, down] == pytest.approx(0.75)
    assert lab[0, down] == CLASS_NAMES.index("chair") + 1
    far, lab_far = all_round_views(world, np.array([[3.0, 2.0]]), 8.0, 0.5, n_beams=360)
    assert lab_far[0, down] == 0 and far[0, down] == pytest.approx(0.75)  # beyond the camera's range: a range only


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"pose": [1.0, 2.0]}, "three finite numbers"),
        ({"pose": [1.0, float("nan"), 0.0]}, "three finite numbers"),
        ({"min_distance_m": -1.0}, "min_distance_m must be a finite number >= 0"),
        ({"candidates": 0}, "candidates must be an integer >= 1"),
        ({"n_beams": 4}, "n_beams must be an integer >= 8"),
        ({"min_distance_m": 100.0}, "no free place 100.0 m or more"),
    ],
)
def test_bad_arguments_are_refused(kwargs, match):
    world = _world(TWO_SAME_ROOMS)
    kw = {"pose": [2.0, 3.0, 0.0], **kwargs}
    with pytest.raises(ValueError, match=match):
        lookalike_pose(world, kw.pop("pose"), np.random.default_rng(0), **kw)


def test_a_lookalike_kidnap_goes_half_as_far_where_no_place_is_3_m_away_each_try_from_the_generator_as_given():
    """`lookalike_kidnap`: in a room with no free place 3 m from the pose it tries 1.5 m, 0.75 m, ... (0.375 m
    at least), each try drawing from the generator in the state it was given, so the place it finds is
    `lookalike_pose`'s at that distance with a fresh generator of the same seed."""
    from semreloc_env.lookalike import KIDNAP_MIN_DISTANCE_M, NoPlaceError, lookalike_kidnap

    small = {"outer": [[0, 0], [3.2, 0], [3.2, 2.6], [0, 2.6]], "walls": [], "objects": []}
    world = _world(small)
    pose = [0.8, 1.3, 0.0]
    ranges = {"max_range_m": 8.0, "camera_range_m": 4.5}
    with pytest.raises(NoPlaceError):
        lookalike_pose(world, pose, np.random.default_rng(3), min_distance_m=KIDNAP_MIN_DISTANCE_M, **ranges)
    found = lookalike_kidnap(world, pose, np.random.default_rng(3), **ranges)
    least = next(d for d in (1.5, 0.75, 0.375) if found.distance_m >= d)
    direct = lookalike_pose(world, pose, np.random.default_rng(3), min_distance_m=least, **ranges)
    np.testing.assert_array_equal(found.pose, direct.pose)
    assert 0.375 <= found.distance_m < KIDNAP_MIN_DISTANCE_M and world.is_free(found.pose[:2])
