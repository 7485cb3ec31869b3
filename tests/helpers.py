"""Shared test helpers (importable as ``helpers``: pytest puts tests/ on sys.path)."""

import numpy as np


def assert_identical(a, b) -> None:
    """Assert two env outputs (dicts, lists, arrays, scalars) are exactly equal, recursively
    (``np.testing.assert_equal``: NaN equals NaN, a missing key is a difference)."""
    np.testing.assert_equal(a, b)


def random_rollout(env, seed: int, n: int = 200, action_seed: int = 123) -> list:
    """Reset with ``seed``, take ``n`` random discrete actions (from ``action_seed``), resetting
    when an episode ends; returns every (obs, reward, terminated, truncated, info)."""
    obs, info = env.reset(seed=seed)
    rng = np.random.default_rng(action_seed)
    out = [(obs, info)]
    for _ in range(n):
        obs, r, term, trunc, info = env.step(int(rng.integers(0, 4)))
        out.append((obs, r, term, trunc, info))
        if term or trunc:
            obs, info = env.reset()
    return out
