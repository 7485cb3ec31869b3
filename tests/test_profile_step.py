"""`agents.tools.profile_step`: the batched env's CPU split (`batched_split`) and what it counts as compiled."""

import pytest

from agents.tools import profile_step
from filters.localization import audit
from filters.localization.likelihood_field import log_likelihood_kernel
from filters.localization.mcl import MonteCarloLocalizer


def test_compiled_functions_are_the_numba_kernels():
    keys = profile_step.compiled_functions()
    code = log_likelihood_kernel.py_func.__code__
    assert (code.co_filename, code.co_firstlineno, code.co_name) in keys
    python_code = MonteCarloLocalizer.update.__code__
    assert (python_code.co_filename, python_code.co_firstlineno, python_code.co_name) not in keys


def test_batched_split_accounts_for_every_robot_step_and_restores_the_filter():
    before = (MonteCarloLocalizer._audit, audit.best_alternative)
    s = profile_step.batched_split(3, 12, seed=4, env_id="SemReloc-v21", max_episode_steps=5)
    assert (MonteCarloLocalizer._audit, audit.best_alternative) == before
    assert s.robot_steps == 36
    assert s.update_steps + s.plain_steps + s.resets == s.robot_steps
    assert s.resets >= 6  # 5-step episodes: each robot restarts at least twice in steps 6-17
    assert s.update_steps > 0 and s.plain_steps > 0
    assert s.update_s + s.plain_s + s.reset_s <= s.total_s
    assert 0.0 < s.audit_s <= s.update_s + s.reset_s  # every update runs its audit step, most return at once
    assert 0.0 < s.kernel_s < s.total_s * 5  # the profiled run is slower, but its kernels not by much
    assert s.loop_s >= 0.0


@pytest.mark.filterwarnings("ignore:.*out of date.*:DeprecationWarning")
def test_batched_split_counts_the_audits_searches():
    """In SemReloc-v20, robot 0 of seed 0 converges twice in its first 45 steps: two audits search for another place,
    counted as the calls of `audit.best_alternative` (the same episodes every run; v21's episodes of that seed search
    once)."""
    s = profile_step.batched_split(2, 40, seed=0, env_id="SemReloc-v20")
    assert s.audits == 2 and s.audit_s > 0.0


def test_a_timed_robot_sorts_its_steps_by_the_filter_s_updates():
    """`_TimedRobot` counts a step as an update step exactly when the filter's update count rose in it (random
    actions: the motion gate lets some pass), and leaves the episode as it is (the same observations as the env
    stepped bare)."""
    import gymnasium as gym
    import numpy as np

    keys = ("update_s", "update_steps", "plain_s", "plain_steps", "reset_s", "resets", "audit_s", "audits")
    tally = dict.fromkeys(keys, 0.0)
    timed, bare = profile_step._TimedRobot(gym.make("SemReloc-v21"), tally), gym.make("SemReloc-v21")
    timed.reset(seed=3)
    bare.reset(seed=3)
    rng = np.random.default_rng(3)
    updates = 0
    for _ in range(40):
        a = int(rng.integers(0, 4))
        before = timed.unwrapped.mcl.n_updates
        obs = timed.step(a)[0]
        updates += timed.unwrapped.mcl.n_updates > before
        want = bare.step(a)[0]
        assert all(np.array_equal(obs[k], want[k]) for k in want)
    assert tally["update_steps"] == updates and tally["plain_steps"] == 40 - updates
    assert 0 < updates < 40 and tally["resets"] == 1 and tally["update_s"] > 0 and tally["plain_s"] > 0


def test_profile_step_refuses_a_negative_robot_count():
    with pytest.raises(ValueError, match="robots"):
        profile_step.Args(robots=-1)
