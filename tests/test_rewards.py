import gymnasium as gym
import numpy as np
import pytest

import semreloc_env  # noqa: F401
from semreloc_env.rewards import BeliefMassReward, belief_mass_near


def test_belief_mass_near_counts_weight_within_the_radius():
    poses = np.array([[0.0, 0.0, 0.0], [0.3, 0.3, 3.0], [2.0, 0.0, 0.0], [0.0, 0.49, 0.1]])
    w = np.array([1.0, 2.0, 3.0, 4.0])
    assert belief_mass_near(poses, w, [0, 0, 0]) == pytest.approx(0.7)  # 0.42 m and 0.49 m are in
    assert belief_mass_near(poses, w, [0, 0, 0], heading_tol_rad=0.2) == pytest.approx(0.5)
    assert belief_mass_near(poses, w, [10, 10, 0]) == 0.0
    with pytest.raises(ValueError, match="radius_m"):
        belief_mass_near(poses, w, [0, 0, 0], radius_m=0)
    with pytest.raises(ValueError, match="weights"):
        belief_mass_near(poses, -w, [0, 0, 0])
    with pytest.raises(ValueError, match="poses"):
        belief_mass_near(poses[:, :2], w, [0, 0, 0])


@pytest.mark.parametrize("mode", ["level", "gain"])
def test_belief_mass_reward_adds_a_named_term(mode):
    kw = {"layout": "twin_rooms", "map_source": "perfect", "relocalizer": {"n_particles": 300}}
    plain, wrapped = gym.make("SemReloc-v22", **kw), BeliefMassReward(gym.make("SemReloc-v22", **kw), 2.0, mode=mode)
    plain.reset(seed=1)
    wrapped.reset(seed=1)
    prev = wrapped.mass()
    for a in [0] * 10 + [1] * 10:
        _, r0, *_, i0 = plain.step(a)
        _, r1, *_, i1 = wrapped.step(a)
        m = wrapped.mass()
        expected = 2.0 * (m if mode == "level" else m - prev)
        prev = m
        assert i1["rewards"]["belief_mass"] == pytest.approx(expected)
        assert r1 == pytest.approx(r0 + expected)
        assert {k: v for k, v in i1["rewards"].items() if k != "belief_mass"} == i0["rewards"]
    with pytest.raises(ValueError, match="mode"):
        BeliefMassReward(plain, mode="sum")
    # an outside audit's: these were accepted, and failed at reset or gave a mass of 0 every step; two stacked
    # made the terms not sum to the reward
    for kw, match in (
        ({"heading_tol_rad": -1.0}, "heading_tol_rad"),
        ({"heading_tol_rad": "x"}, "heading_tol_rad"),
        ({"weight": "a"}, "weight must be a finite number"),
        ({"weight": True}, "weight must be a finite number"),
    ):
        with pytest.raises(ValueError, match=match):
            BeliefMassReward(plain, **kw)
    with pytest.raises(ValueError, match="has a BeliefMassReward already"):
        BeliefMassReward(BeliefMassReward(plain, weight=0.05), weight=0.5, mode="gain")
    with pytest.raises(TypeError, match="needs a SemReloc env"):
        BeliefMassReward(gym.make("SemSlam-v2"))
