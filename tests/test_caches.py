"""Caches that make resets and new envs cheap: the likelihood field per map, maps per layout."""

import gymnasium as gym
import numpy as np

import semreloc_env  # noqa: F401


def test_envs_on_the_same_map_share_one_likelihood_model_across_resets():
    a = gym.make("SemReloc-v0", map_source="perfect").unwrapped
    b = gym.make("SemReloc-v0", map_source="perfect").unwrapped
    a.reset(seed=0)
    model = a.mcl.measurement_model
    a.reset(seed=1)
    b.reset(seed=2)
    assert a.mcl.measurement_model is model and b.mcl.measurement_model is model
    c = gym.make("SemReloc-v0", map_source="perfect", relocalizer={"lidar_field": {"sigma_hit_m": 0.3}}).unwrapped
    c.reset(seed=0)
    assert c.mcl.measurement_model is not model
    assert np.isclose(c.mcl.measurement_model.lidar_config.sigma_hit_m, 0.3)
