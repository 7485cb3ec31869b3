import math

import numpy as np
import pytest

from filters.simulators.car_sim import CarSimConfig, default_course, observe, simulate, small_course


def _signed_area(poly: np.ndarray) -> float:
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def test_default_course_matches_the_described_layout():
    c = default_course()
    assert c.waypoints.shape == (15, 2)
    assert c.landmarks.shape == (31, 2)
    np.testing.assert_array_equal(c.start_pose, [0.0, 0.0, 0.0])
    pts = np.vstack([c.waypoints, c.landmarks])
    assert np.ptp(pts[:, 0]) <= 100.0 and np.ptp(pts[:, 1]) <= 80.0
    assert _signed_area(c.waypoints) < 0  # clockwise
    # the course itself has no randomness
    np.testing.assert_array_equal(default_course().landmarks, c.landmarks)


@pytest.mark.parametrize("course_fn", [small_course, default_course])
def test_follows_every_waypoint_in_order(course_fn):
    course = course_fn()
    cfg = CarSimConfig(n_loops=1)
    run = simulate(cfg, course, np.random.default_rng(0))
    reached = run.waypoint_reached
    assert np.all(reached >= 0), reached
    assert np.all(np.diff(reached) > 0)
    for k, t in enumerate(reached):  # within the acceptance distance when it switched
        d = np.hypot(*(run.true_poses[t, :2] - course.waypoints[k]))
        assert d < cfg.at_waypoint_m
    # speed and steering limits hold
    step = np.hypot(*np.diff(run.true_poses[:, :2], axis=0).T)
    np.testing.assert_allclose(step, cfg.speed_mps * cfg.dt_control_s, rtol=1e-9)
    g = run.controls_true[:, 1]
    assert np.all(np.abs(g) <= cfg.max_steer_rad + 1e-12)
    assert np.all(np.abs(np.diff(g)) <= cfg.max_steer_rate_radps * cfg.dt_control_s + 1e-12)


def test_same_seed_is_bit_identical_and_seeds_differ():
    cfg = CarSimConfig(max_steps=600)
    a = simulate(cfg, small_course(), np.random.default_rng(7))
    b = simulate(cfg, small_course(), np.random.default_rng(7))
    c = simulate(cfg, small_course(), np.random.default_rng(8))
    np.testing.assert_array_equal(a.controls, b.controls)
    for za, zb in zip(a.observations, b.observations, strict=True):
        np.testing.assert_array_equal(za, zb)
    assert not np.array_equal(a.controls, c.controls)
    np.testing.assert_array_equal(a.true_poses, c.true_poses)  # noise never reaches the true vehicle
    assert a.n_steps == 600


def test_noise_free_observations_are_exact_forward_and_in_range():
    cfg = CarSimConfig(n_loops=1, control_noise=False, sensor_noise=False)
    run = simulate(cfg, default_course(), np.random.default_rng(0))
    np.testing.assert_array_equal(run.controls, run.controls_true)
    assert np.all(np.diff(run.obs_steps) == cfg.observe_every) and cfg.observe_every == 8
    for t, z, ids in zip(run.obs_steps, run.observations, run.observation_ids, strict=True):
        pose = run.true_poses[t + 1]
        assert np.all(z[:, 0] < cfg.max_range_m)
        assert np.all(np.abs(z[:, 1]) < math.pi / 2)
        lm = run.landmarks[ids]
        np.testing.assert_allclose(pose[0] + z[:, 0] * np.cos(pose[2] + z[:, 1]), lm[:, 0], atol=1e-9)
        np.testing.assert_allclose(pose[1] + z[:, 0] * np.sin(pose[2] + z[:, 1]), lm[:, 1], atol=1e-9)
    assert sum(len(i) for i in run.observation_ids) > 0


def test_observe_respects_half_plane_and_range():
    lms = np.array([[10.0, 0.0], [-10.0, 0.0], [40.0, 0.0], [0.0, 5.0], [5.0, 5.0]])
    z, ids = observe(np.array([0.0, 0.0, 0.0]), lms, 30.0)
    np.testing.assert_array_equal(ids, [0, 4])
    np.testing.assert_allclose(z[1], [math.hypot(5, 5), math.pi / 4])


def test_config_rejects_bad_values():
    with pytest.raises(ValueError):
        CarSimConfig(speed_mps=0.0)
    with pytest.raises(ValueError):
        CarSimConfig(sigma_r_m=-1.0)
    with pytest.raises(ValueError):
        CarSimConfig(n_loops=0)
