import json
import math

import numpy as np
import pytest

from filters.localization.belief import BeliefConfig, summarize


def blob(rng, centre, n, std_xy=0.05, std_th=0.02):
    c = np.asarray(centre, dtype=float)
    p = c + rng.normal(0.0, 1.0, (n, 3)) * [std_xy, std_xy, std_th]
    p[:, 2] = (p[:, 2] + np.pi) % (2 * np.pi) - np.pi
    return p


def test_circular_mean_across_the_pi_seam():
    poses = np.array([[0.0, 0.0, np.pi - 0.1], [0.0, 0.0, -np.pi + 0.1]])
    b = summarize(poses, np.ones(2))
    assert abs(abs(b.mean[2]) - np.pi) < 1e-9  # not 0, as a naive mean would say
    assert -np.pi <= b.mean[2] < np.pi
    assert b.theta_std_rad == pytest.approx(0.1)  # wrapped residuals: +-0.1
    # weighted: the heavier particle pulls the mean towards itself
    b2 = summarize(poses, np.array([3.0, 1.0]))
    assert 0 < b2.mean[2] < np.pi and b2.mean[2] > np.pi - 0.1


def test_mean_and_covariance_of_weighted_particles():
    poses = np.array([[1.0, 2.0, 0.0], [3.0, 2.0, 0.0]])
    b = summarize(poses, np.array([1.0, 3.0]))
    np.testing.assert_allclose(b.mean, [2.5, 2.0, 0.0])
    assert b.cov[0, 0] == pytest.approx(0.25 * 1.5**2 + 0.75 * 0.5**2)
    assert b.cov[1, 1] == 0.0 and b.cov.shape == (3, 3)
    assert b.ess == pytest.approx(1 / (0.25**2 + 0.75**2))
    assert b.n_particles == 2


def test_converged_flag_follows_the_thresholds():
    rng = np.random.default_rng(0)
    tight = blob(rng, [1.0, 1.0, 3.1], 500)  # straddles the seam in heading
    b = summarize(tight, np.ones(500))
    assert b.converged and b.pos_std_m < 0.1 and b.theta_std_rad < 0.05
    wide = blob(rng, [1.0, 1.0, 0.0], 500, std_xy=0.5)
    assert not summarize(wide, np.ones(500)).converged
    turned = blob(rng, [1.0, 1.0, 0.0], 500, std_th=0.5)
    assert not summarize(turned, np.ones(500)).converged
    strict = BeliefConfig(converged_pos_std_m=0.01)
    assert not summarize(tight, np.ones(500), strict).converged


def test_cluster_count_and_entropy():
    rng = np.random.default_rng(1)
    one = blob(rng, [1.0, 1.0, 0.0], 400)
    two = np.vstack([one, blob(rng, [6.0, 3.0, 0.0], 400)])
    b1 = summarize(one, np.ones(400))
    b2 = summarize(two, np.ones(800))
    assert b1.n_clusters == 1
    assert b2.n_clusters == 2
    assert b2.entropy_nats > b1.entropy_nats + 0.5  # two equal blobs: about log 2 more
    # a few stray particles with negligible weight are not a hypothesis
    stray = np.vstack([two, [[9.0, 9.0, 0.0], [-5.0, 4.0, 1.0]]])
    w = np.concatenate([np.ones(800), [1e-3, 1e-3]])
    assert summarize(stray, w).n_clusters == 2
    # the second blob carries no weight: one cluster
    assert summarize(two, np.concatenate([np.ones(400), np.zeros(400)])).n_clusters == 1
    # every particle in one bin: zero entropy
    assert summarize(np.tile([[0.1, 0.1, 0.1]], (5, 1)), np.ones(5)).entropy_nats == 0.0


@pytest.mark.parametrize("backend", ["numba", "numpy"])
def test_a_belief_cannot_be_written_through_its_arrays(backend):
    """A Belief is frozen, its arrays too: the means and covariances (the hypotheses' share the arrays they are
    views of) refuse writes and refuse to become writable."""
    rng = np.random.default_rng(4)
    two = np.vstack([blob(rng, [1.0, 1.0, 0.0], 300), blob(rng, [6.0, 3.0, 0.0], 300)])
    b = summarize(two, rng.random(600), backend=backend)
    assert b.n_clusters == 2
    for h in b.hypotheses:
        assert type(h.weight) is float and type(h.n_particles) is int
    for a in [b.mean, b.cov, b.estimate] + [x for h in b.hypotheses for x in (h.mean, h.cov)]:
        with pytest.raises(ValueError, match="read-only"):
            a[0] = 1.0
    for h in b.hypotheses:
        with pytest.raises(ValueError, match="WRITEABLE"):
            h.mean.setflags(write=True)


def test_as_dict_is_plain_python_and_bad_input_raises():
    rng = np.random.default_rng(2)
    b = summarize(blob(rng, [0.0, 0.0, 0.0], 50), rng.random(50))
    d = b.as_dict()
    json.dumps(d)  # plain floats, ints, bools, lists
    assert isinstance(d["converged"], bool) and isinstance(d["n_clusters"], int)
    assert len(d["cov"]) == 3 and all(isinstance(v, float) for v in d["mean"])
    with pytest.raises(ValueError):
        summarize(np.zeros((0, 3)), np.zeros(0))
    with pytest.raises(ValueError):
        summarize(np.zeros((2, 3)), np.zeros(2))
    with pytest.raises(ValueError):
        summarize(np.zeros((2, 3)), np.array([1.0, math.nan]))
    with pytest.raises(TypeError):
        BeliefConfig(bin_m=0.5)


@pytest.mark.parametrize("name", ["cluster_bin_theta_rad", "entropy_bin_theta_rad"])
def test_heading_bins_narrower_than_a_tenth_of_a_degree_are_refused(name):
    # 1e-7 rad made 63 million heading bins: the NumPy clustering recursed without end, the compiled one raised
    # a SystemError
    from filters.localization.belief import MIN_BIN_THETA_RAD

    with pytest.raises(ValueError, match=f"{name} must be at least MIN_BIN_THETA_RAD"):
        BeliefConfig(**{name: 1e-7})
    cfg = BeliefConfig(**{name: MIN_BIN_THETA_RAD})
    rng = np.random.default_rng(0)
    p = np.concatenate([rng.normal([0.0, 0.0, 0.0], 1e-4, (150, 3)), rng.normal([2.0, 2.0, 1.0], 1e-4, (150, 3))])
    a, b = summarize(p, np.ones(300), cfg, backend="numba"), summarize(p, np.ones(300), cfg, backend="numpy")
    assert a.n_clusters > 1 and repr(a.as_dict(10**6)) == repr(b.as_dict(10**6))


def test_no_hypothesis_of_weight_zero_and_numpy_numbers_in_configs():
    # a twenty-third tester's: with both thresholds 0 a zero-weight cluster became a hypothesis (documented
    # weight: (0, 1]); BeliefConfig and OdometryMotionConfig refused NumPy numbers and took True
    from filters.localization.belief import BeliefConfig, summarize
    from filters.motion.odometry import OdometryMotionConfig

    cfg = BeliefConfig(cluster_min_weight=0.0, cluster_min_bin_frac=0.0)
    b = summarize(np.array([[0.0, 0, 0], [0.1, 0, 0], [5, 5, 2]]), np.array([1.0, 1, 0]), cfg)
    assert [h.weight for h in b.hypotheses] == [1.0]
    assert BeliefConfig(cluster_bin_m=np.float32(0.5)).cluster_bin_m == 0.5
    assert type(OdometryMotionConfig(alpha1=np.float64(0.1)).alpha1) is float
    with pytest.raises(ValueError, match="alpha1"):
        OdometryMotionConfig(alpha1=True)


def test_carried_belief_moves_means_and_covariances_with_the_odometry():
    from filters.localization.belief import carried
    from filters.pose import compose

    rng = np.random.default_rng(7)
    # two hypotheses, one 60/40: the carried means are the composed means, the covariances J cov J^T
    cloud = np.vstack([blob(rng, [2.0, 1.0, 0.4], 600, 0.05, 0.05), blob(rng, [7.0, 3.0, -2.5], 400, 0.05, 0.05)])
    b = summarize(cloud, np.ones(1000))
    assert b.n_clusters == 2
    d = np.array([0.3, -0.1, 0.2])
    moved = carried(b, d)
    for h, m in zip(b.hypotheses, moved.hypotheses):
        np.testing.assert_array_equal(m.mean, compose(h.mean, d))
        c, s = math.cos(h.mean[2]), math.sin(h.mean[2])
        jac = np.array([[1.0, 0.0, -s * d[0] - c * d[1]], [0.0, 1.0, c * d[0] - s * d[1]], [0.0, 0.0, 1.0]])
        np.testing.assert_allclose(m.cov, jac @ h.cov @ jac.T, rtol=1e-12, atol=1e-15)
        assert (m.weight, m.n_particles) == (h.weight, h.n_particles)
    np.testing.assert_array_equal(moved.mean, compose(b.mean, d))
    np.testing.assert_array_equal(moved.estimate, moved.hypotheses[0].mean)
    assert (moved.entropy_nats, moved.ess, moved.n_particles, moved.n_clusters) == (
        b.entropy_nats, b.ess, b.n_particles, b.n_clusters
    )  # fmt: skip
    assert moved.pos_std_m == pytest.approx(math.sqrt(moved.cov[0, 0] + moved.cov[1, 1]))
    # close to the summary of the cloud moved without noise (exact for a rigid motion of a tight cloud, to first order)
    exact = summarize(compose(cloud, d), np.ones(1000))
    for h, m in zip(exact.hypotheses, moved.hypotheses):
        np.testing.assert_allclose(m.mean, h.mean, atol=2e-3)
        np.testing.assert_allclose(m.cov, h.cov, atol=2e-4)
    assert carried(b, np.zeros(3)) is b
    with pytest.raises(ValueError, match="3 finite numbers"):
        carried(b, [0.1, np.nan, 0.0])
    with pytest.raises(ValueError, match="3 finite numbers"):
        carried(b, [0.1, 0.0])
    with pytest.raises(ValueError, match="non-finite"):
        carried(b, [1e308, 1e308, 0.0])  # finite, but the carried means overflow
    with pytest.raises(ValueError):
        moved.mean[0] = 1.0  # read-only, as a summary's


def test_carried_belief_judges_convergence_again():
    from filters.localization.belief import carried

    rng = np.random.default_rng(8)
    # tight in position, 0.15 rad in heading: converged; carried 2 m ahead, the heading's spread swings the position
    cloud = blob(rng, [2.0, 2.0, 0.0], 800, 0.02, 0.15)
    b = summarize(cloud, np.ones(800))
    assert b.converged
    far = carried(b, [2.0, 0.0, 0.0])
    assert far.hypotheses[0].pos_std_m > 0.25 and not far.converged
    assert carried(b, [0.05, 0.0, 0.0]).converged
    spread = BeliefConfig(converged_rule="spread")
    bs = summarize(cloud, np.ones(800), spread)
    assert bs.converged and not carried(bs, [2.0, 0.0, 0.0], spread).converged
    np.testing.assert_array_equal(carried(bs, [2.0, 0.0, 0.0], spread).estimate, carried(bs, [2.0, 0, 0], spread).mean)


def test_cluster_stats_of_clusters_without_particles_are_floats_on_both_backends():
    from filters.localization.belief import cluster_stats

    p, w = np.zeros((3, 3)), np.full(3, 1.0 / 3.0)
    for n in (0, 2):  # every particle unlabelled: NumPy's bincount gave int64 weights
        a, b = cluster_stats(p, w, np.full(3, -1), n, "numba"), cluster_stats(p, w, np.full(3, -1), n, "numpy")
        assert [(x.dtype, x.shape) for x in a] == [(x.dtype, x.shape) for x in b]
        assert a[0].dtype == np.float64
