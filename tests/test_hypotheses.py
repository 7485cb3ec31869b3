"""Hypotheses in the belief, the converged rule, clustered resampling, proposals and recovery."""

import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from filters.localization.belief import BeliefConfig, cluster_labels, summarize
from filters.localization.mcl import MCLConfig, MonteCarloLocalizer
from filters.localization.proposals import ScanProposal, detection_runs, prior_mass_near
from filters.pose import compose, wrap_angle
from filters.robot_data.scans import SemanticScan
from filters.simulators.grid_raycast import simulate_lidar, simulate_semantic
from tests.test_mcl import CAMERA_ANGLES, LIDAR_ANGLES, drive, mirror, symmetric_room


def blob(rng, centre, n, std_xy=0.05, std_th=0.02):
    p = np.asarray(centre, float) + rng.normal(0.0, 1.0, (n, 3)) * [std_xy, std_xy, std_th]
    p[:, 2] = (p[:, 2] + np.pi) % (2 * np.pi) - np.pi
    return p


def test_two_clusters_give_two_hypotheses_sorted_by_weight():
    rng = np.random.default_rng(0)
    a, b = blob(rng, [1.0, 1.0, 0.5], 300), blob(rng, [6.0, 3.0, -2.0], 100)
    w = np.concatenate([np.full(300, 1.0), np.full(100, 2.0)])  # b: 200 of 500 units of mass
    bel = summarize(np.vstack([a, b]), w)
    assert bel.n_clusters == 2 and len(bel.hypotheses) == 2
    h0, h1 = bel.hypotheses
    assert h0.weight == pytest.approx(0.6) and h1.weight == pytest.approx(0.4)
    assert h0.n_particles == 300 and h1.n_particles == 100
    np.testing.assert_allclose(h0.mean, [1.0, 1.0, 0.5], atol=0.02)
    np.testing.assert_allclose(h1.mean, [6.0, 3.0, -2.0], atol=0.02)
    assert h0.pos_std_m < 0.1 and h1.theta_std_rad < 0.05
    np.testing.assert_allclose(bel.estimate, h0.mean)  # the estimate is the heaviest hypothesis
    d = bel.as_dict()
    assert [h["weight"] for h in d["hypotheses"]] == pytest.approx([0.6, 0.4])
    assert len(d["hypotheses"][0]["cov"]) == 3 and d["estimate"] == pytest.approx(list(h0.mean))


def test_converged_needs_one_hypothesis_with_nearly_all_the_mass():
    rng = np.random.default_rng(1)
    a, b = blob(rng, [1.0, 1.0, 0.0], 400), blob(rng, [6.0, 3.0, 0.0], 400)
    two = summarize(np.vstack([a, b]), np.ones(800))
    assert not two.converged  # each part is tight, but the mass is split
    assert two.best.pos_std_m < 0.1
    assert summarize(a, np.ones(400)).converged  # one removed: converged
    w = np.concatenate([np.ones(400), np.full(400, 0.04 / 0.96 / 1.0)])  # 4 % on the second place
    assert summarize(np.vstack([a, b]), w).converged
    w = np.concatenate([np.ones(400), np.full(400, 0.1)])  # 9 % on the second place
    assert not summarize(np.vstack([a, b]), w).converged
    spread = BeliefConfig(converged_rule="spread")  # the first release's rule, for comparisons
    assert not summarize(np.vstack([a, b]), np.ones(800), spread).converged
    assert summarize(a, np.ones(400), spread).converged


def test_a_cluster_across_the_heading_seam_is_one_hypothesis():
    rng = np.random.default_rng(2)
    seam = blob(rng, [2.0, 2.0, np.pi], 500, std_th=0.05)  # half at +pi, half at -pi
    assert (seam[:, 2] > 3.0).any() and (seam[:, 2] < -3.0).any()
    bel = summarize(seam, np.ones(500))
    assert bel.n_clusters == 1 and bel.converged
    assert abs(abs(bel.best.mean[2]) - np.pi) < 0.02
    # same place, opposite headings: two hypotheses
    flip = np.vstack([blob(rng, [2.0, 2.0, 0.0], 300), blob(rng, [2.0, 2.0, np.pi], 300)])
    assert summarize(flip, np.ones(600)).n_clusters == 2


def test_a_haze_of_unlikely_particles_does_not_join_two_hypotheses():
    rng = np.random.default_rng(3)
    a, b = blob(rng, [1.0, 1.0, 0.0], 400), blob(rng, [5.0, 1.0, 0.0], 400)
    haze = np.column_stack([rng.uniform(0, 6, 4000), rng.uniform(0, 2, 4000), rng.uniform(-np.pi, np.pi, 4000)])
    poses = np.vstack([a, b, haze])
    w = np.concatenate([np.ones(800), np.full(4000, 1e-6)])
    labels, n = cluster_labels(poses, 0.5, math.pi / 4)  # every particle counts: one blob of haze
    assert n < 10 and labels.min() == 0
    bel = summarize(poses, w)
    assert bel.n_clusters == 2 and bel.hypotheses[0].weight == pytest.approx(0.5, abs=0.01)


def test_clustered_resampling_keeps_a_weak_hypothesis_and_its_weight():
    grid = symmetric_room()
    rng = np.random.default_rng(4)
    cfg = MCLConfig(n_particles=1000, resample_mode="clustered", cluster_min_particles=50, resample_ess_frac=1.0)
    mcl = MonteCarloLocalizer(grid, cfg, np.random.default_rng(5))
    strong, weak = blob(rng, [3.0, 2.5, 0.0], 990), blob(rng, [7.0, 2.5, np.pi], 10)
    mcl._set(np.vstack([strong, weak]))
    w = np.concatenate([np.full(990, 0.995 / 990), np.full(10, 0.005 / 10)])
    mcl._resample_now(w)
    bel = mcl.belief()
    assert bel.n_clusters == 1  # 0.5 % is below cluster_min_weight: no listed hypothesis ...
    near_weak = np.hypot(mcl.poses[:, 0] - 7.0, mcl.poses[:, 1] - 2.5) < 0.5
    assert near_weak.sum() == 50  # ... but it keeps cluster_min_particles particles
    assert mcl.weights[near_weak].sum() == pytest.approx(0.005, rel=1e-6)  # and its weight
    glob = MonteCarloLocalizer(grid, MCLConfig(n_particles=1000), np.random.default_rng(5))
    glob._set(np.vstack([strong, weak]))
    glob._resample_now(w)
    assert np.hypot(glob.poses[:, 0] - 7.0, glob.poses[:, 1] - 2.5).__lt__(0.5).sum() <= 10


def test_clustered_resampling_with_keep_weight_zero_skips_empty_groups():
    # cluster_keep_weight = 0 is allowed; with every particle in one cluster the haze group is
    # empty (weight 0) and used to be drawn from (IndexError in the CDF of no particles)
    grid = symmetric_room()
    cfg = MCLConfig(n_particles=500, resample_mode="clustered", cluster_keep_weight=0.0)
    mcl = MonteCarloLocalizer(grid, cfg, np.random.default_rng(5))
    mcl._set(np.tile([3.0, 2.5, 0.0], (500, 1)))
    poses, logw = mcl._clustered(np.full(500, 1 / 500), 400)
    assert poses.shape == (400, 3) and np.allclose(poses, [3.0, 2.5, 0.0])
    assert np.exp(logw).sum() == pytest.approx(1.0)


def test_detection_runs_and_a_proposal_from_a_unique_object_lands_near_the_truth():
    grid = symmetric_room()  # the cabinet is the only object of its class
    pose = np.array([3.5, 1.5, np.pi])  # facing the cabinet (x 2.0-2.5, y 1.0-2.0)
    sem = simulate_semantic(grid, pose, CAMERA_ANGLES, 5.0)
    runs = detection_runs(sem)
    assert len(runs) == 1 and runs[0][0] == 1 + grid.class_names.index("cabinet")
    assert 0.9 < runs[0][1] < 1.6  # about 1 m to the cabinet's face
    rng = np.random.default_rng(6)
    prop = ScanProposal(grid, lambda n: np.zeros((n, 3)))
    cand = prop.candidates(4000, sem, 1.0, rng)
    assert cand.shape == (4000, 3)
    lidar = simulate_lidar(grid, pose, LIDAR_ANGLES, 8.0)
    mcl = MonteCarloLocalizer(grid, MCLConfig(), np.random.default_rng(7))
    ll_l, ll_s, _ = mcl.measurement_model.log_likelihood_terms(cand, lidar, sem)
    drawn = prop.draw(200, cand, 0.1 * (ll_l + ll_s), rng)
    err = np.hypot(drawn[:, 0] - pose[0], drawn[:, 1] - pose[1])
    assert np.median(err) < 0.3  # the proposal finds the pose, not its mirror image
    mirror_err = np.hypot(drawn[:, 0] - (10 - pose[0]), drawn[:, 1] - (5 - pose[1]))
    assert (mirror_err < 0.5).mean() < 0.05
    assert detection_runs(SemanticScan(np.full(5, 9.0), np.linspace(-0.3, 0.3, 5), np.zeros(5, int), 5.0)) == []


@pytest.mark.parametrize("sensor_pose", [(0.0, 0.0, math.pi), (0.25, -0.1, 0.7), (-0.2, 0.15, -2.0)])
def test_a_mounted_camera_proposes_where_its_detection_fits(sensor_pose):
    """A camera mounted off the robot's centre or turned: candidates from its detection put the
    detected object where the map has it (its ranges and bearings are in the sensor's frame), as
    candidates from the same rays of a camera at the centre do."""
    grid = symmetric_room()  # the cabinet is the only object of its class
    sensor = np.array([3.5, 1.5, np.pi])  # the camera facing the cabinet (x 2.0-2.5, y 1.0-2.0)
    mount = np.asarray(sensor_pose)
    x, y, t = mount
    robot = compose(sensor, [-x * math.cos(t) - y * math.sin(t), x * math.sin(t) - y * math.cos(t), -t])
    back = compose(robot, mount)
    assert np.allclose(back[:2], sensor[:2]) and abs(wrap_angle(back[2] - sensor[2])) < 1e-9
    seen = simulate_semantic(grid, sensor, CAMERA_ANGLES, 5.0)  # ranges and bearings in the sensor's frame
    mounted = SemanticScan(seen.ranges, seen.angles, seen.labels, 5.0, sensor_pose=mount)
    cabinet = 1 + grid.class_names.index("cabinet")
    assert [r[0] for r in detection_runs(mounted)] == [cabinet]
    prop = ScanProposal(grid, lambda n: np.zeros((n, 3)), range_jitter_m=0.0)
    cand = prop.candidates(3000, mounted, 1.0, np.random.default_rng(1))
    cand = cand[np.any(cand != 0.0, axis=1)]  # the semantic candidates (the rest are the stub's zeros)
    assert cand.shape[0] > 1000
    label, r, a = detection_runs(mounted)[0]
    ends = np.array([compose(compose(c, mount), [r * math.cos(a), r * math.sin(a), 0.0])[:2] for c in cand])
    row, col = grid.world_to_cell(ends)
    near = np.zeros(len(ends), bool)
    for dr in (-1, 0, 1):  # within a cell of a cabinet cell (candidates are jittered by half a cell)
        for dc in (-1, 0, 1):
            rr, cc = row + dr, col + dc
            ok = grid.in_bounds(rr, cc)
            near[ok] |= grid.class_mask(cabinet - 1)[rr[ok], cc[ok]]
    assert near.all()
    at_robot = (np.hypot(*(cand[:, :2] - robot[:2]).T) < 0.3) & (np.abs(wrap_angle(cand[:, 2] - robot[2])) < 0.2)
    assert at_robot.sum() > 30  # some at the robot's own pose


def test_augmented_injection_rises_right_after_a_kidnap():
    grid = symmetric_room()
    rng = np.random.default_rng(8)
    cfg = MCLConfig(n_particles=500, augmented=True, injection="scan")
    mcl = MonteCarloLocalizer(grid, cfg, np.random.default_rng(9))
    pose = np.array([4.0, 1.5, np.pi])
    mcl.init_around(pose, [0.05, 0.05, 0.02])
    pose = drive(grid, pose, mcl, rng, steps=30)
    assert mcl.belief().converged and mcl.last_diagnostics.w_slow > 0
    kidnapped = np.array([8.5, 1.0, 0.5 * np.pi])
    p, injected = [], 0
    for _ in range(12):
        mcl.predict([0.0, 0.0, 0.2])
        kidnapped = compose(kidnapped, [0.0, 0.0, 0.2])
        d = mcl.update(
            simulate_lidar(grid, kidnapped, LIDAR_ANGLES, 8.0, 0.02, rng),
            simulate_semantic(grid, kidnapped, CAMERA_ANGLES, 5.0),
        )
        p.append(d.p_inject)
        injected += d.n_injected
    assert max(p[:3]) > 0.03 and injected > 0  # the likelihood drop triggers injection at once
    err = np.hypot(*(mcl.belief().estimate[:2] - kidnapped[:2]))
    assert err < 0.5  # scan proposals brought the filter back


def test_global_particle_count_follows_the_free_area_and_kld_bounds_hold():
    grid = symmetric_room()  # about 49 m^2 free
    by_map = {"n_particles": None, "global_particles_per_m2": 100, "min_particles": 400, "max_particles": 20000}
    mcl = MonteCarloLocalizer(grid, MCLConfig(**by_map), np.random.default_rng(0))
    assert 45 < mcl.free_area_m2 < 50
    assert mcl.global_particle_count() == round(100 * mcl.free_area_m2)
    mcl.init_global()
    assert mcl.n_particles == mcl.global_particle_count()
    mcl.init_around([4.0, 1.5, 0.0], 0.1)
    assert mcl.n_particles == 400  # a tight cloud starts at the KLD floor
    capped = MonteCarloLocalizer(
        grid, MCLConfig(**{**by_map, "global_particles_per_m2": 1000, "max_particles": 8000}), np.random.default_rng(0)
    )
    assert capped.global_particle_count() == 8000
    floor = MonteCarloLocalizer(grid, MCLConfig(**{**by_map, "global_particles_per_m2": 1}), np.random.default_rng(0))
    assert floor.global_particle_count() == 400
    fixed = MonteCarloLocalizer(
        grid, MCLConfig(n_particles=3000, global_particles_per_m2=100), np.random.default_rng(0)
    )
    assert fixed.global_particle_count() == 3000  # an explicit count wins
    with pytest.raises(ValueError, match="global_particles_per_m2"):
        MCLConfig(n_particles=None)
    cfg = MCLConfig(kld=True, min_particles=300, max_particles=6000, resample_mode="clustered", resample_ess_frac=1.0)
    k = MonteCarloLocalizer(grid, cfg, np.random.default_rng(1))
    rng = np.random.default_rng(2)
    pose = np.array([4.0, 1.5, np.pi])
    k.init_global(6000)
    for _ in range(8):
        d = k.update(simulate_lidar(grid, pose, LIDAR_ANGLES, 8.0, 0.02, rng), force=True)
        assert 300 <= d.n_particles <= 6000 + 50 * 20  # clustered: each kept cluster adds at most its floor
    assert d.n_particles < 3000


@pytest.mark.parametrize(
    "bad",
    [
        {"resample_mode": "nope"},
        {"injection": "gps"},
        {"proposal_frac": 1.5},
        {"proposal_weight": 0.0},
        {"proposal_weight": 1.5},
        {"proposal_weight": -1},
        {"proposal_weight": float("nan")},
        {"proposal_weight": True},
        {"proposal_weight": "0.5"},
        {"proposal_prior_weight": 1.5},
        {"proposal_prior_weight": -0.1},
        {"proposal_prior_weight": float("nan")},
        {"proposal_prior_weight": True},
        {"likelihood_scale": "a"},
        {"update_min_d_m": None},
        {"resampler": ["x"]},
        {"alpha_fast": 0},
        {"global_particles_per_m2": -1},
        {"global_particles_per_m2": float("nan")},
        {"max_update_log_ratio": 0},
        {"lidar_on_rotation": "no"},
        {"cluster_min_particles": 0},
        {"belief": {"converged_rule": "maybe"}},
        {"belief": {"converged_min_weight": 2.0}},
    ],
)
def test_bad_relocalizer_options_are_rejected(bad):
    key = next(iter(bad))
    if isinstance(bad[key], dict):  # a sub-config: its own field is named
        key = next(iter(bad[key]))
    with pytest.raises((ValueError, TypeError), match=key):
        MCLConfig(**bad)


def test_numpy_numbers_are_accepted_as_plain_numbers():
    c = MCLConfig(proposal_frac=np.float32(0.5), holdoff_min_detections=np.int64(3))
    assert type(c.proposal_frac) is float and c.proposal_frac == 0.5
    assert type(c.holdoff_min_detections) is int and c.holdoff_min_detections == 3
    c = MCLConfig(n_particles=np.int64(300), max_particles=np.int64(900))
    assert type(c.n_particles) is int and type(c.max_particles) is int
    json.dumps(c.as_dict())


@pytest.mark.parametrize("recovery", [False, True])
def test_routine_proposals_carry_proposal_weight_and_recoveries_a_full_share(recovery):
    grid = symmetric_room()
    cfg = MCLConfig(n_particles=400, injection="uniform", proposal_frac=0.2, proposal_weight=0.25)
    mcl = MonteCarloLocalizer(grid, cfg, np.random.default_rng(3))
    mcl.init_global()
    before = mcl.poses.copy()
    m = mcl._inject(0.2, None, None, recovery=recovery)
    w = mcl.weights
    fresh = np.any(mcl.poses != before, axis=1)
    assert 0 < m == fresh.sum() < 400 and w.sum() == pytest.approx(1.0)
    ratio = w[fresh].mean() / w[~fresh].mean()
    assert ratio == pytest.approx(1.0 if recovery else 0.25)


def test_update_gives_routine_proposals_their_weight():
    # Through `update`: two filters alike but for proposal_weight draw the same particles; the
    # injected ones weigh 0.25 of their counterparts relative to the rest (no augmented MCL, so
    # every injection is routine).
    grid = symmetric_room()
    pose = np.array([4.0, 1.5, np.pi])
    lidar = simulate_lidar(grid, pose, LIDAR_ANGLES, 8.0)
    sem = simulate_semantic(grid, pose, CAMERA_ANGLES, 5.0)
    w = {}
    for pw in (1.0, 0.25):
        cfg = MCLConfig(n_particles=400, injection="scan", proposal_frac=0.1, proposal_weight=pw, resample_ess_frac=0.0)
        mcl = MonteCarloLocalizer(grid, cfg, np.random.default_rng(5))
        mcl.init_global()
        d = mcl.update(lidar, sem, force=True)
        assert d.n_injected > 0 and not d.resampled
        w[pw] = (mcl.poses.copy(), mcl.weights)
    np.testing.assert_array_equal(w[1.0][0], w[0.25][0])
    ratio = w[0.25][1] / w[1.0][1]
    low = ratio < ratio.max() * 0.5
    assert low.sum() == d.n_injected
    np.testing.assert_allclose(ratio[low] / ratio[~low].mean(), 0.25, rtol=1e-9)


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    n=st.integers(0, 60),
    m=st.integers(0, 20),
    bin_xy=st.sampled_from([0.25, 0.5, 1.3]),
    bin_th=st.sampled_from([math.pi / 4, 2.0, math.pi, 2 * math.pi]),
)
def test_prior_mass_near_sums_the_weight_in_the_neighbouring_bins(seed, n, m, bin_xy, bin_th):
    import filters.localization.proposals as proposals

    rng = np.random.default_rng(seed)
    prior = np.column_stack([rng.uniform(-3, 3, n), rng.uniform(-3, 3, n), rng.uniform(-4, 4, n)])
    query = np.column_stack([rng.uniform(-3, 3, m), rng.uniform(-3, 3, m), rng.uniform(-4, 4, m)])
    w = rng.random(n)
    got = prior_mass_near(prior, w, query, bin_xy, bin_th)
    dense_cells = proposals._MAX_DENSE_CELLS
    try:  # the path for bounding boxes too large to raster: the same sums
        proposals._MAX_DENSE_CELLS = 0
        sparse = prior_mass_near(prior, w, query, bin_xy, bin_th)
    finally:
        proposals._MAX_DENSE_CELLS = dense_cells
    np.testing.assert_allclose(sparse, got, rtol=1e-12, atol=1e-12)
    n_t = max(1, round(2 * math.pi / bin_th))

    def cell(p):  # one pose at a time, as a reader would compute it
        t = min(int(math.floor((math.remainder(p[2], 2 * math.pi) + math.pi) * n_t / (2 * math.pi))), n_t - 1)
        return math.floor(p[0] / bin_xy), math.floor(p[1] / bin_xy), t

    want = np.zeros(m)
    for j in range(m):
        qx, qy, qt = cell(query[j])
        for i in range(n):
            px, py, pt = cell(prior[i])
            dt = min((pt - qt) % n_t, (qt - pt) % n_t)
            if abs(px - qx) <= 1 and abs(py - qy) <= 1 and dt <= 1:
                want[j] += w[i]
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12)


def test_routine_proposals_at_a_look_alike_place_the_belief_left_weigh_by_the_prior():
    """Tracking in the half-turn symmetric room with the lidar alone: the scan fits the pose and its
    half-turned image equally, so the routine scan proposals land at both. Weighed evenly (0) those
    at the image get an average weight at every update; scaled by ``1 - lam + lam * near`` (the
    prior holds nothing there) half of it with 0.5 and nothing with 1, relative to the particles
    the injection kept; those at the pose, where the prior holds everything, keep theirs."""
    grid = symmetric_room()
    pose = np.array([3.0, 2.5, 0.3])
    lidar = simulate_lidar(grid, pose, LIDAR_ANGLES, 8.0)
    image = mirror(pose)[:2]
    ratio, runs = {}, {}
    for lam in (0.0, 0.5, 1.0):
        cfg = MCLConfig(
            n_particles=400,
            injection="scan",
            proposal_frac=0.3,
            proposal_prior_weight=lam,
            proposal_candidates=4000,
            use_semantic=False,
            resample_ess_frac=0.0,
            likelihood_scale=0.03,  # flat enough that the proposals spread over both places
        )
        mcl = MonteCarloLocalizer(grid, cfg, np.random.default_rng(2))
        mcl.init_around(pose, (0.05, 0.05, 0.02))
        before = mcl.poses.copy()
        d = mcl.update(lidar, force=True)
        assert d.n_injected > 0 and not d.resampled
        fresh = np.any(mcl.poses != before, axis=1)
        at_image = np.hypot(*(mcl.poses[:, :2] - image).T) < 0.5
        at_pose = (np.hypot(*(mcl.poses[:, :2] - pose[:2]).T) < 0.5) & (
            np.abs(wrap_angle(mcl.poses[:, 2] - pose[2])) < 1.0
        )
        assert (fresh & at_image).sum() >= 5 and (fresh & at_pose).sum() >= 1  # proposals landed at both
        assert mcl.weights.sum() == pytest.approx(1.0)
        kept = mcl.weights[~fresh].mean()  # the same update weighed them, whatever lam
        ratio[lam] = (mcl.weights[fresh & at_image] / kept, mcl.weights[fresh & at_pose] / kept)
        runs[lam] = mcl.poses.copy()
    np.testing.assert_array_equal(runs[0.0], runs[1.0])  # the same draws: only the weights differ
    np.testing.assert_allclose(ratio[0.5][0], 0.5 * ratio[0.0][0], rtol=1e-9)
    assert np.all(ratio[1.0][0] == 0.0)
    np.testing.assert_allclose(ratio[1.0][1], ratio[0.0][1], rtol=0.05)  # near ~ 1 at the pose


def test_the_env_runs_with_routine_proposals_weighed_by_the_prior():
    """With the registered relocalizer (augmented MCL, scan proposals, KLD, clustered resampling)."""
    import gymnasium as gym

    import semreloc_env  # noqa: F401

    out = {}
    for lam in (0.0, 0.5):
        env = gym.make(
            "SemReloc-v22", map_source="perfect", relocalizer={"n_particles": 300, "proposal_prior_weight": lam}
        )
        obs, info = env.reset(seed=3)
        injected = 0
        for t in range(40):
            obs, r, term, trunc, info = env.step(t % 4)
            injected += info["mcl"]["n_injected"]
        out[lam] = (injected, info["belief"]["hypotheses"])
        env.close()
    assert out[0.0][0] > 0 and out[0.5][0] > 0
    assert out[0.0][1] != out[0.5][1]  # the weights differ, so the beliefs do


def test_scaling_never_leaves_the_set_without_weight():
    """lam = 1 with every particle replaced by proposals where the belief holds nothing (a review):
    the weights stayed NaN. Now the scaling is skipped for such an update."""
    grid = symmetric_room()
    cfg = MCLConfig(n_particles=50, injection="scan", proposal_frac=1.0, proposal_prior_weight=1.0, use_semantic=False)
    mcl = MonteCarloLocalizer(grid, cfg, np.random.default_rng(0))
    mcl.init_around([5.0, 2.5, 1.0], (0.02, 0.02, 0.01))  # where the scan below does not fit
    d = mcl.update(simulate_lidar(grid, np.array([2.0, 1.0, 0.0]), LIDAR_ANGLES, 8.0), force=True)
    assert d.n_injected == 50 and np.all(np.isfinite(mcl.weights)) and mcl.weights.sum() == pytest.approx(1.0)
    mcl.belief()  # raised on NaN weights
