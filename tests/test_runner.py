"""filters.experiments.runner: the same results in job order sequentially, in a process pool and on a
local Ray, on real seeded jobs (paper 001's Table 1 and reference runs); options checked."""

import contextlib
import os
import signal
import subprocess
import sys
import time

import pytest

from filters.experiments import paper001
from filters.experiments.cli import parse
from filters.experiments.runner import RunnerConfig, run_jobs


def _table1_jobs():
    args = parse(paper001.Args, ["--runs", "3", "--steps", "15", "--particles", "20", "30", "--no-ablations"])
    return [(args, n, r) for n in args.particles for r in range(args.runs)]


def _rmse(results):
    return [res["rmse"] for res in results]


def test_process_pool_gives_the_sequential_results_in_job_order():
    jobs = _table1_jobs()
    seq = run_jobs(paper001.table1_job, jobs, RunnerConfig(executor="sequential", progress=False))
    pool = run_jobs(paper001.table1_job, jobs, RunnerConfig(executor="process", workers=2, progress=False))
    assert _rmse(pool) == _rmse(seq)
    # the jobs differ from each other (the comparison is not between constants)
    assert len({tuple(r.values()) for r in _rmse(seq)}) == len(jobs)
    # job order, not completion order: run r of the first N is the job (args, 20, r)
    one = paper001.table1_job(jobs[1])
    assert seq[1]["rmse"] == one["rmse"]


def test_ray_gives_the_sequential_results():
    ray = pytest.importorskip("ray")
    jobs = _table1_jobs()
    ref_jobs = [(paper001.Args(runs=3, steps=15, reference_particles=200), r) for r in range(3)]
    seq = run_jobs(paper001.table1_job, jobs, RunnerConfig(executor="sequential", progress=False))
    seq_ref = run_jobs(paper001.reference_job, ref_jobs, RunnerConfig(progress=False))
    # "local": a private instance, also when `ray start` left a cluster running on this machine
    ray.init(address="local", num_cpus=1, include_dashboard=False, log_to_driver=False)
    try:
        cfg = RunnerConfig(executor="ray", progress=False)
        assert _rmse(run_jobs(paper001.table1_job, jobs, cfg)) == _rmse(seq)
        assert run_jobs(paper001.reference_job, ref_jobs, cfg) == seq_ref
        assert run_jobs(abs, [-1, 2], cfg) == [1, 2]  # any picklable callable, a builtin too
        assert ray.is_initialized()  # a Ray started by the caller is left running
    finally:
        ray.shutdown()
    # a Ray the runner starts itself (a private local one, as above) is shut down after the jobs
    assert run_jobs(abs, [-1, 2], RunnerConfig(executor="ray", workers=1, progress=False)) == [1, 2]
    assert not ray.is_initialized()


def test_progress_callback_and_auto_executor():
    calls = []
    out = run_jobs(abs, [-3, 2, -1], RunnerConfig(progress=False), on_result=lambda k, n: calls.append((k, n)))
    assert out == [3, 2, 1] and calls == [(1, 3), (2, 3), (3, 3)]
    assert run_jobs(abs, [], RunnerConfig(progress=False)) == []
    assert RunnerConfig().resolved_executor == "sequential"
    assert RunnerConfig(workers=2).resolved_executor == "process"
    assert RunnerConfig(address="auto").resolved_executor == "ray"


@pytest.mark.parametrize(
    "kw, msg",
    [
        ({"executor": "threads"}, "executor"),
        ({"workers": 0}, "workers"),
        ({"workers": True}, "workers"),
        ({"executor": "process", "address": "auto"}, "address"),
    ],
)
def test_bad_runner_options_are_rejected(kw, msg):
    with pytest.raises(ValueError, match=msg):
        RunnerConfig(**kw)


def test_runner_options_on_the_command_line():
    args = parse(paper001.Args, ["--workers", "2", "--executor", "process", "--no-progress"])
    assert args.runner == RunnerConfig(executor="process", workers=2, progress=False)
    with pytest.raises(SystemExit):
        parse(paper001.Args, ["--workers", "0"])


def _environ_of_worker(key):
    import os

    return os.environ.get(key)


def test_process_workers_see_the_callers_environment_when_the_pool_starts(monkeypatch):
    """Workers start from a clean process (forkserver), which would otherwise keep the environment of
    the first pool's time: a cache folder or layout path set later must reach them (a review)."""
    config = RunnerConfig(executor="process", workers=2, progress=False)
    monkeypatch.setenv("SEMRELOC_LAYOUT_PATH", "/first")
    assert run_jobs(_environ_of_worker, ["SEMRELOC_LAYOUT_PATH"] * 2, config) == ["/first"] * 2
    monkeypatch.setenv("SEMRELOC_LAYOUT_PATH", "/second")
    assert run_jobs(_environ_of_worker, ["SEMRELOC_LAYOUT_PATH"] * 2, config) == ["/second"] * 2
    monkeypatch.delenv("SEMRELOC_LAYOUT_PATH")
    assert run_jobs(_environ_of_worker, ["SEMRELOC_LAYOUT_PATH"], config) == [None]


def test_a_job_function_workers_cannot_import_is_named():
    config = RunnerConfig(executor="process", workers=2, progress=False)
    local = eval("lambda x: x")  # noqa: S307  (not importable by name, like a function of `python -c`)
    with pytest.raises(Exception, match="pickle|importable by name"):
        run_jobs(local, [1], config)


def test_a_failing_job_stops_the_pools_other_workers_at_once():
    # time.sleep(-1) raises at once; before, leaving the pool waited for the 60 s job beside it
    t0 = time.monotonic()
    with pytest.raises(ValueError, match="non-negative"):
        run_jobs(time.sleep, [60.0, -1.0], RunnerConfig(workers=2, progress=False))
    assert time.monotonic() - t0 < 30


def _descendants(pid: int) -> set[int]:
    parent_of = {}
    for d in os.listdir("/proc"):
        if d.isdigit():
            try:
                with open(f"/proc/{d}/stat") as f:
                    stat = f.read()
            except OSError:
                continue
            parent_of[int(d)] = int(stat[stat.rindex(")") + 2 :].split()[1])
    found, frontier = set(), {pid}
    while frontier:
        frontier = {p for p, pp in parent_of.items() if pp in frontier} - found
        found |= frontier
    return found


def _running(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


@pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="reads the process table in /proc")
def test_sigterm_to_a_pool_run_leaves_no_worker_behind(tmp_path):
    # an outside tester's: `timeout` or a scheduler sends SIGTERM, the caller died at once, and its forkserver,
    # resource tracker and workers waited on their pipes for ever
    script = tmp_path / "run.py"
    script.write_text(
        "import time\n"
        "from filters.experiments.runner import RunnerConfig, run_jobs\n"
        'if __name__ == "__main__":\n'
        '    print("start", flush=True)\n'
        "    run_jobs(time.sleep, [60.0, 60.0, 60.0], RunnerConfig(workers=2, progress=False))\n"
    )
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([root, os.environ.get("PYTHONPATH", "")])}
    proc = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE, text=True, env=env)
    helpers: set[int] = set()
    try:
        assert proc.stdout.readline().strip() == "start"
        deadline = time.monotonic() + 30
        while len(_descendants(proc.pid)) < 4 and time.monotonic() < deadline:  # forkserver, tracker, 2 workers
            time.sleep(0.2)
        helpers = _descendants(proc.pid)
        assert len(helpers) >= 4
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(timeout=30) == 128 + signal.SIGTERM  # SystemExit(143), after the workers were stopped
        deadline = time.monotonic() + 15
        while any(_running(p) for p in helpers) and time.monotonic() < deadline:
            time.sleep(0.2)
        assert not [p for p in helpers if _running(p)]
    finally:
        proc.kill()
        proc.wait()
        for p in helpers:
            with contextlib.suppress(OSError):
                os.kill(p, signal.SIGKILL)


def test_a_callers_own_sigterm_handler_is_left_alone_and_ours_removed():
    before = signal.getsignal(signal.SIGTERM)

    def mine(signum, frame):
        pass

    signal.signal(signal.SIGTERM, mine)
    try:
        assert run_jobs(abs, [-1, 2], RunnerConfig(workers=2, progress=False)) == [1, 2]
        assert signal.getsignal(signal.SIGTERM) is mine  # not replaced during the run, nor after
    finally:
        signal.signal(signal.SIGTERM, before)
    assert run_jobs(abs, [-3], RunnerConfig(workers=2, progress=False)) == [3]
    assert signal.getsignal(signal.SIGTERM) is before
    assert RunnerConfig(workers=1, executor="process").describe() == "1 worker process"
    assert RunnerConfig(workers=2).describe() == "2 worker processes"
    assert RunnerConfig(address="auto").describe() == "the Ray cluster at auto"
