"""stable-baselines3 ``VecEnv`` whose robots run in a few worker processes, many robots per process.

`WorkersVecEnv` splits ``num_envs`` robots into ``workers`` contiguous blocks; each worker process builds one
block as an SB3 ``VecEnv`` of its own (`batched_block`: `agents.vec_env.SB3VecEnvAdapter` over
`semreloc_env.envs.batched.SemRelocLoopVectorEnv`; any picklable ``make_block(n, first) -> VecEnv`` works) and
steps it when told. So the robots' steps run in parallel on ``workers`` cores, while SB3's ``SubprocVecEnv`` would
start one process (each importing torch, about 400 MB) per robot and pay a round trip per robot and step.

What a policy sees is what it sees with the blocks in one process: robot ``i`` is seeded ``seed + i`` (`seed`)
and reset and stepped by SB3's rule, so the observations, rewards, dones and infos equal those of
``SB3VecEnvAdapter`` over the same robots bit for bit (``tests/test_worker_vec_env.py``).

Checks run before anything moves: `step_async` has every worker check its robots' actions, and `reset` every
robot's seed and options, before any robot steps or resets (ValueError naming the robot, with a note saying which
worker ran it). A robot that raises mid-step leaves the robots of the other workers stepped: `step_async` then
refuses (RuntimeError) until `reset`, as the batched env does.
"""

from __future__ import annotations

import contextlib
import multiprocessing as mp
import pickle
import signal
import threading
import time
import traceback
from collections.abc import Callable, Sequence
from functools import partial
from typing import Any

import cloudpickle
import numpy as np
from stable_baselines3.common.vec_env import VecEnv
from stable_baselines3.common.vec_env.base_vec_env import VecEnvObs, VecEnvStepReturn

from filters.numbers import is_int
from semreloc_env.envs.batched import SemRelocLoopVectorEnv, action_list, shortened_message

from .vec_env import SB3VecEnvAdapter, check_seed, options_per_robot


class RemoteTraceback(Exception):
    """A worker's traceback (its text), the cause of an error re-raised in the main process."""

    def __str__(self) -> str:
        return f"\n\n(the worker's traceback)\n{self.args[0]}"


def _make_batched_block(n: int, first: int, env_id: str, wrapper, kwargs: dict[str, Any]) -> VecEnv:
    return SB3VecEnvAdapter(
        SemRelocLoopVectorEnv(num_envs=n, env_id=env_id, wrapper=wrapper, first_robot=first, **kwargs)
    )


def batched_block(env_id: str, wrapper: Callable | None = None, **kwargs) -> Callable[[int, int], VecEnv]:
    """The ``make_block`` of `WorkersVecEnv` for batched SemReloc robots: ``make_block(n, first)`` builds
    ``SB3VecEnvAdapter(SemRelocLoopVectorEnv(num_envs=n, env_id=env_id, wrapper=wrapper, first_robot=first,
    **kwargs))``: its errors name robots by their number in the whole set."""
    return partial(_make_batched_block, env_id=env_id, wrapper=wrapper, kwargs=dict(kwargs))


def _picklable(e: BaseException) -> BaseException:
    try:
        pickle.loads(pickle.dumps(e))
        return e
    except Exception:  # an exception class or argument that does not pickle: its type, message and notes
        plain = RuntimeError(f"{type(e).__name__}: {e}")
        for note in getattr(e, "__notes__", ()):
            plain.add_note(note)
        return plain


def _serve(venv: VecEnv, cmd: str, data: Any) -> Any:
    if cmd == "step_async":
        venv.step_async(data)
        return None
    if cmd == "step_wait":
        out = venv.step_wait()
        return out, {int(i): venv.reset_infos[i] for i in np.flatnonzero(out[2])}  # the autoresets' infos
    if cmd == "check_reset":
        venv._seeds, venv._options = data  # SB3's per-env seeds and options for the next reset
        check = getattr(venv, "check_reset", None)
        if check is not None:
            check()
        return None
    if cmd == "reset":
        return venv.reset(), venv.reset_infos
    if cmd == "call":
        name, args, kwargs = data
        return getattr(venv, name)(*args, **kwargs)
    if cmd == "cpu":
        return time.process_time()
    raise ValueError(f"unknown command {cmd!r}")


def _failure(venv: VecEnv | None, e: BaseException) -> tuple:
    """An error's message to the main process: the exception, its traceback, and why the block's robots are out of
    step if they are (a batched block names the robot that raised)."""
    batched = getattr(venv, "venv", None)
    return "error", (_picklable(e), traceback.format_exc(), getattr(batched, "out_of_step", None))


def _worker(conn, parent_end, payload: bytes, n: int, first: int) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the main process's to handle (it closes us)
    parent_end.close()
    venv = None
    try:
        venv = cloudpickle.loads(payload)(n, first)
        if not isinstance(venv, VecEnv) or venv.num_envs != n:
            raise TypeError(f"make_block({n}, {first}) must return an SB3 VecEnv of {n} envs, got {venv!r:.80}")
        conn.send(("ok", (venv.observation_space, venv.action_space)))
    except BaseException as e:
        conn.send(_failure(None, e))
        return
    while True:
        try:
            message = conn.recv_bytes()
        except (EOFError, OSError):  # the main process is gone
            break
        try:
            cmd, data = pickle.loads(message)
        except Exception as e:  # say, an argument whose class this process cannot import
            conn.send(_failure(venv, e))
            continue
        if cmd == "close":
            venv.close()
            conn.send(("ok", None))
            break
        try:
            out = ("ok", _serve(venv, cmd, data))
        except BaseException as e:
            out = _failure(venv, e)
        try:
            conn.send(out)  # pickled before anything is written: a result that does not pickle leaves the pipe clean
        except Exception as e:
            conn.send(_failure(venv, e))


@contextlib.contextmanager
def _whole_messages():
    """Hold a Ctrl-C (SIGINT) back until the block ends, so that a message to or from a worker is never cut in two
    (the pipe would be out of step for good); in the main thread only, where Python runs signal handlers."""
    if threading.current_thread() is not threading.main_thread() or signal.getsignal(signal.SIGINT) is None:
        yield  # not the main thread, or a handler installed from C, which Python cannot put back
        return
    held: list[int] = []
    previous = signal.signal(signal.SIGINT, lambda signum, frame: held.append(signum))
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
        if held and callable(previous):
            previous(signal.SIGINT, None)  # Python's own handler raises KeyboardInterrupt here


class WorkersVecEnv(VecEnv):
    """SB3 ``VecEnv`` of ``num_envs`` robots in ``workers`` processes (see the module docstring).

    Args:
        make_block: ``make_block(n, first) -> VecEnv``, run in each worker with its block's size and the index of
            its first robot; pickled with cloudpickle (a lambda or closure will do). `batched_block` makes the
            batched SemReloc one.
        num_envs: robots (>= 1).
        workers: processes (1 to ``num_envs``); worker ``w`` runs the ``w``-th of ``workers`` contiguous blocks,
            sized as ``numpy.array_split`` does.
        start_method: ``multiprocessing`` start method (default ``"forkserver"`` where there is one, else
            ``"spawn"``, as SB3's ``SubprocVecEnv``; both need the main module import-safe: ``if __name__ ==
            "__main__":``).

    A Ctrl-C while the workers step interrupts the wait (the robots are then out of step until `reset`); a message
    to or from a worker is never cut in two. A worker that dies makes every later call a RuntimeError that says
    so: `close` is what is left.
    """

    def __init__(
        self,
        make_block: Callable[[int, int], VecEnv],
        num_envs: int,
        workers: int = 2,
        start_method: str | None = None,
    ):
        if not callable(make_block):
            raise TypeError(f"make_block must be a callable (n, first) -> VecEnv, got {make_block!r:.80}")
        if not (is_int(num_envs) and num_envs >= 1):
            raise ValueError(f"num_envs must be an int >= 1, got {num_envs!r:.80}")
        if not (is_int(workers) and 1 <= workers <= num_envs):
            raise ValueError(f"workers must be an int from 1 to num_envs ({num_envs}), got {workers!r:.80}")
        if start_method is None:
            start_method = "forkserver" if "forkserver" in mp.get_all_start_methods() else "spawn"
        ctx = mp.get_context(start_method)
        self.num_envs = int(num_envs)
        sizes = [len(b) for b in np.array_split(np.arange(self.num_envs), int(workers))]
        self._first = np.cumsum([0, *sizes[:-1]]).tolist()
        self._sizes = sizes
        self._worker_of = np.repeat(np.arange(len(sizes)), sizes)
        self._out_of_step: str | None = None
        self._gone: str | None = None  # why the workers cannot be used any more (one died)
        self._failed: int | None = None  # the worker whose error the last call raised
        self._failed_why: str | None = None  # why its robots are out of step, as its block says
        self._also_failed: list[int] = []  # the other workers that raised in the last call
        self._acted = False  # actions taken by step_async since the last reset
        self._waiting = [False] * len(sizes)
        self.closed = False
        payload = cloudpickle.dumps(make_block)
        self._conns, self.processes = [], []
        for first, n in zip(self._first, sizes):
            ours, theirs = ctx.Pipe()
            proc = ctx.Process(target=_worker, args=(theirs, ours, payload, n, first), daemon=True)
            proc.start()
            theirs.close()
            self._conns.append(ours)
            self.processes.append(proc)
        try:
            spaces = self._gather(range(len(sizes)))
            if any(s != spaces[0] for s in spaces[1:]):
                raise ValueError(f"the workers' blocks have different spaces: {spaces}")
            super().__init__(self.num_envs, *spaces[0])
        except BaseException:
            self.close()
            raise

    @property
    def workers(self) -> int:
        return len(self._sizes)

    # ------------------------------------------------------------------ messaging
    def _block(self, w: int) -> slice:
        return slice(self._first[w], self._first[w] + self._sizes[w])

    def _block_text(self, w: int) -> str:
        block = self._block(w)
        return f"robot {block.start}" if self._sizes[w] == 1 else f"robots {block.start} to {block.stop - 1}"

    def _usable(self) -> None:
        if self.closed:
            raise RuntimeError("this WorkersVecEnv is closed")
        if self._gone is not None:
            raise RuntimeError(self._gone)

    def _lost(self, w: int) -> RuntimeError:
        self.processes[w].join(timeout=0.5)
        self._gone = (
            f"worker {w} ({self._block_text(w)}) is gone (exit code {self.processes[w].exitcode}): close this VecEnv"
        )
        return RuntimeError(self._gone)

    def _send(self, w: int, cmd: str, data: Any = None) -> None:
        self._usable()
        with _whole_messages():
            try:
                self._conns[w].send((cmd, data))
            except ConnectionError as e:
                raise self._lost(w) from e
            self._waiting[w] = True

    def _recv(self, w: int) -> tuple[str, Any]:
        conn = self._conns[w]
        try:
            while not conn.poll(0.05):  # a Ctrl-C while waiting leaves the answer for `_drain`
                if not self.processes[w].is_alive() and not conn.poll():
                    raise EOFError
            with _whole_messages():
                message = conn.recv_bytes()
                self._waiting[w] = False
        except (EOFError, ConnectionError) as e:  # not any OSError: a signal handler's TimeoutError is the caller's
            raise self._lost(w) from e
        try:
            return pickle.loads(message)
        except Exception as e:  # an answer whose class this process cannot rebuild: that call's error
            error = RuntimeError(f"worker {w}'s answer did not unpickle here: {type(e).__name__}: {e}")
            error.__cause__ = e
            return "error", (error, traceback.format_exc(), None)

    def _gather(self, ws: Sequence[int]) -> list:
        """Every worker's answer, in order; the first worker's error is raised once all have answered."""
        outs, error = [], None
        self._failed, self._also_failed = None, []
        for w in ws:
            status, out = self._recv(w)
            if status == "error" and error is None:
                error = self._noted(w, *out)
            elif status == "error":
                self._also_failed.append(w)
            outs.append(out)
        if error is not None:
            raise error
        return outs

    def _noted(self, w: int, e: BaseException, tb: str, out_of_step: str | None) -> BaseException:
        self._failed, self._failed_why = w, out_of_step
        if hasattr(e, "add_note"):  # Python 3.11+
            e.add_note(f"(raised in worker {w}, which runs {self._block_text(w)})")
        e.__cause__ = RemoteTraceback(tb)  # printed above the error, as concurrent.futures does
        return e

    def _drain(self) -> None:
        """Read the answers a Ctrl-C left unread, so the pipes are in step again."""
        for w, waiting in enumerate(self._waiting):
            if waiting:
                self._recv(w)

    def _all(self, cmd: str, per_worker: Sequence[Any] | None = None) -> list:
        self._usable()
        self._drain()
        ws = range(self.workers)
        for w in ws:
            self._send(w, cmd, None if per_worker is None else per_worker[w])
        return self._gather(ws)

    def _stopped(self, call: str, e: BaseException) -> None:
        """Remember that the robots are out of step after ``e`` interrupted ``call`` (unless a worker is gone)."""
        if self._gone is not None:
            return
        if isinstance(e, KeyboardInterrupt):
            self._out_of_step = (
                f"the last {call}() was interrupted (KeyboardInterrupt): the robots are out of step, call reset()"
            )
            return
        w = self._failed
        if w is None:
            self._out_of_step = f"the last {call}() raised {type(e).__name__} ({shortened_message(e)}): call reset()"
            return
        others = [self._block_text(v) for v in range(self.workers) if v != w and v not in self._also_failed]
        why = (
            self._failed_why
            or f"{self._block_text(w)} raised {type(e).__name__} in the last {call}() ({shortened_message(e)})"
        )
        why = why.removesuffix(": the robots are out of step, call reset()")
        ran = f"; the other workers' {', '.join(others)} had run it" if others and call == "step" else ""
        also = [f"worker {v} ({self._block_text(v)})" for v in self._also_failed]
        raised = f"; {', '.join(also)} raised too" if also else ""
        self._out_of_step = f"{why} (worker {w}){ran}{raised}: the robots are out of step, call reset()"

    # ------------------------------------------------------------------ VecEnv
    def seed(self, seed: int | None = None):
        """SB3's seeding (robot ``i`` gets ``seed + i`` at the next reset); ValueError unless ``seed`` is None
        or an int."""
        return super().seed(check_seed(seed))

    def set_options(self, options: list[dict] | dict | None = None) -> None:
        """SB3's ``set_options``, its shape checked now (`agents.vec_env.options_per_robot`; each robot's options are
        checked at the next `reset`, before any robot resets)."""
        self._options = options_per_robot(options, self.num_envs)

    def reset(self) -> VecEnvObs:
        """Reset every robot; every robot's seed and options are checked first (ValueError, nothing reset)."""
        self._usable()
        seeds, options = list(self._seeds), list(self._options)  # one dict per robot: set_options checks it
        self._all("check_reset", [(seeds[self._block(w)], options[self._block(w)]) for w in range(self.workers)])
        try:
            outs = self._all("reset")
        except BaseException as e:
            self._stopped("reset", e)
            raise
        self._out_of_step = None
        self._acted = False
        self._reset_seeds()
        self._reset_options()
        self.reset_infos = [info for _, infos in outs for info in infos]
        return _concat([obs for obs, _ in outs])

    def step_async(self, actions: np.ndarray) -> None:
        """RuntimeError after a robot raised in the last step or reset (until `reset`); ValueError naming the robot
        if an action is invalid (every worker checks its robots' actions before any robot moves)."""
        self._usable()
        if self._out_of_step is not None:
            raise RuntimeError(self._out_of_step)
        self._acted = False  # refused actions leave none to step with
        action_list(actions, self.num_envs, self.action_space)  # the batch's checks, with the whole set's numbers
        self._all("step_async", [actions[self._block(w)] for w in range(self.workers)])
        self._acted = True

    def step_wait(self) -> VecEnvStepReturn:
        """Step every robot with the actions `step_async` took. RuntimeError, nothing stepped, when unusable, out of
        step (a robot raised: until `reset`) or without a `step_async` since the last reset."""
        self._usable()
        if self._out_of_step is not None:
            raise RuntimeError(self._out_of_step)
        if not self._acted:
            raise RuntimeError("step_wait() without step_async(actions) first: nothing to step with")
        try:
            outs = self._all("step_wait")
        except BaseException as e:
            self._stopped("step", e)
            raise
        for w, (_, reset_infos) in enumerate(outs):
            for i, info in reset_infos.items():
                self.reset_infos[self._first[w] + i] = info
        outs = [o for o, _ in outs]
        obs = _concat([o[0] for o in outs])
        rewards = np.concatenate([o[1] for o in outs])
        dones = np.concatenate([o[2] for o in outs])
        return obs, rewards, dones, [info for o in outs for info in o[3]]

    def close(self) -> None:
        """Ask every worker to close its robots and stop, waiting 10 s in all for those still stepping, then end the
        processes (terminated if they have not stopped by then, or on a Ctrl-C meanwhile); twice is fine."""
        if self.closed:
            return
        deadline = time.monotonic() + 10.0

        def left() -> float:
            return max(0.0, deadline - time.monotonic())

        interrupted = False
        try:
            for w, conn in enumerate(self._conns):
                try:
                    if self._waiting[w] and conn.poll(left()):
                        with _whole_messages():
                            conn.recv_bytes()
                            self._waiting[w] = False
                    if not self._waiting[w]:
                        with _whole_messages():
                            conn.send(("close", None))
                except (EOFError, OSError):
                    pass
            for w, conn in enumerate(self._conns):
                try:
                    if not self._waiting[w] and conn.poll(left()):
                        conn.recv_bytes()
                except (EOFError, OSError):
                    pass
        except KeyboardInterrupt:
            interrupted = True  # end the workers now, not at the deadline
            raise
        finally:
            try:
                for proc in self.processes:
                    if not interrupted:
                        proc.join(timeout=left())
                    if proc.is_alive():
                        proc.terminate()
                        proc.join(timeout=2.0)
            except KeyboardInterrupt:  # a Ctrl-C while waiting for them: end the rest at once
                for proc in self.processes:
                    if proc.is_alive():
                        proc.terminate()
                raise
            finally:
                for conn in self._conns:
                    conn.close()
                self._waiting = [False] * self.workers
                self.closed = True

    def worker_cpu_seconds(self) -> list[float]:
        """Each worker's CPU time so far (``time.process_time`` in that process, s): what a CPU-time benchmark adds
        to this process's own."""
        return self._all("cpu")

    def _call(self, method: str, indices, /, *args, **kwargs) -> list:
        """``block.method(*args, indices=<the block's own indices>, **kwargs)`` in each worker, the results in the
        order of ``indices`` (negative ones count from the end, as in ``DummyVecEnv``)."""
        self._usable()
        self._drain()
        order = []
        for i in self._get_indices(indices):
            if not -self.num_envs <= int(i) < self.num_envs:
                raise IndexError(f"robot index {i} out of range for {self.num_envs} robots")
            order.append(int(i) % self.num_envs)
        parts: dict[int, list[int]] = {}
        for i in order:
            w = int(self._worker_of[i])
            parts.setdefault(w, []).append(i - self._first[w])
        for w, local in parts.items():
            self._send(w, "call", (method, args, {**kwargs, "indices": local}))
        answers = {w: iter(out or [None] * len(parts[w])) for w, out in zip(parts, self._gather(list(parts)))}
        return [next(answers[int(self._worker_of[i])]) for i in order]

    def get_attr(self, attr_name: str, indices=None) -> list[Any]:
        return self._call("get_attr", indices, attr_name)

    def set_attr(self, attr_name: str, value: Any, indices=None) -> None:
        self._call("set_attr", indices, attr_name, value)

    def env_method(self, method_name: str, *method_args, indices=None, **method_kwargs) -> list[Any]:
        return self._call("env_method", indices, method_name, *method_args, **method_kwargs)

    def env_is_wrapped(self, wrapper_class, indices=None) -> list[bool]:
        return self._call("env_is_wrapped", indices, wrapper_class)

    def get_images(self) -> Sequence[np.ndarray | None]:
        return [None] * self.num_envs


def _concat(parts: list) -> VecEnvObs:
    if isinstance(parts[0], dict):
        return {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
    return np.concatenate(parts)
