"""SemReloc-v1 episodes are the same bit for bit with the numba fast path and the NumPy reference path.

``MCLConfig.fast_path`` may only change speed: observations, rewards, terminations and every
info entry (belief floats included) must be identical. The episodes cover a spread global
belief (10,000+ particles, clustered and KLD resampling, scan injection), a twin-rooms layout
with look-alike hypotheses, and a tracking episode with a kidnap.
"""

import gymnasium as gym
import numpy as np
import pytest
from helpers import assert_identical

import semreloc_env  # noqa: F401


def rollout(fast: bool, layout: str, seed: int, steps: int, options: dict | None = None) -> list:
    env = gym.make("SemReloc-v1", layout=layout, relocalizer={"fast_path": fast})
    rng = np.random.default_rng(seed)
    obs, info = env.reset(seed=seed, options=options)
    out = [(obs, info)]
    for t in range(steps):
        obs, r, term, trunc, info = env.step(int(rng.integers(0, 4)))
        out.append((obs, r, term, trunc, info))
        if term or trunc:
            obs, info = env.reset(seed=seed + 1 + t)
            out.append((obs, info))
    env.close()
    return out


@pytest.mark.parametrize(
    ("layout", "seed", "steps", "options"),
    [
        ("lab", 0, 60, None),
        ("twin_rooms", 2, 50, None),
        ("lab", 3, 50, {"tracking": True, "kidnap_at_step": 15}),
    ],
)
def test_fast_path_episodes_equal_reference(layout, seed, steps, options):
    fast = rollout(True, layout, seed, steps, options)
    ref = rollout(False, layout, seed, steps, options)
    assert len(fast) == len(ref)
    for a, b in zip(fast, ref):
        assert_identical(a, b)
    # the episodes did exercise resampling and a multi-hypothesis belief
    infos = [rec[-1] for rec in fast]
    assert any(i["mcl"]["resampled"] for i in infos)
    assert max(i["belief"]["n_particles"] for i in infos) >= 500


def test_fast_path_must_be_a_bool():
    from filters.localization.mcl import MCLConfig

    with pytest.raises(ValueError, match="fast_path"):
        MCLConfig(fast_path=1)
