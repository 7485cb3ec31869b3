"""The experiment runner: a list of seeded jobs mapped over one function, sequentially, in a local
process pool or on Ray (this machine or a cluster), with the same results in job order either way.

Contract of a job function ``fn(job) -> result``:

* it is a module-level function (importable by name: process pools and Ray pickle it by reference);
* ``job`` and ``result`` are picklable plain data (tuples, dicts, dataclasses, NumPy arrays);
* every random draw inside comes from generators seeded from ``job`` alone (for example
  ``np.random.default_rng([seed, run, ...])``), never from global state or from the order in which
  jobs run. Then `run_jobs` returns the same list with every executor and any worker count
  (wall-clock and CPU times measured inside a job aside).

Use::

    from filters.experiments.runner import RunnerConfig, run_jobs

    if __name__ == "__main__":  # process workers import the script that started them: guard its top level
        results = run_jobs(my_job, [(seed, r) for r in range(100)], RunnerConfig(workers=2), desc="runs")

A command line gets the runner's options by holding a ``runner: filters.experiments.cli.Runner`` field in its tyro
``Args`` dataclass (``--executor``, ``--workers``, ``--address``, ``--progress/--no-progress``;
see `filters.experiments.cli`).

Executors (``RunnerConfig.executor``):

* ``"sequential"``: ``[fn(j) for j in jobs]`` in this process.
* ``"process"``: a `concurrent.futures.ProcessPoolExecutor` of ``workers`` processes, started from a clean
  process (``forkserver``; ``spawn`` where there is none), never forked from the caller.
* ``"ray"``: one Ray task per job (``num_cpus=1`` each). If Ray is not initialised yet, the runner
  calls ``ray.init(address=address)`` for a cluster (``"auto"``, ``"ray://head:10001"``, ...) or,
  with no address, ``ray.init(address="local", num_cpus=workers, include_dashboard=False)``: a private
  instance on this machine, also when ``ray start`` left a cluster running here (pass ``--address auto`` to
  use that one), and
  shuts Ray down afterwards; an already initialised Ray is used as it is and left running. Ray is
  the optional extra ``ray`` (``pip install -e ".[ray]"``); every node of a cluster needs this
  package installed at the same commit (see docs/cluster.md).
* ``"auto"`` (default): ``"ray"`` if an address is given, else ``"process"`` if ``workers > 1``,
  else ``"sequential"``.
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys
import threading
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from typing import Any, Literal

from filters.numbers import is_int

__all__ = ["EXECUTORS", "RunnerConfig", "run_jobs"]

EXECUTORS = ("auto", "sequential", "process", "ray")

Executor = Literal["auto", "sequential", "process", "ray"]


@dataclass(frozen=True)
class RunnerConfig:
    """How the runs are executed; the results do not depend on it (docs/cluster.md)."""

    executor: Executor = "auto"
    """auto (ray with --address, process pool with --workers > 1, else sequential), sequential, process or ray"""
    workers: int = 1
    """worker processes (process pool) or CPUs given to a local Ray; ignored on a Ray cluster"""
    address: str = ""
    """Ray cluster address ('auto' or 'ray://<head>:10001'); empty = run on this machine"""
    progress: bool = True
    """show a progress bar on stderr"""

    def __post_init__(self) -> None:
        if self.executor not in EXECUTORS:
            raise ValueError(f"executor must be one of {EXECUTORS}, got {self.executor!r}")
        if not is_int(self.workers) or self.workers < 1:
            raise ValueError(f"workers must be an int >= 1, got {self.workers!r}")
        object.__setattr__(self, "workers", int(self.workers))
        if self.address and self.executor not in ("auto", "ray"):
            raise ValueError(f"address {self.address!r} needs the ray executor, not {self.executor!r}")

    def describe(self) -> str:
        """Where the jobs ran, for a report: "one process", "2 worker processes", "a local Ray of 2 CPUs",
        "the Ray cluster at auto"."""
        kind = self.resolved_executor
        n = self.workers
        plural = "" if n == 1 else "s"
        if kind == "sequential":
            return "one process"
        if kind == "process":
            return f"{n} worker process" + ("es" if plural else "")
        return f"the Ray cluster at {self.address}" if self.address else f"a local Ray of {n} CPU{plural}"

    @property
    def resolved_executor(self) -> str:
        """The executor ``"auto"`` stands for with these settings."""
        if self.executor != "auto":
            return self.executor
        if self.address:
            return "ray"
        return "process" if self.workers > 1 else "sequential"


def run_jobs(
    fn: Callable[[Any], Any],
    jobs: Sequence[Any],
    config: RunnerConfig | None = None,
    desc: str = "jobs",
    on_result: Callable[[int, int], None] | None = None,
) -> list:
    """``[fn(job) for job in jobs]``, executed as ``config`` says; results in the order of ``jobs``.

    ``on_result(done, total)`` is called in this process after each finished job (in completion
    order); ``config.progress`` adds a tqdm bar named ``desc`` on stderr. An exception raised by a
    job propagates as soon as it is raised (in a pool: the first to fail; the other jobs are cancelled
    and the workers stopped, as after Ctrl-C or SIGTERM).
    """
    config = config or RunnerConfig()
    jobs = list(jobs)
    if not jobs:
        return []
    bar = None
    if config.progress:
        from tqdm import tqdm

        bar = tqdm(total=len(jobs), desc=desc, unit="job", file=sys.stderr)
    done = 0

    def tick() -> None:
        nonlocal done
        done += 1
        if bar is not None:
            bar.update(1)
        if on_result is not None:
            on_result(done, len(jobs))

    try:
        kind = config.resolved_executor
        if kind == "sequential":
            out = []
            for job in jobs:
                out.append(fn(job))
                tick()
            return out
        if kind == "process":
            pool = ProcessPoolExecutor(
                max_workers=config.workers,
                mp_context=_worker_context(),
                initializer=_set_environ,
                initargs=(dict(os.environ),),
            )
            try:
                with _sigterm_as_exit() as sigterm:
                    try:
                        futures = {pool.submit(fn, job): i for i, job in enumerate(jobs)}
                        sigterm.armed()  # a SIGTERM while the workers started is raised now
                        out = [None] * len(jobs)
                        for future in as_completed(futures):  # a failure surfaces as soon as it happens
                            out[futures[future]] = future.result()
                            tick()
                    except BaseException:  # a job's error, Ctrl-C, SIGTERM: no worker may outlive this call
                        _stop_workers(pool)
                        raise
                    pool.shutdown(wait=True)
            except BrokenProcessPool as e:
                raise RuntimeError(
                    f"a worker process died or could not return its result ({e}; the chained error below may say "
                    "more). Possible causes: it ran out of memory or crashed; a job's result or exception cannot be "
                    "unpickled; or, since workers start from a clean process, the job function "
                    f"({getattr(fn, '__module__', '?')}.{getattr(fn, '__qualname__', fn)}) is not importable by "
                    "name (defined in `python -c`, a notebook or a function), or the script that calls run_jobs "
                    'lacks `if __name__ == "__main__":` around its top level. The sequential executor runs '
                    "without workers"
                ) from e
            return out
        return _run_ray(fn, jobs, config, tick)
    finally:
        if bar is not None:
            bar.close()


class _SigTerm:
    """SIGTERM as ``SystemExit(143)``, held back until `armed` while the pool starts its workers (an exit
    inside ``submit`` could leave a half-started worker that nothing stops)."""

    def __init__(self) -> None:
        self.starting = True
        self.pending = False

    def __call__(self, signum, frame) -> None:
        if self.starting:
            self.pending = True
            return
        raise SystemExit(128 + signum)

    def armed(self) -> None:
        self.starting = False
        if self.pending:
            raise SystemExit(128 + signal.SIGTERM)


@contextlib.contextmanager
def _sigterm_as_exit() -> Iterator[_SigTerm]:
    """Within the block, SIGTERM (``timeout``, a batch scheduler, ``kill``) raises ``SystemExit(143)`` in
    this process, so the pool's workers are stopped as after Ctrl-C; by default SIGTERM ends this process
    at once and its workers wait on their pipes for ever. Only in the main thread (where signals are
    delivered) and only if SIGTERM has its default action (a caller's own handler, or an ignored SIGTERM,
    is left alone); the previous handler comes back afterwards."""
    handler = _SigTerm()
    main = threading.current_thread() is threading.main_thread()
    if not main or signal.getsignal(signal.SIGTERM) is not signal.SIG_DFL:
        handler.starting = False
        yield handler
        return
    signal.signal(signal.SIGTERM, handler)
    try:
        yield handler
    finally:
        signal.signal(signal.SIGTERM, signal.SIG_DFL)


def _stop_workers(pool: ProcessPoolExecutor) -> None:
    """Cancel the pool's queued jobs and end its worker processes now (``shutdown`` alone would wait for
    the running jobs): terminate, then kill what is left after 5 s (a job may handle SIGTERM itself), then
    join the pool's manager thread (left running, it can print an error at interpreter exit). Uses the
    pool's private ``_processes`` and ``_executor_manager_thread``, as Python 3.14's ``terminate_workers``
    does."""
    processes = list((getattr(pool, "_processes", None) or {}).values())
    manager = getattr(pool, "_executor_manager_thread", None)
    pool.shutdown(wait=False, cancel_futures=True)
    for p in processes:
        if p.is_alive():
            p.terminate()
    for p in processes:
        p.join(timeout=5)
        if p.is_alive():
            p.kill()
            p.join(timeout=5)
    if manager is not None:
        manager.join(timeout=5)


def _set_environ(environ: dict[str, str]) -> None:
    """A worker's environment variables := the caller's when it started the pool (a ``forkserver`` worker
    otherwise has those of the server, started once per process: a ``SEMRELOC_CACHE_DIR`` or
    ``SEMRELOC_LAYOUT_PATH`` set later would not reach it)."""
    for key in set(os.environ) - set(environ):
        del os.environ[key]
    os.environ.update(environ)


def _worker_context():
    """Workers start from a clean process (``forkserver``, else ``spawn``), not forked from this one: a
    fork copies the state of thread pools the caller started (torch's OpenMP pool, once a policy's
    constructor or a model load has run a tensor operation), and forked workers then wait forever on
    their first matrix product."""
    import multiprocessing

    methods = multiprocessing.get_all_start_methods()
    return multiprocessing.get_context("forkserver" if "forkserver" in methods else "spawn")


def _run_ray(fn: Callable, jobs: list, config: RunnerConfig, tick: Callable[[], None]) -> list:
    try:
        import ray
    except ImportError as e:  # pragma: no cover - depends on the installation
        raise ImportError(
            'the ray executor needs Ray: python -m pip install -e ".[ray]" (or pip install "ray>=2.9")'
        ) from e
    started = not ray.is_initialized()
    if started:
        if config.address:
            try:
                ray.init(address=config.address)
            except (ConnectionError, ValueError, RuntimeError) as e:
                raise RuntimeError(
                    f"could not reach a Ray cluster at --address {config.address!r} ({type(e).__name__}: {e}). "
                    "Start one (`ray start --head` on the head node), give its address (`auto` on a node of it, "
                    "`ray://<head>:10001` from elsewhere), or drop --address to run on this machine"
                ) from e
        else:
            # "local": a private instance even when `ray start` left a cluster running here (ray.init would
            # connect to that one and refuse num_cpus)
            ray.init(address="local", num_cpus=config.workers, include_dashboard=False, log_to_driver=False)
    try:
        remote = ray.remote(num_cpus=1)(_apply)
        fn_ref = ray.put(fn)  # pickled once; any callable (a builtin too), resolved on the worker
        refs = [remote.remote(fn_ref, job) for job in jobs]
        pending = list(refs)
        while pending:
            ready, pending = ray.wait(pending, num_returns=1)
            ray.get(ready)  # raise a failed job's exception now
            tick()
        return ray.get(refs)
    finally:
        if started:
            ray.shutdown()


def _apply(fn: Callable, job: Any) -> Any:
    """``fn(job)``: the Ray task (a plain function, so that ``fn`` may be any picklable callable)."""
    return fn(job)
