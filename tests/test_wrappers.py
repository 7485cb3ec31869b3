import math
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env as gym_check_env
from stable_baselines3.common.env_checker import check_env as sb3_check_env

import semreloc_env  # noqa: F401
from semreloc_env.envs.semreloc import SemRelocEnv
from semreloc_env.wrappers import BELIEF_FEATURES, BeliefObservation, FlatObservation

FAST = {"map_source": "perfect", "relocalizer": {"n_particles": 300}}


def _expected(belief: dict) -> np.ndarray:
    return np.array(
        [
            belief["pos_std_m"],
            belief["theta_std_rad"],
            belief["entropy_nats"],
            belief["n_clusters"],
            belief["ess"] / belief["n_particles"],
            float(belief["converged"]),
        ],
        dtype=np.float32,
    )


def _rollout(env, seed=3, n=40):
    rng = np.random.default_rng(5)
    obs, info = env.reset(seed=seed)
    out = [(obs, info)]
    for _ in range(n):
        obs, _, term, trunc, info = env.step(int(rng.integers(0, 4)))
        out.append((obs, info))
        if term or trunc:
            obs, info = env.reset()
            out.append((obs, info))
    return out


def test_belief_observation_space_and_features_equal_info():
    env = BeliefObservation(gym.make("SemReloc-v22", **FAST))
    space = env.observation_space
    assert set(space.spaces) == {"lidar", "semantic_range", "semantic_class", "odometry", "belief"}
    assert space["belief"].shape == (len(BELIEF_FEATURES),)
    assert space["belief"].dtype == np.float32
    # documented bounds; entropy bound = log(n_particles)
    np.testing.assert_allclose(space["belief"].high, [20.0, math.pi, math.log(300), 20, 1, 1], rtol=1e-6)
    np.testing.assert_array_equal(space["belief"].low, np.zeros(6, np.float32))
    seen_converged = set()
    for obs, info in _rollout(env):
        assert space.contains(obs)
        np.testing.assert_allclose(obs["belief"], _expected(info["belief"]), rtol=1e-6)
        seen_converged.add(bool(obs["belief"][5]))
    # a tracking start is converged at once: the feature must then read 1 (and 0 in the global rollout)
    obs, info = env.reset(seed=3, options={"tracking": True})
    np.testing.assert_allclose(obs["belief"], _expected(info["belief"]), rtol=1e-6)
    seen_converged.add(bool(obs["belief"][5]))
    assert seen_converged == {False, True}
    # the belief moves during the rollout: features are not constant
    beliefs = np.array([o["belief"] for o, _ in _rollout(env)])
    assert np.ptp(beliefs[:, 0]) > 0.1 and np.ptp(beliefs[:, 2]) > 0.1


def test_belief_observation_does_not_change_the_rest_of_the_step():
    plain = gym.make("SemReloc-v22", **FAST)
    wrapped = BeliefObservation(gym.make("SemReloc-v22", **FAST))
    for (o1, i1), (o2, i2) in zip(_rollout(plain, n=15), _rollout(wrapped, n=15)):
        for k in o1:
            np.testing.assert_array_equal(o1[k], o2[k])
        assert i1["belief"] == i2["belief"]
    # the true pose is not in the observation: no observation entry equals it
    obs, info = wrapped.reset(seed=1)
    assert not any(np.allclose(v[:3], info["pose"], atol=1e-3) for v in obs.values() if v.size >= 3)


def test_belief_observation_clips_to_bounds():
    env = BeliefObservation(gym.make("SemReloc-v22", **FAST), pos_std_max_m=1.0, max_clusters=2)
    obs, info = env.reset(seed=0)
    assert info["belief"]["pos_std_m"] > 1.0  # global start: spread over the lab
    assert obs["belief"][0] == np.float32(1.0)
    assert env.observation_space.contains(obs)
    f = env.belief_features({**info["belief"], "n_clusters": 7, "entropy_nats": 1e9})
    assert f[3] == 2.0 and f[2] == np.float32(math.log(300))


def test_belief_observation_rejects_bad_envs_and_bounds():
    with pytest.raises(ValueError):
        BeliefObservation(BeliefObservation(gym.make("SemReloc-v22", **FAST)))
    with pytest.raises(TypeError):
        BeliefObservation(gym.make("CartPole-v1"))
    with pytest.raises(TypeError, match="SemSlamEnv has no belief"):  # used to fail at reset with KeyError: 'belief'
        BeliefObservation(gym.make("SemSlam-v2", layout="twin_rooms"))

    class NoBelief(gym.Wrapper):  # another Dict env whose info lacks the belief: the keys it has are named
        def reset(self, **kw):
            obs, info = self.env.reset(**kw)
            return obs, {k: v for k, v in info.items() if k != "belief"}

    with pytest.raises(KeyError, match="needs info\\['belief'\\].*'pose_error'"):
        BeliefObservation(NoBelief(gym.make("SemReloc-v22", **FAST))).reset(seed=0)
    for bad in (0.0, True, "a"):
        with pytest.raises(ValueError, match="pos_std_max_m"):
            BeliefObservation(gym.make("SemReloc-v22", **FAST), pos_std_max_m=bad)


def _check(env):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        # the one warning gymnasium's checker gives for any wrapper, by design of this test
        warnings.filterwarnings("ignore", message=".*different from the unwrapped version.*")
        gym_check_env(env, skip_render_check=True)
        sb3_check_env(env, warn=True)


def test_check_env_passes_on_wrapped_envs_with_warnings_as_errors():
    _check(BeliefObservation(SemRelocEnv(**FAST)))
    _check(FlatObservation(BeliefObservation(SemRelocEnv(**FAST))))
    _check(BeliefObservation(SemRelocEnv(action_type="continuous", **FAST)))


@pytest.mark.parametrize(
    "env_id, keys",
    [
        ("SemReloc-v22", ("belief", "lidar", "odometry", "semantic_class", "semantic_range")),
        ("SemReloc-v1", ("belief", "lidar", "odometry", "semantic")),
    ],
)
def test_flat_observation_concatenates_in_key_order(env_id, keys):
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=".*out of date.*", category=DeprecationWarning)
        inner = BeliefObservation(gym.make(env_id, **FAST))
    flat = FlatObservation(inner)
    spaces = inner.observation_space.spaces
    n = sum(
        int(s.nvec.sum()) if isinstance(s, gym.spaces.MultiDiscrete) else int(np.prod(s.shape)) for s in spaces.values()
    )
    assert flat.observation_space.shape == (n,)
    assert flat.keys == keys  # gymnasium's Dict sorts its keys
    seen_classes = set()
    for (o_dict, _), (o_flat, _) in zip(_rollout(inner, n=40), _rollout(flat, n=40)):
        assert flat.observation_space.contains(o_flat)
        for k in flat.keys:
            part = o_flat[flat.slices[k]]
            if isinstance(spaces[k], gym.spaces.MultiDiscrete):  # one-hot per beam, beam-major
                onehot = part.reshape(len(spaces[k].nvec), -1)
                np.testing.assert_array_equal(onehot.sum(axis=1), 1.0)
                np.testing.assert_array_equal(onehot.argmax(axis=1), o_dict[k])
                seen_classes |= set(o_dict[k].tolist())
            else:
                np.testing.assert_array_equal(part, o_dict[k].ravel())
    if "semantic_class" in keys:
        assert len(seen_classes) >= 2  # the rollout saw objects, so the one-hot was exercised
    for k in flat.keys:
        low, high = flat.observation_space.low[flat.slices[k]], flat.observation_space.high[flat.slices[k]]
        if isinstance(spaces[k], gym.spaces.MultiDiscrete):
            assert (low == 0).all() and (high == 1).all()
        else:
            np.testing.assert_array_equal(low, spaces[k].low)
            np.testing.assert_array_equal(high, spaces[k].high)


def test_flat_observation_key_subset_and_errors():
    flat = FlatObservation(gym.make("SemReloc-v22", **FAST), keys=["odometry", "lidar"])
    obs, _ = flat.reset(seed=0)
    assert obs.shape == (3 + 60,)
    assert flat.slices["odometry"] == slice(0, 3)
    with pytest.raises(KeyError):
        FlatObservation(gym.make("SemReloc-v22", **FAST), keys=["belief"])
    with pytest.raises(ValueError, match="at least one"):
        FlatObservation(gym.make("SemReloc-v22", **FAST), keys=())
    with pytest.raises(
        ValueError, match=r"keys must be a list of observation keys, got 'lidar' \(one key: \['lidar'\]\)"
    ):
        FlatObservation(gym.make("SemReloc-v22", **FAST), keys="lidar")  # said keys ['l', 'i', 'd', 'a', 'r']
    with pytest.raises(TypeError):
        FlatObservation(gym.make("CartPole-v1"))


def test_every_wrapper_records_its_arguments_so_check_env_and_specs_work():
    """Gymnasium's convention (gymnasium.utils.RecordConstructorArgs): env.spec lists each wrapper with
    its arguments, gym.make(env.spec) rebuilds the stack, and check_env accepts a wrapped env."""
    import warnings

    from gymnasium.utils.env_checker import check_env

    from agents.options import ExplorerOption, MotionOptions, TeacherLabels
    from semreloc_env.layout_sampling import LayoutSampler, RandomLayout
    from semreloc_env.observations import ActiveObservation
    from semreloc_env.rewards import BeliefMassReward
    from semreloc_env.wrappers import ActionRepeat, BeliefObservation, FlatObservation

    def raw():
        return gym.make("SemReloc-v22", map_source="perfect", relocalizer={"n_particles": 100})

    stacks = [
        (ActiveObservation(raw(), ego_size=16), {"ego_size": 16}),
        (FlatObservation(BeliefObservation(raw(), max_clusters=7)), {"keys": None}),
        (ActionRepeat(raw(), 3), {"repeat": 3}),
        (BeliefMassReward(raw(), weight=0.2, mode="gain"), {"weight": 0.2, "mode": "gain"}),
        (MotionOptions(raw(), ("explore", "viewpoint")), {"options": ("explore", "viewpoint")}),
        (ExplorerOption(raw()), {}),
        (TeacherLabels(raw(), {"replan_every": 5}), {"planner": {"replan_every": 5}}),
        (RandomLayout(raw(), LayoutSampler(kinds=("twin_rooms", "lab", "three_rooms")), seed=4), {"seed": 4}),
    ]
    for env, kwargs in stacks:
        spec = env.spec.additional_wrappers[-1]
        assert spec.name == type(env).__name__
        assert kwargs.items() <= spec.kwargs.items() if kwargs else spec.kwargs == {}, (spec.name, spec.kwargs)
        again = gym.make(env.spec)
        assert type(again) is type(env) and again.observation_space == env.observation_space
        assert again.action_space == env.action_space
    layouts = stacks[-1][0]
    rebuilt = gym.make(layouts.spec)
    names = []
    for env in (layouts, rebuilt):
        names.append([env.reset(seed=s)[1]["layout"]["name"] for s in range(6)])
    assert names[0] == names[1] and len(set(names[0])) > 1  # the same sampler and stream
    belief = BeliefObservation(raw(), max_clusters=7)
    assert belief.spec.additional_wrappers[-1].kwargs["max_clusters"] == 7
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # check_env's advice to pass the unwrapped env
        check_env(ActiveObservation(raw()), skip_render_check=True)
