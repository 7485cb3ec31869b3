"""filters.slam.metrics (landmark errors, both directions) and car_sim.run_slam (the SLAM drive loop)."""

import math

import numpy as np
import pytest

from filters.motion.velocity import BicycleModel
from filters.simulators.car_sim import CarSimConfig, run_slam, simulate, small_course
from filters.slam.association import AssociationConfig
from filters.slam.fastslam import FastSLAM, FastSLAMConfig
from filters.slam.landmarks import RangeBearingNoise
from filters.slam.metrics import map_landmark_errors, true_landmark_errors

TRUE = np.array([[0.0, 0.0], [10.0, 0.0], [0.0, 5.0]])


def test_map_landmark_errors_by_id_and_nearest():
    est = np.array([[0.0, 1.0], [13.0, 4.0]])
    np.testing.assert_allclose(map_landmark_errors(est, [0, 1], TRUE, True), [1.0, 5.0])
    # without ids: the nearest true landmark ([0, 1] is 1 m from [0, 0]; [13, 4] is 5 m from [10, 0])
    np.testing.assert_allclose(map_landmark_errors(est, [2, 2], TRUE, False), [1.0, 5.0])
    assert map_landmark_errors(np.zeros((0, 2)), [], TRUE, False).shape == (0,)


def test_true_landmark_errors_count_unmapped_as_inf():
    est = np.array([[10.0, 3.0]])
    d = true_landmark_errors(est, [1], TRUE, [0, 1], True)
    assert d[0] == math.inf and d[1] == pytest.approx(3.0)
    np.testing.assert_allclose(true_landmark_errors(est, [1], TRUE, [1, 2], False), [3.0, math.hypot(10, 2)])
    assert np.all(np.isinf(true_landmark_errors(np.zeros((0, 2)), [], TRUE, [0, 2], False)))


def test_landmark_errors_bad_input():
    with pytest.raises(ValueError, match="est_xy"):
        map_landmark_errors(np.zeros((2, 3)), [0, 1], TRUE, True)
    with pytest.raises(ValueError, match="est_ids"):
        map_landmark_errors(np.zeros((2, 2)), [0], TRUE, True)
    with pytest.raises(ValueError, match="est_ids must index"):
        map_landmark_errors(np.zeros((1, 2)), [3], TRUE, True)
    with pytest.raises(ValueError, match="which"):
        true_landmark_errors(np.zeros((1, 2)), [0], TRUE, [5], True)


def test_run_slam_matches_a_hand_written_loop_and_calls_back_per_scan():
    cfg = CarSimConfig(max_steps=300)
    run = simulate(cfg, small_course(), np.random.default_rng(2))
    motion = BicycleModel(cfg.wheelbase_m, cfg.sigma_v_mps, cfg.sigma_g_rad)
    noise = RangeBearingNoise(cfg.sigma_r_m, cfg.sigma_b_rad)
    fcfg = FastSLAMConfig(n_particles=10, association=AssociationConfig(mode="known"))

    seen = []
    a = FastSLAM(motion, noise, fcfg, np.random.default_rng(1))
    err = run_slam(a, run, lambda f, t: seen.append(t))
    assert seen == [int(t) for t in run.obs_steps] and err.shape == (len(run.obs_steps),)

    b = FastSLAM(motion, noise, fcfg, np.random.default_rng(1))
    want, scans = [], run.scans_by_step()
    for t in range(run.n_steps):
        b.predict(run.controls[t], run.dt_control_s)
        if t in scans:
            b.update(*scans[t])
            want.append(np.linalg.norm(b.estimate().pose[:2] - run.true_poses[t + 1, :2]))
    np.testing.assert_allclose(err, want, rtol=1e-12)
    np.testing.assert_array_equal(a.estimate().landmarks, b.estimate().landmarks)
