"""Shared test helpers (importable as ``helpers``: pytest puts tests/ on sys.path)."""

import numpy as np


def assert_identical(a, b) -> None:
    """Recursively assert two env outputs (dicts, lists, arrays, scalars) are exactly equal."""
    if isinstance(a, dict):
        assert a.keys() == b.keys()
        for k in a:
            assert_identical(a[k], b[k])
    elif isinstance(a, (list, tuple)):
        assert len(a) == len(b)
        for x, y in zip(a, b):
            assert_identical(x, y)
    elif isinstance(a, np.ndarray):
        np.testing.assert_array_equal(a, b)
    else:
        assert a == b


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
