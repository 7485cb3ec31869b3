"""Shared test helpers (importable as ``helpers``: pytest puts tests/ on sys.path)."""

import numpy as np


def assert_identical(a, b) -> None:
    """Assert two env outputs (dicts, lists, arrays, scalars) are exactly equal, recursively
    (``np.testing.assert_equal``: NaN equals NaN, a missing key is a difference)."""
    np.testing.assert_equal(a, b)


def strictly_equal(a, b) -> bool:
    """Equal keys in the same order, arrays of the same dtype and shape, and elements of the same type and value."""
    if isinstance(a, dict):
        return isinstance(b, dict) and list(a) == list(b) and all(strictly_equal(a[k], b[k]) for k in a)
    if isinstance(a, np.ndarray):
        if not (isinstance(b, np.ndarray) and a.dtype == b.dtype and a.shape == b.shape):
            return False
        if a.dtype != object:
            return a.tobytes() == b.tobytes()
        return all(strictly_equal(x, y) for x, y in zip(a.tolist(), b.tolist()))
    if isinstance(a, (list, tuple)):
        return type(a) is type(b) and len(a) == len(b) and all(strictly_equal(x, y) for x, y in zip(a, b))
    return type(a) is type(b) and (a == b or (a != a and b != b))


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
