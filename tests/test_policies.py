import gymnasium as gym
import numpy as np
import pytest

import semreloc_env  # noqa: F401
from agents.baselines import all_round_angles
from agents.info_gain import InfoGainPlanner
from agents.policies import POLICIES, SpinThenBackUp

KW = {"layout": "twin_rooms", "map_source": "perfect", "relocalizer": {"n_particles": 300}, "max_episode_steps": 40}


def _episode(name, seed=1, **kw):
    pol = POLICIES[name](seed)
    env = pol.wrap(gym.make("SemReloc-v22", **{**KW, **kw}))
    pol.reset()
    obs, _ = env.reset(seed=seed)
    actions = []
    while True:
        a = pol.act(obs)
        assert env.action_space.contains(a)
        actions.append(np.asarray(a).tolist())
        obs, _, term, trunc, info = env.step(a)
        if term or trunc:
            return actions, info


@pytest.mark.parametrize("name", sorted(POLICIES))
def test_every_baseline_runs_an_episode_deterministically(name):
    # seed 6: episodes long enough to show each policy's behaviour (on seed 1 v21's filter converges after 6 steps)
    a1, info = _episode(name, seed=6)
    a2, _ = _episode(name, seed=6)
    assert a1 == a2 and len(a1) >= 1
    # what each does, so that a stub returning one constant action fails
    expect = {
        "random": lambda a: len(set(a)) >= 3,
        "spin": lambda a: set(a) == {1},
        "spin_backup": lambda a: a[: min(len(a), 60)] == [1] * min(len(a), 60),  # its full turn comes first
        "wall_follow": lambda a: 0 in a,
        "info_gain": lambda a: len(set(a)) >= 2,
        "viewpoint": lambda a: len(set(a)) >= 2,
    }
    assert expect[name](a1), a1


def test_wall_follow_turns_toward_the_freer_side_before_a_wall():
    from agents.baselines import FORWARD, TURN_LEFT, TURN_RIGHT, WallFollowExplorer, all_round_angles

    angles = all_round_angles(60)
    free = np.full(60, 8.0)
    blocked_left_freer = np.where(np.abs(angles) < 0.6, 0.3, np.where(angles > 0, 6.0, 1.0))
    blocked_right_freer = np.where(np.abs(angles) < 0.6, 0.3, np.where(angles > 0, 1.0, 6.0))
    ex = WallFollowExplorer()
    assert ex({"lidar": free}) == FORWARD
    assert ex({"lidar": blocked_left_freer}) == TURN_LEFT
    assert ex({"lidar": blocked_right_freer}) == TURN_LEFT  # keeps its side until the front is clear
    ex.reset()
    assert ex({"lidar": blocked_right_freer}) == TURN_RIGHT


@pytest.mark.parametrize("name", ["random", "spin_backup", "wall_follow"])
def test_baselines_drive_continuous_envs(name):
    actions, _ = _episode(name, action_type="continuous")
    assert all(len(a) == 2 for a in actions)


def test_spin_then_back_up_spins_a_full_turn_then_reverses():
    pol = SpinThenBackUp()
    env = pol.wrap(gym.make("SemReloc-v22", **{**KW, "action_type": "continuous", "max_episode_steps": 100}))
    pol.reset()
    obs, _ = env.reset(seed=0, options={"pose": (3.0, 3.0, 0.0)})  # room to back up
    acts = [pol.act(obs) for _ in range(73)]
    assert all(a[0] == 0 and a[1] == 1 for a in acts[:63])  # 63 x 0.1 rad >= 2 pi
    assert all(a[0] == -1 for a in acts[63:73])  # 0.5 m back at 0.05 m per step


class _NoTruth:
    def __getattr__(self, name):
        raise AssertionError(f"the planner read the simulator's world ({name})")


def test_info_gain_planner_reads_the_belief_not_the_truth():
    pol = InfoGainPlanner(seed=0, n_particles=16)
    env = pol.wrap(gym.make("SemReloc-v22", **KW))
    pol.reset()
    env.reset(seed=2)
    base = env.unwrapped
    world, base.world = base.world, _NoTruth()
    try:
        prim = pol.plan()
    finally:
        base.world = world
    assert prim.name in pol.last_scores and len(pol.last_scores) == len(pol.primitives)
    assert all(np.isfinite(v) for v in pol.last_scores.values())
    # a fresh global belief: some primitive is expected to tell hypotheses apart
    assert max(pol.last_scores.values()) > 0


def test_info_gain_planner_expects_nothing_from_a_tight_belief():
    # a belief on one pose (tracking start) is one hypothesis: no primitive can gain
    pol = InfoGainPlanner(seed=0, n_particles=24)
    no_injection = {**KW.get("relocalizer", {}), "proposal_frac": 0.0, "augmented": False}
    env = pol.wrap(gym.make("SemReloc-v22", **{**KW, "relocalizer": no_injection}))
    pol.reset()
    env.reset(seed=0, options={"pose": (3.0, 3.0, 0.0), "tracking": True})
    tight = pol.plan()
    assert max(pol.last_scores.values()) < 1e-6, (tight, pol.last_scores)
    with pytest.raises(ValueError, match="n_particles"):
        InfoGainPlanner(n_particles=0)


@pytest.mark.parametrize("name", sorted(POLICIES))
def test_baselines_reject_bad_seeds_other_envs_and_act_before_wrap(name):
    for seed in (-1, 1.5, True):
        with pytest.raises(ValueError, match="seed"):
            POLICIES[name](seed)
    pol = POLICIES[name](0)
    obs, _ = gym.make("SemReloc-v22", **KW).reset(seed=0)
    with pytest.raises(RuntimeError, match="wrap"):
        pol.act(obs)
    with pytest.raises(TypeError, match="action space"):
        pol.wrap(gym.make("CartPole-v1"))  # Discrete(2): the baselines' actions would not fit


@pytest.mark.parametrize("name", sorted(POLICIES))
def test_baselines_refuse_repeated_or_rescaled_actions_and_say_what_act_lacks(name):
    # an outside audit's: under ActionRepeat the viewpoint planner lost track of its motion and spin_backup turned
    # three or four times; a rescaled Box made "forward" an arc; act before reset failed deep in the planners
    from semreloc_env.wrappers import ActionRepeat

    with pytest.raises(ValueError, match=r"decides every env step.*ActionRepeat\(repeat=4\)"):
        POLICIES[name](0).wrap(ActionRepeat(gym.make("SemReloc-v22", **KW), 4))
    rescaled = gym.wrappers.RescaleAction(
        gym.make("SemReloc-v22", action_type="continuous", **KW), np.zeros(2, np.float32), np.ones(2, np.float32)
    )
    with pytest.raises(TypeError, match=r"Box\(-1, 1, \(2,\)\)"):
        POLICIES[name](0).wrap(rescaled)
    pol = POLICIES[name](0)
    env = pol.wrap(gym.make("SemReloc-v22", **KW))
    obs, _ = gym.make("SemReloc-v22", **KW).reset(seed=0)
    if name not in ("random", "spin"):  # the two that read nothing
        with pytest.raises(RuntimeError, match="reset the env before act"):
            pol.act(obs)
        env.reset(seed=0)
        with pytest.raises(ValueError, match=r"obs\['lidar'\] has shape \(10,\), the env's lidar \(60,\)"):
            pol.act({**obs, "lidar": obs["lidar"][:10]})


def test_spin_then_back_up_checks_its_distances():
    for bad in ({"backup_m": float("nan")}, {"backup_m": 0.0}, {"clearance_m": -1.0}):
        with pytest.raises(ValueError):
            SpinThenBackUp(0, **bad)


def test_policies_refuse_vector_envs_by_name():
    from stable_baselines3.common.vec_env import DummyVecEnv

    import agents

    vec = gym.make_vec("SemRelocVec-v22", num_envs=2, vectorization_mode="vector_entry_point", layout="twin_rooms")
    sb3 = DummyVecEnv([lambda: gym.make("SemReloc-v22", layout="twin_rooms")])
    for policy in (POLICIES["wall_follow"](), POLICIES["viewpoint"](), agents.load_policy(agents.SHIPPED_POLICY)):
        for env in (vec, sb3):
            with pytest.raises(TypeError, match="one env at a time"):
                policy.wrap(env)


def test_policies_read_the_env_lidar_beams_and_refuse_one_blind_where_they_look():
    """The hand-written policies took beam k to lie at -pi + 2 pi k / n: with one beam they failed with NumPy's
    "zero-size array" error, with a 90 deg lidar the explorer took side beams for its front (an outside tester).
    They now read the env's beam angles, and `wrap` refuses a lidar with no beam where they look."""
    from agents.options import MotionOptions

    blind = gym.make("SemReloc-v22", map_source="perfect", lidar={"n_beams": 1}, relocalizer={"n_particles": 50})
    for name in ("wall_follow", "spin_backup", "viewpoint", "info_gain"):
        with pytest.raises(ValueError, match=r"needs a lidar beam within 0.5 rad of 0 rad .* n_beams=1\) has none"):
            POLICIES[name](0).wrap(blind)
    with pytest.raises(ValueError, match=r"MotionOptions \['explore'\] needs a lidar beam within 0.5 rad of 0"):
        MotionOptions(blind, ("explore",))
    for name in ("spin", "random"):  # they do not read it
        policy = POLICIES[name](0)
        wrapped = policy.wrap(blind)
        obs, _ = wrapped.reset(seed=0)
        wrapped.step(policy.act(obs))

    ahead = gym.make("SemReloc-v22", map_source="perfect", lidar={"fov_rad": 1.5708, "n_beams": 30},
                     relocalizer={"n_particles": 50})  # fmt: skip
    with pytest.raises(ValueError, match=r"SpinThenBackUp needs a lidar beam within 0.5 rad of 3.14 rad"):
        POLICIES["spin_backup"](0).wrap(ahead)  # it backs up: it must see behind
    policy = POLICIES["wall_follow"](0)
    env = policy.wrap(ahead)
    np.testing.assert_array_equal(policy.explorer.beam_angles, ahead.unwrapped.lidar.angles)
    obs, _ = env.reset(seed=0)
    for _ in range(30):
        obs, *_ = env.step(policy.act(obs))
    assert MotionOptions(ahead, ("explore",)).explorer.beam_angles is not None
    default = gym.make("SemReloc-v22", map_source="perfect", relocalizer={"n_particles": 50})
    policy = POLICIES["wall_follow"](0)
    policy.wrap(default)  # the default lidar's angles are the all-round ones, bit for bit: episodes unchanged
    np.testing.assert_array_equal(policy.explorer.beam_angles, all_round_angles(60))
