"""`agents.tools.profile_step`: the batched env's CPU split (`batched_split`) and what it counts as compiled."""

import dataclasses

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
    s = profile_step.batched_split(3, 12, seed=4, env_id="SemReloc-v22", max_episode_steps=5)
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
    timed, bare = profile_step._TimedRobot(gym.make("SemReloc-v22"), tally), gym.make("SemReloc-v22")
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


def test_compiled_time_counts_the_kernels_calls_and_only_theirs():
    import cProfile
    import pstats
    import time

    import numpy as np

    args = profile_step.empty_kernel_args()
    log_likelihood_kernel(*args)
    prof = cProfile.Profile(time.process_time)
    prof.enable()
    for _ in range(3):
        log_likelihood_kernel(*args)
    np.cos(np.zeros(3))  # NumPy's compiled code is not this package's
    prof.disable()
    seconds, calls = profile_step.compiled_time(pstats.Stats(prof))
    assert calls == 3 and 0.0 < seconds < 0.1


def test_compiled_by_function_splits_the_kernels_time_heaviest_first():
    """Two kernels, one called with work and one without: each its own calls, the heavier first, and the two sum to
    `compiled_time`."""
    import cProfile
    import pstats
    import time

    import numpy as np

    from filters.pose import _cos_sin

    theta, c, s = np.linspace(-3.0, 3.0, 200_000), np.empty(200_000), np.empty(200_000)
    args = profile_step.empty_kernel_args()
    log_likelihood_kernel(*args)
    _cos_sin(theta[:2], c[:2], s[:2])
    prof = cProfile.Profile(time.process_time)
    prof.enable()
    for _ in range(4):
        log_likelihood_kernel(*args)
    for _ in range(2):
        _cos_sin(theta, c, s)
    prof.disable()
    stats = pstats.Stats(prof)
    split = profile_step.compiled_by_function(stats)
    assert list(split) == ["_cos_sin", "log_likelihood_kernel"]
    assert split["_cos_sin"][1] == 2 and split["log_likelihood_kernel"][1] == 4
    compiled = profile_step.compiled_functions()  # the same sum, straight from the profile's records
    direct = sum(tt for key, (_, _, tt, _, _) in stats.stats.items() if key in compiled)
    assert sum(t for t, _ in split.values()) == pytest.approx(direct)
    assert profile_step.compiled_time(stats) == (pytest.approx(direct), 6)


def test_a_compiled_call_s_dispatch_is_measured_in_microseconds():
    """The same calls timed here, in turn with it: the two agree within a factor the load cannot explain away
    (a measurement off by its call count or its units would not)."""
    import time

    args = profile_step.empty_kernel_args()
    measured, direct = [], []
    for _ in range(3):
        measured.append(profile_step.dispatch_seconds(2000))
        t0 = time.process_time()
        for _ in range(10_000):
            log_likelihood_kernel(*args)
        direct.append((time.process_time() - t0) / 10_000)
    assert 1e-8 < min(measured) < 1e-4
    assert 1 / 3 < min(measured) / min(direct) < 3


def test_batched_split_counts_the_particles_the_updates_weigh():
    """One robot: padded to the largest set of one is the set itself, and what it weighed is the particle count before
    each of its update steps (an env of the same seed stepped with the same actions, no episode ending in them);
    four robots whose updates meet in a step with sets of different sizes: padding weighs more."""
    import gymnasium as gym
    import numpy as np

    one = profile_step.batched_split(1, 30, seed=2, env_id="SemReloc-v22")
    assert one.resets == 0 and one.update_steps > 0
    assert one.weighed == one.weighed_stacked > 0
    env = gym.make("SemReloc-v22")
    env.reset(seed=2)
    rng = np.random.default_rng(2)
    for _ in range(5):
        env.step(int(rng.integers(0, 4, 1)[0]))
    mcl, weighed = env.unwrapped.mcl, 0
    for _ in range(30):
        n = mcl.n_particles
        env.step(int(rng.integers(0, 4, 1)[0]))
        weighed += n if mcl.last_diagnostics.updated else 0
    assert weighed == one.weighed
    four = profile_step.batched_split(4, 12, seed=4, env_id="SemReloc-v22")  # robots of unequal sets update together
    assert four.weighed_stacked > four.weighed > 0 and four.kernel_calls > four.robot_steps


def test_stacked_counts_pad_every_updating_robot_to_the_largest_set():
    assert profile_step.stacked_counts([]) == (0, 0)
    assert profile_step.stacked_counts([500]) == (500, 500)
    assert profile_step.stacked_counts([500, 3484, 700]) == (4684, 3 * 3484)


def test_the_heaviest_text_names_the_kernels_with_their_shares_of_the_compiled_time():
    s = profile_step.BatchedSplit(
        robot_steps=100, total_s=0.1, update_steps=20, update_s=0.05, audits=1, audit_s=0.01, plain_steps=80,
        plain_s=0.04, resets=0, reset_s=0.0, loop_s=0.01, kernel_s=0.04, kernel_calls=1500, weighed=1000,
        weighed_stacked=2500, kernels=(("a", 0.02), ("b", 0.01), ("c", 0.006), ("d", 0.004)),
    )  # fmt: skip
    assert profile_step.heaviest_text(s) == "a 50 %, b 25 %, c 15 %"
    assert profile_step.heaviest_text(s, 1) == "a 50 %"


def test_the_robots_fused_text_says_what_fusing_and_stacking_would_do():
    s = profile_step.BatchedSplit(
        robot_steps=100, total_s=0.1, update_steps=20, update_s=0.05, audits=1, audit_s=0.01, plain_steps=80,
        plain_s=0.04, resets=0, reset_s=0.0, loop_s=0.01, kernel_s=0.04, kernel_calls=1500, weighed=1000,
        weighed_stacked=2500,
    )  # fmt: skip
    text = profile_step.robots_fused_text(s, 2e-6)
    assert "15.0, 2.00 us of dispatch each" in text
    assert "save about 30 us (3.0 %) of a robot-step in dispatch" in text and "2.50x the particles" in text
    none = profile_step.robots_fused_text(dataclasses.replace(s, weighed=0, weighed_stacked=0), 2e-6)
    assert "no measurement update ran" in none and "nan" not in none  # printed "nanx the particles"
