"""`agents.worker_vec_env.WorkersVecEnv`: batched robots in worker processes, equal bit for bit to one process."""

import dataclasses
import os
import signal
import threading
import time

import gymnasium as gym
import numpy as np
import pytest
import torch
from helpers import strictly_equal

from agents.train import TrainConfig, train
from agents.vec_env import SB3VecEnvAdapter
from agents.worker_vec_env import WorkersVecEnv, batched_block
from semreloc_env.envs.batched import SemRelocLoopVectorEnv
from semreloc_env.wrappers import BeliefObservation

KW = dict(layout="twin_rooms", relocalizer={"n_particles": 200}, max_episode_steps=7)


class RaisesAtStep(gym.Wrapper):
    """Raises KeyError at its ``at``-th step (counted over episodes); a picklable wrapper for the workers."""

    def __init__(self, env, at: int):
        super().__init__(env)
        self.at, self.count = at, 0

    def step(self, action):
        self.count += 1
        if self.count == self.at:
            raise KeyError("a robot's own failure")
        return self.env.step(action)


class Slow(gym.Wrapper):
    """Sleeps ``delay`` seconds in each step (set through ``set_attr``); holds a lock when asked (no pickling)."""

    delay = 0.0

    def step(self, action):
        time.sleep(self.delay)
        return self.env.step(action)

    def hold_a_lock(self):
        self.lock = threading.Lock()

    def make_bad(self):
        return TwoArgs("a", "b")


class TwoArgs(Exception):
    """Pickles, but does not unpickle (its arguments are not its ``args``)."""

    def __init__(self, a, b):
        super().__init__(a)


def _slow_block(n: int, first: int):
    return batched_block("SemReloc-v22", Slow, **KW)(n, first)


def _block_where_robot_3_fails_at_step_3(n: int, first: int):
    block = batched_block("SemReloc-v22", **{**KW, "max_episode_steps": 50})(n, first)
    if first <= 3 < first + n:
        block.envs[3 - first] = RaisesAtStep(block.envs[3 - first], 3)  # the adapter's list is the batched env's
    return block


def _pair(num_envs=5, workers=2, **kw):
    kw = {**KW, **kw}
    ref = SB3VecEnvAdapter(SemRelocLoopVectorEnv(num_envs, wrapper=BeliefObservation, **kw))
    return WorkersVecEnv(batched_block("SemReloc-v22", BeliefObservation, **kw), num_envs, workers), ref


@pytest.fixture(scope="module")
def pair():
    workers, ref = _pair()
    yield workers, ref
    workers.close()
    ref.close()


def test_the_workers_equal_one_process_bit_for_bit_through_episode_ends(pair):
    workers, ref = pair
    assert workers.workers == 2 and workers.num_envs == 5
    assert workers.observation_space == ref.observation_space and workers.action_space == ref.action_space
    for v in pair:
        v.seed(30)
    assert strictly_equal(workers.reset(), ref.reset())
    assert strictly_equal(workers.reset_infos, ref.reset_infos)
    rng = np.random.default_rng(1)
    ends = 0
    for _ in range(16):  # two episode ends per robot: SB3's terminal_observation and the reset inside the step
        actions = rng.integers(0, 4, 5)
        got, want = workers.step(actions), ref.step(actions)
        assert strictly_equal(list(got), list(want))
        ends += int(got[2].sum())
    assert ends == 10
    assert strictly_equal(workers.reset_infos, ref.reset_infos)


def test_attributes_and_methods_reach_the_robots_asked_in_the_order_asked(pair):
    workers, _ = pair
    workers.set_attr("marker", "x", indices=[4, 1])
    assert workers.get_attr("marker", indices=[4, 1]) == ["x", "x"]
    assert workers.get_attr("marker", indices=4) == ["x"]
    seeds = workers.env_method("get_wrapper_attr", "np_random_seed")
    assert len(seeds) == 5
    assert workers.env_method("get_wrapper_attr", "np_random_seed", indices=[3, 0, 4]) == [seeds[3], seeds[0], seeds[4]]
    assert workers.env_is_wrapped(BeliefObservation) == [True] * 5
    cpu = workers.worker_cpu_seconds()
    assert len(cpu) == 2 and all(c > 0 for c in cpu)


def test_an_invalid_action_or_seed_is_refused_before_any_robot_moves(pair):
    workers, ref = pair
    for v in pair:
        v.seed(50)
        v.reset()
    with pytest.raises(ValueError, match=r"robot 4: invalid action") as err:
        workers.step(np.array([0, 1, 2, 3, 9]))  # worker 1's second robot
    assert any("worker 1, which runs robots 3 to 4" in n for n in getattr(err.value, "__notes__", [])) or not hasattr(
        err.value, "add_note"
    )
    with pytest.raises(ValueError, match="got 4 actions for 5 robots"):
        workers.step(np.array([0, 1, 2, 3]))
    with pytest.raises(ValueError, match="seed must be None or an int"):
        workers.seed("7")
    workers.set_options([{}, {}, {}, {"no_such_option": 1}, {}])
    with pytest.raises(ValueError, match="robot 3: "):
        workers.reset()
    actions = np.array([0, 1, 2, 3, 0])  # nothing moved or reset above: the same step as the reference's
    assert strictly_equal(list(workers.step(actions)), list(ref.step(actions)))


def test_a_robot_raising_mid_step_stops_every_worker_until_a_reset():
    workers = WorkersVecEnv(_block_where_robot_3_fails_at_step_3, num_envs=4, workers=2)
    try:
        workers.reset()
        workers.step(np.zeros(4, dtype=np.int64))
        workers.step(np.zeros(4, dtype=np.int64))
        with pytest.raises(KeyError, match="a robot's own failure") as err:
            workers.step(np.zeros(4, dtype=np.int64))
        assert "in step" in str(err.value.__cause__)  # the worker's traceback
        with pytest.raises(
            RuntimeError,
            match=r"robot 3 raised KeyError in the last step\(\).*\(worker 1\); the other workers' robots 0 to 1 had",
        ):
            workers.step(np.zeros(4, dtype=np.int64))
        workers.reset()
        assert workers.step(np.zeros(4, dtype=np.int64))[0]["lidar"].shape[0] == 4
    finally:
        workers.close()
    workers.close()  # twice is fine
    with pytest.raises(RuntimeError, match="closed"):
        workers.reset()


def test_bad_arguments_and_a_block_that_fails_to_build_are_clear_errors():
    with pytest.raises(ValueError, match="workers must be an int from 1 to num_envs"):
        WorkersVecEnv(batched_block("SemReloc-v22"), num_envs=2, workers=3)
    with pytest.raises(ValueError, match="num_envs must be an int >= 1"):
        WorkersVecEnv(batched_block("SemReloc-v22"), num_envs=0)
    with pytest.raises(TypeError, match="make_block must be a callable"):
        WorkersVecEnv("SemReloc-v22", num_envs=2)
    with pytest.raises(TypeError, match="no_such_argument"):
        WorkersVecEnv(batched_block("SemReloc-v22", no_such_argument=1), num_envs=2, workers=2)
    with pytest.raises(ValueError, match="workers > 1 needs vec_env 'batched'"):
        TrainConfig(vec_env="dummy", workers=2)
    with pytest.raises(ValueError, match=r"workers must be at most n_envs \(4\)"):
        TrainConfig(vec_env="batched", n_envs=4, workers=5)


def test_ppo_trains_the_same_model_with_the_robots_in_two_workers():
    cfg = TrainConfig(
        n_envs=4, vec_env="batched", n_steps=32, batch_size=64, n_epochs=1, total_timesteps=256, env_kwargs=dict(KW)
    )
    one = train(cfg)
    two = train(dataclasses.replace(cfg, workers=2))
    assert isinstance(two.get_env(), WorkersVecEnv)
    for v in (one.get_env(), two.get_env()):
        v.close()
    a, b = one.policy.state_dict(), two.policy.state_dict()
    assert a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)


def test_ctrl_c_a_dead_worker_and_odd_calls_leave_clear_errors_and_nothing_lost():
    # Python's Ctrl-C handler, even where the test process started with SIGINT ignored (a shell's background job)
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        _ctrl_c_a_dead_worker_and_odd_calls()
    finally:
        signal.signal(signal.SIGINT, previous)


def _ctrl_c_a_dead_worker_and_odd_calls():
    workers = WorkersVecEnv(_slow_block, num_envs=6, workers=2)
    try:
        workers.seed(0)
        workers.reset()
        # a NaN among discrete actions is named by its robot in the whole set
        with pytest.raises(ValueError, match=r"robots \[4\] hold NaN or inf"):
            workers.step(np.array([0, 1, 0, 0, np.nan, 0.0]))
        # options must be one per robot, as in one process
        with pytest.raises(ValueError, match="got 7 options dicts for 6 robots"):  # refused when set, as in one process
            workers.set_options([{}] * 7)
        with pytest.raises(ValueError, match="options must be None, a dict or a list"):
            workers.set_options(5)
        workers.set_options(None)
        # keyword arguments of any name, and negative indices as in DummyVecEnv
        workers.set_attr("tag", "t5", indices=-1)
        assert workers.env_method("get_wrapper_attr", name="tag", indices=[-1]) == ["t5"]
        assert workers.get_attr("tag", indices=[5, -1]) == ["t5", "t5"]
        with pytest.raises(IndexError, match="robot index 6 out of range"):
            workers.get_attr("tag", indices=[6])
        # a result that does not pickle is an error, and the worker goes on
        workers.env_method("hold_a_lock", indices=[4])
        with pytest.raises(TypeError, match="pickle"):
            workers.get_attr("lock", indices=[4])
        assert workers.get_attr("tag", indices=[5]) == ["t5"]
        # Ctrl-C while the workers step: the robots are out of step until a reset, which works
        workers.set_attr("delay", 1.5, indices=[3])
        threading.Timer(0.5, os.kill, (os.getpid(), signal.SIGINT)).start()
        with pytest.raises(KeyboardInterrupt):
            workers.step(np.zeros(6, dtype=np.int64))
        with pytest.raises(RuntimeError, match=r"the last step\(\) was interrupted .*call reset\(\)"):
            workers.step(np.zeros(6, dtype=np.int64))
        workers.set_attr("delay", 0.0)
        workers.reset()
        assert workers.step(np.zeros(6, dtype=np.int64))[1].shape == (6,)
        # a worker that dies: every later call says so, and close still works
        os.kill(workers.processes[1].pid, signal.SIGKILL)
        workers.processes[1].join(5.0)
        for _ in range(2):
            with pytest.raises(RuntimeError, match=r"worker 1 \(robots 3 to 5\) is gone \(exit code -9\): close"):
                workers.step(np.zeros(6, dtype=np.int64))
        with pytest.raises(RuntimeError, match="is gone"):
            workers.reset()
    finally:
        workers.close()
    assert not any(p.is_alive() for p in workers.processes)
    with pytest.raises(RuntimeError, match="closed"):
        workers.step(np.zeros(6, dtype=np.int64))


def test_answers_and_arguments_that_do_not_unpickle_and_a_signal_handlers_error_leave_the_workers_usable():
    workers = WorkersVecEnv(_slow_block, num_envs=4, workers=2)
    try:
        workers.seed(0)
        workers.reset()
        with pytest.raises(RuntimeError, match="worker 0's answer did not unpickle here"):
            workers.env_method("make_bad", indices=[0])
        assert workers.get_attr("delay", indices=[0, 3]) == [0.0, 0.0]  # no hang, no stale answer
        with pytest.raises(TypeError, match="missing 1 required positional argument"):
            workers.set_attr("bad", TwoArgs("a", "b"), indices=[3])
        assert workers.get_attr("delay", indices=[3]) == [0.0]  # the worker lives on
        # a TimeoutError from the caller's own alarm is the caller's: the workers are not "gone"
        workers.set_attr("delay", 1.0, indices=[3])

        def alarm(signum, frame):
            raise TimeoutError("the caller's own time limit")

        previous = signal.signal(signal.SIGALRM, alarm)
        try:
            signal.setitimer(signal.ITIMER_REAL, 0.3)
            with pytest.raises(TimeoutError):
                workers.step(np.zeros(4, dtype=np.int64))
        finally:
            signal.setitimer(signal.ITIMER_REAL, 0)
            signal.signal(signal.SIGALRM, previous)
        with pytest.raises(RuntimeError, match=r"the last step\(\) raised TimeoutError .*call reset\(\)"):
            workers.step(np.zeros(4, dtype=np.int64))
        workers.set_attr("delay", 0.0)
        workers.reset()
        assert workers.step(np.zeros(4, dtype=np.int64))[2].shape == (4,)
    finally:
        workers.close()


def test_continuous_actions_of_the_wrong_shape_and_a_closed_adapter_are_refused_as_in_one_process():
    kw = {**KW, "action_type": "continuous"}
    workers = WorkersVecEnv(batched_block("SemReloc-v22", **kw), num_envs=3, workers=2)
    one = SB3VecEnvAdapter(SemRelocLoopVectorEnv(3, **kw))
    try:
        for v in (workers, one):
            v.reset()
            for bad in (np.zeros((3, 3), np.float32), np.zeros(3, np.float32)):
                with pytest.raises(ValueError, match=r"must have shape \(3, 2\)") as err:
                    v.step(bad)
                assert f"got shape {bad.shape}" in str(err.value)
    finally:
        workers.close()
        one.close()
    for v in (workers, one):
        with pytest.raises(RuntimeError, match="is closed"):
            v.step(np.zeros((3, 2), np.float32))


def test_a_training_run_that_fails_stops_its_workers():
    import multiprocessing

    from stable_baselines3.common.callbacks import BaseCallback

    class Fails(BaseCallback):
        def _on_step(self) -> bool:
            raise RuntimeError("a callback's own failure")

    cfg = TrainConfig(
        n_envs=2, vec_env="batched", workers=2, n_steps=16, batch_size=32, total_timesteps=32, env_kwargs=KW
    )
    before = set(multiprocessing.active_children())  # the module's fixture keeps its own workers
    with pytest.raises(RuntimeError, match="a callback's own failure"):
        train(cfg, callbacks=[Fails()])
    assert not set(multiprocessing.active_children()) - before


def _block_where_robots_1_and_3_fail_at_step_2(n: int, first: int):
    block = batched_block("SemReloc-v22", **{**KW, "max_episode_steps": 50})(n, first)
    for robot in (1, 3):
        if first <= robot < first + n:
            block.envs[robot - first] = RaisesAtStep(block.envs[robot - first], 2)
    return block


def test_a_failing_robot_is_named_at_once_and_every_worker_that_failed_is_named_as_failed():
    # an outside audit's: the first error did not name the robot (SB3's learn() never makes the call that did), and
    # with two workers failing the message said the second worker's robots "had run it"
    workers = WorkersVecEnv(_block_where_robots_1_and_3_fail_at_step_2, num_envs=4, workers=2)
    one = SB3VecEnvAdapter(SemRelocLoopVectorEnv(4, **{**KW, "max_episode_steps": 50}))
    one.envs[1], one.envs[3] = RaisesAtStep(one.envs[1], 2), RaisesAtStep(one.envs[3], 2)
    try:
        for v in (workers, one):
            v.reset()
            v.step(np.zeros(4, dtype=np.int64))
            with pytest.raises(KeyError, match="a robot's own failure") as err:
                v.step(np.zeros(4, dtype=np.int64))
            assert any("robot 1 raised this in step()" in note for note in err.value.__notes__)
            with pytest.raises(RuntimeError, match="out of step"):  # a review's: step_wait stepped them again
                v.step_wait()
        with pytest.raises(RuntimeError, match=r"\(worker 0\); worker 1 \(robots 2 to 3\) raised too: the robots"):
            workers.step(np.zeros(4, dtype=np.int64))
        with pytest.raises(RuntimeError, match="robot 1 raised KeyError.*robot 0 had run it and robots 2 to 3 had not"):
            one.step(np.zeros(4, dtype=np.int64))
    finally:
        workers.close()
        one.close()


def test_step_wait_without_step_async_is_refused_and_leaves_the_robots_usable():
    # an outside audit's: a TypeError from inside the robot loop, which put the robots out of step
    workers = WorkersVecEnv(batched_block("SemReloc-v22", **KW), num_envs=2, workers=2)
    one = SB3VecEnvAdapter(SemRelocLoopVectorEnv(2, **KW))
    try:
        for v in (workers, one):
            v.reset()
            with pytest.raises(RuntimeError, match=r"step_wait\(\) without step_async"):
                v.step_wait()
            assert v.step(np.zeros(2, dtype=np.int64))[0]["lidar"].shape[0] == 2
    finally:
        workers.close()
        one.close()
    with pytest.raises(RuntimeError, match="is closed"):  # the adapter stepped, read and called its closed robots
        one.get_attr("render_mode")
    with pytest.raises(RuntimeError, match="is closed"):
        one.step_wait()


def test_a_ctrl_c_in_close_ends_the_workers_at_once(monkeypatch):
    # an outside audit's: close() waited out its 10 s deadline after a Ctrl-C before it terminated the workers
    workers = WorkersVecEnv(batched_block("SemReloc-v22", **KW), num_envs=2, workers=2)
    workers.reset()
    joins = []
    for proc in workers.processes:
        join = proc.join
        monkeypatch.setattr(proc, "join", lambda timeout=None, join=join: joins.append(timeout) or join(timeout))

    class Interrupted:
        def __init__(self, conn):
            self.conn = conn

        def poll(self, timeout=None):
            raise KeyboardInterrupt

        def __getattr__(self, name):
            return getattr(self.conn, name)

    workers._waiting[0] = True
    workers._conns[0] = Interrupted(workers._conns[0])
    with pytest.raises(KeyboardInterrupt):
        workers.close()
    assert workers.closed and not any(p.is_alive() for p in workers.processes)
    assert joins == [2.0, 2.0]  # terminated at once, each joined after its end; no wait for the deadline


def test_a_ctrl_c_while_close_waits_for_the_workers_still_ends_them_and_closes(monkeypatch):
    # a review's: a Ctrl-C in close()'s joins left it half closed, workers alive and pipes open
    workers = WorkersVecEnv(batched_block("SemReloc-v22", **KW), num_envs=2, workers=2)
    workers.reset()
    first = workers.processes[0]
    join = first.join

    def interrupted_once(timeout=None):
        monkeypatch.setattr(first, "join", join)
        raise KeyboardInterrupt

    monkeypatch.setattr(first, "join", interrupted_once)
    with pytest.raises(KeyboardInterrupt):
        workers.close()
    for proc in workers.processes:
        proc.join(timeout=5.0)
    assert workers.closed and not any(p.is_alive() for p in workers.processes)
    assert all(conn.closed for conn in workers._conns)


def test_an_error_that_does_not_unpickle_keeps_its_notes():
    from agents.worker_vec_env import _picklable

    e = TwoArgs("a", "b")
    e.add_note("(robot 1 raised this in step())")
    plain = _picklable(e)
    assert isinstance(plain, RuntimeError) and plain.__notes__ == ["(robot 1 raised this in step())"]
