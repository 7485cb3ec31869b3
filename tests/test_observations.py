import math

import gymnasium as gym
import numpy as np
import pytest

import semreloc_env  # noqa: F401
from semreloc_env.observations import (
    BELIEF_SUMMARY,
    HYPOTHESIS_FEATURES,
    ActiveObservation,
    hypotheses_of,
)
from semreloc_env.observations.rasters import MapRasters, egocentric_raster
from semreloc_env.wrappers import FlatObservation

SMALL = {"name": "small", "outer": [[0, 0], [4, 0], [4, 3], [0, 3]], "walls": [], "objects": []}
BIG = {
    "name": "big",
    "outer": [[0, 0], [40, 0], [40, 12], [0, 12]],
    "walls": [[[20, 0], [20, 5]], [[20, 7], [20, 12]]],
    "objects": [{"class": "cabinet", "center": [0.3, 6], "size": [0.6, 1.2]}],
}


class _Recorder(gym.Wrapper):
    """Keeps the raw observation of the last reset / step (what ActiveObservation was given)."""

    def reset(self, **kw):
        self.last, info = self.env.reset(**kw)
        return self.last, info

    def step(self, action):
        self.last, *rest = self.env.step(action)
        return (self.last, *rest)


def _env(layout, n, **kw):
    inner = gym.make("SemReloc-v22", layout=layout, map_source="perfect", relocalizer={"n_particles": n})
    return ActiveObservation(_Recorder(inner), **kw)


def obs_raw(env):
    return env.env.last


def _spaces_equal(a, b):
    assert list(a.spaces) == list(b.spaces)
    for k in a.spaces:
        sa, sb = a[k], b[k]
        assert type(sa) is type(sb)
        if hasattr(sa, "low"):
            np.testing.assert_array_equal(sa.low, sb.low)
            np.testing.assert_array_equal(sa.high, sb.high)
        else:
            np.testing.assert_array_equal(sa.nvec, sb.nvec)


@pytest.mark.parametrize("layout", ["twin_rooms", SMALL, BIG])
@pytest.mark.parametrize("n", [30, 2500])
def test_observation_inside_its_space_at_any_particle_count_and_layout_size(layout, n):
    env = _env(layout, n)
    _spaces_equal(env.observation_space, _env("lab", 1000).observation_space)  # bounds independent of both
    rng = np.random.default_rng(0)
    obs, info = env.reset(seed=2)
    assert env.observation_space.contains(obs)
    for _ in range(25):
        obs, *_, info = env.step(int(rng.integers(0, 4)))
        assert env.observation_space.contains(obs), [
            k for k, v in obs.items() if not env.observation_space[k].contains(v)
        ]
    assert obs["semantic_class"].dtype == np.int64
    assert obs["ego"][:4].max() == pytest.approx(1.0)  # max-normalised mass: some particle near the anchor


class _NoTruth:
    def __getattr__(self, name):
        raise AssertionError(f"the observation read the simulator's world ({name})")


def test_observation_never_reads_the_true_pose_or_the_error():
    env = _env("twin_rooms", 400)
    obs, info = env.reset(seed=4)
    for a in (0, 0, 1, 1, 0):
        obs, *_, info = env.step(a)
    base = env.unwrapped
    world = base.world
    base.world = _NoTruth()
    stripped = {k: v for k, v in info.items() if k not in ("pose", "pose_error")}
    try:
        again = env.observe(obs_raw(env), stripped)
    finally:
        base.world = world
    for k in obs:
        np.testing.assert_array_equal(again[k], obs[k])


def test_observation_depends_on_the_belief_not_on_where_the_robot_is():
    # same filter state, different true pose: same belief images and hypotheses
    env = _env("lab", 300)
    obs, info = env.reset(seed=0)
    base = env.unwrapped
    world = base.world
    before = env.observe(obs_raw(env), info)
    world.set_pose(world.sample_free_pose(np.random.default_rng(9)))
    after = env.observe(obs_raw(env), info)
    for k in ("ego", "global", "hypotheses", "belief"):
        np.testing.assert_array_equal(before[k], after[k])


def test_last_action_and_scans_are_encoded():
    env = _env("twin_rooms", 200)
    obs, _ = env.reset(seed=0)
    np.testing.assert_array_equal(obs["last_action"], np.zeros(4))
    obs, *_ = env.step(2)
    np.testing.assert_array_equal(obs["last_action"], [0, 0, 1, 0])
    raw = obs_raw(env)
    np.testing.assert_allclose(obs["lidar"], raw["lidar"] / 8.0, rtol=1e-6)
    np.testing.assert_array_equal(obs["semantic_class"], raw["semantic_class"])
    cont = ActiveObservation(
        gym.make(
            "SemReloc-v22",
            layout="twin_rooms",
            map_source="perfect",
            action_type="continuous",
            relocalizer={"n_particles": 100},
        )
    )
    cont.reset(seed=0)
    obs, *_ = cont.step(np.array([0.5, -0.25], np.float32))
    np.testing.assert_allclose(obs["last_action"], [0.5, -0.25])
    assert cont.observation_space.contains(obs)


def test_keys_select_entries_and_bad_arguments_raise():
    env = _env("twin_rooms", 100, keys=("hypotheses", "lidar"))
    obs, _ = env.reset(seed=0)
    assert list(obs) == ["hypotheses", "lidar"] and env.observation_space.contains(obs)
    assert obs["hypotheses"].shape == (8, len(HYPOTHESIS_FEATURES))
    for kw, name in (
        ({"keys": ("pose",)}, "keys"),
        ({"ego_size": 0}, "ego_size"),
        ({"ego_cell_m": -1.0}, "ego_cell_m"),
        ({"ego_size": 10**5}, "ego_size"),
        ({"global_size": 1000}, "global_size"),
        ({"ego_cell_m": 1e-9}, "ego_cell_m"),
    ):
        with pytest.raises(ValueError, match=name):
            _env("twin_rooms", 100, **kw)
    assert len(BELIEF_SUMMARY) == 7
    _env("twin_rooms", 100, ego_cell_m=np.float32(0.25))  # a NumPy float is a number too
    with pytest.raises(TypeError, match="mcl"):  # a SLAM env has no relocalizer to read
        ActiveObservation(gym.make("SemSlam-v2"))


def test_hypotheses_of_prefers_the_filters_list():
    env = _env("twin_rooms", 100)
    _, info = env.reset(seed=0)
    mine = hypotheses_of(env, info)
    mcl = env.unwrapped.mcl
    assert mine == info["belief"]["hypotheses"] == mcl.belief().as_dict()["hypotheses"]
    assert sum(h["weight"] for h in mine) <= 1.0 + 1e-9
    assert sum(h["n_particles"] for h in mine) <= info["belief"]["n_particles"] == mcl.n_particles
    published = [{"weight": 1.0, "mean": [1.0, 2.0, 0.0], "cov": np.eye(3).tolist(), "n_particles": 100}]
    assert hypotheses_of(env, {"belief": {"hypotheses": published}}) == published


def test_egocentric_raster_frame():
    grid = gym.make("SemReloc-v22", layout="twin_rooms", map_source="perfect").unwrapped.grid
    r = MapRasters(grid, 0.25, 32)
    anchor = np.array([3.0, 3.0, math.pi / 2])  # facing +y
    # one particle 1 m ahead of the anchor (4 cells along the columns), one 1 m to its left (rows)
    poses = np.array([[3.0, 4.0, math.pi / 2], [2.0, 3.0, math.pi]])
    img, mass = egocentric_raster(r, poses, np.array([1.0, 0.5]), anchor, 32, 4)
    assert mass == pytest.approx(1.0)
    assert img[0, 16, 20] == pytest.approx(1.0)  # heading equal to the anchor's: bin 0
    assert img[1, 20, 16] == pytest.approx(0.5)  # heading +90 deg relative: bin 1
    assert img[:4].sum() == pytest.approx(1.5)


def test_what_reads_scans_in_metres_refuses_an_env_wrapped_by_active_observation():
    """ActiveObservation keeps the names lidar / semantic_range but scales them to [0, 1]: applied twice,
    or under a baseline, it would give wrong results silently (a new user's trial)."""
    import agents
    from agents.policies import POLICIES

    once = _env("lab", 200)  # ActiveObservation over the raw env
    with pytest.raises(ValueError, match="ActiveObservation needs the env's own observations.*already"):
        ActiveObservation(once)
    flat = FlatObservation(gym.make("SemReloc-v22", layout="lab", map_source="perfect"))
    with pytest.raises(ValueError, match=r"\(Box, from FlatObservation\) lacks the entries \['lidar'"):
        ActiveObservation(flat)
    for name in ("wall_follow", "spin", "viewpoint"):
        with pytest.raises(ValueError, match="own observations"):
            POLICIES[name](0).wrap(once)
    with pytest.raises(ValueError, match="own observations"):
        agents.load_policy(agents.SHIPPED_POLICY).wrap(once)
    raw = gym.make("SemReloc-v22", layout="lab", map_source="perfect", relocalizer={"n_particles": 200})
    timed = gym.wrappers.TimeLimit(raw, 5)  # a wrapper that keeps the observations is fine
    assert isinstance(ActiveObservation(timed).observation_space, gym.spaces.Dict)
    assert POLICIES["spin"](0).wrap(timed) is timed
    from semreloc_env.wrappers import BeliefObservation

    believed = BeliefObservation(
        gym.make("SemReloc-v22", layout="lab", map_source="perfect", relocalizer={"n_particles": 200})
    )
    assert POLICIES["wall_follow"](0).wrap(believed) is believed  # an added entry keeps the scans in metres
    assert "ego" in ActiveObservation(believed).observation_space.spaces


def test_active_observation_arguments_are_checked_without_an_env():
    # a new user's trial: train_active took a bad ego_size and failed in every worker process
    from agents.train_active import ActiveTrainConfig
    from semreloc_env.observations.active import check_arguments

    check_arguments()  # the defaults
    for bad, match in [
        ({"ego_size": 0}, "ego_size must be a positive integer"),
        ({"ego_cell_m": 0.0}, "ego_cell_m"),
        ({"keys": "ego"}, "keys must be a list"),
        ({"keys": ["ego", "x_ray"]}, r"keys \['x_ray'\] invalid"),
    ]:
        with pytest.raises(ValueError, match=match):
            check_arguments(**bad)
        with pytest.raises(ValueError, match="observation: " + match):
            ActiveTrainConfig(observation=bad)


def test_active_observation_keys_may_be_any_iterable():
    # a review: an iterator of keys was read by the check and then gave an empty observation
    from semreloc_env.observations.active import OBSERVATION_KEYS

    env = gym.make("SemReloc-v22", layout="twin_rooms", map_source="perfect", relocalizer={"n_particles": 200})
    wrapped = ActiveObservation(env, keys=iter(OBSERVATION_KEYS[:3]))
    assert wrapped.keys == tuple(OBSERVATION_KEYS[:3])
    assert set(wrapped.observation_space.spaces) == set(OBSERVATION_KEYS[:3])
    with pytest.raises(ValueError, match="keys must be a list"):  # a string is not a list of keys
        ActiveObservation(env, keys="ego")


def test_a_belief_without_hypotheses_is_observed_around_its_estimate():
    # an outside fuzzer's: with no cluster reaching cluster_min_weight the list is empty and hyps[0] crashed
    env = ActiveObservation(gym.make("SemReloc-v22", relocalizer={"belief": {"cluster_min_weight": 1.0}}))
    obs, info = env.reset(seed=0)
    assert info["belief"]["hypotheses"] == []
    assert env.observation_space.contains(obs)
    assert not obs["hypotheses"].any()  # no rows filled

    def ego_at(anchor):
        base = env.unwrapped
        rasters = env.rasters_for(base.grid)
        return egocentric_raster(rasters, base.mcl.poses, base.mcl.weights, anchor, env.ego_size, env.n_heading_bins)[0]

    np.testing.assert_array_equal(obs["ego"], ego_at(np.asarray(info["belief"]["estimate"])))
    assert not np.array_equal(obs["ego"], ego_at(np.zeros(3)))  # the anchor matters
    obs = env.step(0)[0]
    assert env.observation_space.contains(obs)
