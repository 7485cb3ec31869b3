"""Where the time of a default ``SemReloc-v22`` step goes: CPU time per stage (cProfile).

Usage::

    python scripts/profile_step.py                 # 1000 steps, lab, defaults
    python scripts/profile_step.py --steps 300 --top 30
    python scripts/profile_step.py --policy random --particles 2000
    python scripts/profile_step.py --reference     # the NumPy reference path
    python scripts/profile_step.py --robots 64 --steps 40   # a batched env's robot-steps, split (batched_split)

(``semreloc-profile-step`` is the same command; ``--help`` lists every option.)

The stages are the cumulative CPU times of the functions a step calls (cProfile with a
process-time clock, so other processes on a shared machine do not count); ``rest`` is the
step's total minus the stages. cProfile's own overhead inflates short Python calls, so the
shares matter more than the absolute figures (the total without the profiler is printed too).
"""

from __future__ import annotations

import cProfile
import pstats
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import semreloc_env  # noqa: F401  (registers the envs)
from filters.experiments.cli import command, parse

STAGES: dict[str, tuple[str, str]] = {
    "physics (World.drive)": ("world.py", "drive"),
    "odometry (Odometry.read)": ("sensors.py", "read@Odometry"),
    "lidar (Lidar.read)": ("sensors.py", "read@Lidar"),
    "camera (SemanticCamera.read)": ("sensors.py", "read@SemanticCamera"),
    "  of which ray casts (both sensors)": ("raycast.py", "cast"),
    "motion predict (mcl.predict)": ("mcl.py", "predict"),
    "measurement update (mcl.update)": ("mcl.py", "update"),
    "  of which likelihood kernel": ("likelihood_field.py", "log_likelihood_kernel"),
    "belief summary (mcl.belief alone)": ("mcl.py", "belief"),
    "info dict (_info)": ("semreloc.py", "_info"),
}
"""Stage name -> (file name, function name[@class]) whose cumulative time it is ("mcl.belief alone": the
summaries the update computes for its own tests count under the update)."""


@dataclass(frozen=True)
class Args:
    steps: int = 1000
    """profiled env steps"""
    particles: int = 0
    """relocalizer particles (0 = SemReloc-v22's default: sized by the map, KLD)"""
    policy: Literal["explorer", "random"] = "explorer"
    """explorer (wall following) or random (seeded uniform actions, a spread belief)"""
    reference: bool = False
    """profile the NumPy reference path (relocalizer fast_path=False) instead of the fast path"""
    beams: int = 60
    """lidar beams"""
    layout: str = "lab"
    """layout name"""
    seed: int = 0
    """episode seed"""
    top: int = 0
    """also print the top functions by cumulative time (0 = none)"""
    robots: int = 0
    """R > 0: split a batched env of R robots' CPU time instead (batched_split: random actions; no policy, top)"""

    def __post_init__(self) -> None:
        if self.steps < 1 or self.beams < 1 or self.particles < 0 or self.top < 0 or self.robots < 0:
            raise ValueError(
                f"steps and beams must be >= 1, particles, top and robots >= 0; got steps={self.steps}, "
                f"beams={self.beams}, particles={self.particles}, top={self.top}, robots={self.robots}"
            )
        from semreloc_env.layouts import check_layout_option

        check_layout_option(self.layout)


def step_cpu_time(env, policy, steps: int, seed: int = 0) -> float:
    """Mean CPU seconds of one ``env.step`` (resets after an episode end are not counted)."""
    obs, _ = env.reset(seed=seed)
    for _ in range(20):
        obs = env.step(policy(obs))[0]
    total, s = 0.0, seed
    for _ in range(steps):
        action = policy(obs)
        t0 = time.process_time()
        obs, _, term, trunc, _ = env.step(action)
        total += time.process_time() - t0
        if term or trunc:
            s += 1
            obs, _ = env.reset(seed=s)
    return total / steps


def stage_breakdown(env, policy, steps: int, seed: int = 0) -> tuple[dict[str, float], float, pstats.Stats]:
    """Run ``steps`` env steps under cProfile (CPU clock).

    Returns ``({stage: CPU s per step}, total CPU s per step, stats)``.

    The env is reset with ``seed`` first (not profiled); an episode that ends is reset with the next seed.
    """
    import inspect

    from semreloc_env import sensors

    obs, _ = env.reset(seed=seed)
    for _ in range(20):  # warm-up: numba, caches
        obs = env.step(policy(obs))[0]
    classes = ("Lidar", "SemanticCamera", "Odometry")
    line_of = {name: inspect.getsourcelines(getattr(sensors, name).read)[1] for name in classes}
    prof = cProfile.Profile(time.process_time)
    total = 0.0
    s = seed
    for _ in range(steps):
        action = policy(obs)
        t0 = time.process_time()
        prof.enable()
        obs, _, term, trunc, _ = env.step(action)
        prof.disable()
        total += time.process_time() - t0
        if term or trunc:  # resets are not part of a step's time
            s += 1
            obs, _ = env.reset(seed=s)
    total /= steps
    stats = pstats.Stats(prof)
    out = {}
    for stage, (fname, func) in STAGES.items():
        func, _, cls = func.partition("@")
        cum = 0.0
        for (path, line, name), (_, _, _, ct, _) in stats.stats.items():
            if name == func and path.endswith(fname) and (not cls or line == line_of[cls]):
                cum += ct
        out[stage] = cum / steps
    top_level = [k for k in out if not k.startswith(" ")]
    out["rest (env glue, reward, obs)"] = max(0.0, total - sum(out[k] for k in top_level))
    return out, total, stats


def compiled_functions() -> set[tuple[str, int, str]]:
    """cProfile keys ``(file, first line, name)`` of every numba-compiled function of this package's modules
    (``filters``, ``semreloc_env``, ``agents``) loaded so far: what cProfile records a call of one under (numba's
    dispatcher reports the Python function's code)."""
    import sys

    from numba.core.dispatcher import Dispatcher

    keys = set()
    for name, module in list(sys.modules.items()):
        if module is None or name.partition(".")[0] not in ("filters", "semreloc_env", "agents"):
            continue
        for value in list(vars(module).values()):
            if isinstance(value, Dispatcher):
                code = value.py_func.__code__
                keys.add((code.co_filename, code.co_firstlineno, code.co_name))
    return keys


def compiled_time(stats: pstats.Stats) -> tuple[float, int]:
    """``(seconds, calls)`` inside this package's numba-compiled functions (`compiled_functions`) in ``stats``
    (numba's call dispatch included; seconds of the profiler's clock: CPU seconds under ``time.process_time``)."""
    by_kernel = compiled_by_function(stats)
    return sum(s for s, _ in by_kernel.values()), sum(n for _, n in by_kernel.values())


def compiled_by_function(stats: pstats.Stats) -> dict[str, tuple[float, int]]:
    """``{name: (seconds, calls)}`` of each of this package's numba-compiled functions (`compiled_functions`) called in
    ``stats``, heaviest first (``name``: the function's, with its module's file where two share a name)."""
    compiled = compiled_functions()
    names = [key[2] for key in compiled]
    out: dict[str, tuple[float, int]] = {}
    for key, (_, n, tt, _, _) in stats.stats.items():
        if key in compiled:
            name = key[2] if names.count(key[2]) == 1 else f"{Path(key[0]).stem}.{key[2]}"
            seconds, calls = out.get(name, (0.0, 0))
            out[name] = (seconds + tt, calls + n)
    return dict(sorted(out.items(), key=lambda kv: -kv[1][0]))


def empty_kernel_args() -> tuple:
    """Arguments of `filters.localization.likelihood_field.log_likelihood_kernel` with no particle and no beam: a call
    with them does no work, so it costs numba's dispatch and the unboxing of its 17 arguments only."""
    import numpy as np

    f, i = np.zeros(0), np.zeros(0, dtype=np.int64)
    return (f, f, f, f, f, f, i, i, 0, np.zeros(1), 0.0, 0.0, 1.0, 1, 1, np.zeros(0), np.zeros(0))


def dispatch_seconds(calls: int = 20_000) -> float:
    """CPU seconds of one compiled call that does no work: the median over five rounds of ``calls`` calls of
    `filters.localization.likelihood_field.log_likelihood_kernel` with `empty_kernel_args` (numba's dispatch and the
    unboxing of its 17 arguments, as the filter's heaviest calls pay it)."""
    import statistics

    from filters.localization.likelihood_field import log_likelihood_kernel

    args = empty_kernel_args()
    log_likelihood_kernel(*args)  # compiled or loaded outside the clock
    rounds = []
    for _ in range(5):
        t0 = time.process_time()
        for _ in range(calls):
            log_likelihood_kernel(*args)
        rounds.append((time.process_time() - t0) / calls)
    return statistics.median(rounds)


@dataclass(frozen=True)
class BatchedSplit:
    """Where the CPU time of a batched env's robot-steps goes (`batched_split`). Times are CPU seconds of this
    process, summed over the robot-steps.

    Attributes:
        robot_steps: robot-steps run (``steps * num_envs``); ``update_steps + plain_steps + resets`` of them.
        total_s: the vector env's ``step`` calls, all of it.
        update_steps, update_s: robot-steps whose measurement update ran, and their time (the robot's ``step``).
        audits, audit_s: convergence audits that searched for another place (calls of
            `filters.localization.audit.best_alternative`), and the time of every update's audit step
            (`MonteCarloLocalizer._audit`, mostly those searches), part of ``update_s`` and ``reset_s``.
        plain_steps, plain_s: robot-steps the motion gate let pass without an update.
        resets, reset_s: robot-steps that were autoresets (an episode had ended) and their time.
        loop_s: the rest: the vector env's own work (checking the actions, batching observations and infos).
        kernel_s: time inside numba-compiled functions (`compiled_functions`) in a second run of the same
            robot-steps under cProfile (the same seeds and actions, so the same episodes), numba's call dispatch
            included; NumPy's own compiled code (random draws, array operations) is not counted.
        kernel_calls: the calls of those functions in that run.
        weighed: particles the robots' measurement updates weighed first, summed over the update steps (a robot's
            particle count before its step: its held set; the scan-proposal candidates and audit poses an update also
            weighs, and the resets' first updates, are not counted).
        weighed_stacked: what the same updates would weigh with the filters' arrays stacked ``(R, N, 3)``: at each
            step, the robots that update times the largest count among them (every robot padded to it).
        kernels: ``(name, seconds)`` of each compiled function in ``kernel_s``, heaviest first
            (`compiled_by_function`).
    """

    robot_steps: int
    total_s: float
    update_steps: int
    update_s: float
    audits: int
    audit_s: float
    plain_steps: int
    plain_s: float
    resets: int
    reset_s: float
    loop_s: float
    kernel_s: float
    kernel_calls: int
    weighed: int
    weighed_stacked: int
    kernels: tuple[tuple[str, float], ...] = ()


class _TimedRobot:
    """One robot's env in a `SemRelocLoopVectorEnv` with its ``step`` and ``reset`` timed into ``tally``; any other
    attribute is the env's."""

    def __init__(self, env, tally: dict[str, float]) -> None:
        self._env = env
        self._tally = tally

    def __getattr__(self, name: str):
        return getattr(self._env, name)

    def step(self, action):
        mcl = self._env.unwrapped.mcl
        n = mcl.n_particles
        t0 = time.process_time()
        out = self._env.step(action)
        dt = time.process_time() - t0
        kind = "update" if mcl.last_diagnostics.updated else "plain"
        self._tally[f"{kind}_s"] += dt
        self._tally[f"{kind}_steps"] += 1
        if kind == "update":
            self._tally.setdefault("weighing", []).append(n)
        return out

    def reset(self, **kwargs):
        t0 = time.process_time()
        out = self._env.reset(**kwargs)
        self._tally["reset_s"] += time.process_time() - t0
        self._tally["resets"] += 1
        return out


def stacked_counts(counts: list[int]) -> tuple[int, int]:
    """``(held, stacked)`` for the particle counts of the robots that update in one step: the particles their sets
    hold, and what one ``(R, N_max, 3)`` array of them would hold (each set padded to the largest)."""
    return sum(counts), len(counts) * max(counts, default=0)


def _run_batched(num_envs: int, steps: int, seed: int, env_id: str, kwargs: dict, tally, prof) -> float:
    """Reset a fresh batched env with ``seed``, step it 5 times (not counted) and then ``steps`` times with seeded
    random actions, its robots timed into ``tally`` (None: not) and the counted steps under ``prof`` (None: none);
    returns the counted steps' CPU seconds."""
    import numpy as np

    from filters.localization import audit as audit_module
    from filters.localization.mcl import MonteCarloLocalizer
    from semreloc_env.envs.batched import SemRelocLoopVectorEnv

    venv = SemRelocLoopVectorEnv(num_envs=num_envs, env_id=env_id, **kwargs)
    rng = np.random.default_rng(seed)
    audit, search = MonteCarloLocalizer._audit, audit_module.best_alternative
    try:
        venv.reset(seed=seed)
        for _ in range(5):  # warm-up: numba, caches
            venv.step(rng.integers(0, 4, num_envs))
        if tally is not None:
            venv.envs = [_TimedRobot(env, tally) for env in venv.envs]

            def timed_audit(mcl, *a):
                t0 = time.process_time()
                try:
                    return audit(mcl, *a)
                finally:
                    tally["audit_s"] += time.process_time() - t0

            def counted_search(*a, **k):
                tally["audits"] += 1
                return search(*a, **k)

            MonteCarloLocalizer._audit = timed_audit
            audit_module.best_alternative = counted_search
        t0 = time.process_time()
        if prof is not None:
            prof.enable()
        try:
            for _ in range(steps):
                venv.step(rng.integers(0, 4, num_envs))
                if tally is not None:  # this step's updates, weighed as held and as one padded array
                    held, stacked = stacked_counts(tally.pop("weighing", []))
                    tally["weighed"] += held
                    tally["weighed_stacked"] += stacked
        finally:
            if prof is not None:
                prof.disable()
        return time.process_time() - t0
    finally:
        MonteCarloLocalizer._audit, audit_module.best_alternative = audit, search
        venv.close()


def batched_split(
    num_envs: int = 64, steps: int = 40, seed: int = 0, env_id: str = "SemReloc-v22", **kwargs
) -> BatchedSplit:
    """Run ``steps`` steps of a `semreloc_env.envs.batched.SemRelocLoopVectorEnv` of ``num_envs`` robots
    (``env_id``, ``gym.make`` keyword arguments ``kwargs``) with seeded random actions, after 5 not counted, and
    split their CPU time (`BatchedSplit`); then run the same steps again under cProfile for the time in compiled
    kernels."""
    keys = ("update_s", "update_steps", "plain_s", "plain_steps", "reset_s", "resets", "audit_s", "audits")
    tally = dict.fromkeys(keys + ("weighed", "weighed_stacked"), 0.0)
    total = _run_batched(num_envs, steps, seed, env_id, kwargs, tally, None)
    prof = cProfile.Profile(time.process_time)
    _run_batched(num_envs, steps, seed, env_id, kwargs, None, prof)
    stats = pstats.Stats(prof)
    kernel, calls = compiled_time(stats)
    robots = tally["update_s"] + tally["plain_s"] + tally["reset_s"]
    return BatchedSplit(
        robot_steps=steps * num_envs,
        total_s=total,
        update_steps=int(tally["update_steps"]),
        update_s=tally["update_s"],
        audits=int(tally["audits"]),
        audit_s=tally["audit_s"],
        plain_steps=int(tally["plain_steps"]),
        plain_s=tally["plain_s"],
        resets=int(tally["resets"]),
        reset_s=tally["reset_s"],
        loop_s=max(0.0, total - robots),
        kernel_s=kernel,
        kernel_calls=calls,
        weighed=int(tally["weighed"]),
        weighed_stacked=int(tally["weighed_stacked"]),
        kernels=tuple((name, seconds) for name, (seconds, _) in compiled_by_function(stats).items()),
    )


def print_batched_split(s: BatchedSplit) -> dict[str, float]:
    """Print `batched_split`'s figures per robot-step; returns ``{part: CPU s per robot-step}``."""
    n = s.robot_steps
    parts = {
        "steps with a measurement update": (s.update_s, f"{s.update_steps} robot-steps"),
        "  of which convergence audits": (s.audit_s, f"{s.audits} searches for another place"),
        "steps without an update": (s.plain_s, f"{s.plain_steps} robot-steps"),
        "autoresets": (s.reset_s, f"{s.resets} robot-steps"),
        "the vector env's own": (s.loop_s, ""),
        "compiled kernels (cProfile, same steps)": (s.kernel_s, f"alone: {n / s.kernel_s:.0f} robot-steps per CPU-s"),
    }
    print(
        f"robot-step: {1e6 * s.total_s / n:.0f} us CPU ({n / s.total_s:.0f} robot-steps per CPU-second, {n} run, "
        "random actions)"
    )
    for k, (v, note) in parts.items():
        print(f"{k:<40} {1e6 * v / n:8.0f} us  {100 * v / s.total_s:5.1f} %  {note}")
    print(f"heaviest compiled kernels: {heaviest_text(s)}")
    print(robots_fused_text(s, dispatch_seconds()))
    return {k: v / n for k, (v, _) in parts.items()}


def heaviest_text(s: BatchedSplit, k: int = 3) -> str:
    """The ``k`` heaviest compiled kernels of ``s`` (`batched_split`) with their shares of its compiled time, such as
    ``"log_likelihood_kernel 19 %, summary_rasters 19 %, summary_clusters 16 %"``."""
    return ", ".join(f"{name} {100 * t / s.kernel_s:.0f} %" for name, t in s.kernels[:k])


def robots_fused_text(s: BatchedSplit, dispatch_s: float) -> str:
    """What fusing the compiled calls over robots would save in dispatch, and what stacking the filters' arrays would
    weigh, in words (`batched_split`'s ``s``; ``dispatch_s``: `dispatch_seconds`)."""
    n = s.robot_steps
    saved = s.kernel_calls / n * dispatch_s
    share = 100 * saved * n / s.total_s
    stacked = (
        f"the filters' arrays stacked (R, N_max, 3) would weigh {s.weighed_stacked / s.weighed:.2f}x the particles "
        "the updates weighed"
        if s.weighed
        else "no measurement update ran, so nothing tells what stacking the filters' arrays would weigh"
    )
    return (
        f"compiled calls per robot-step: {s.kernel_calls / n:.1f}, {1e6 * dispatch_s:.2f} us of dispatch each: "
        f"one call for all robots would save about {1e6 * saved:.0f} us ({share:.1f} %) of a robot-step in dispatch; "
        + stacked
    )


def run(args: Args) -> dict[str, float]:
    """Profile as ``args`` says and print the stages; returns ``{stage: CPU s per step}``."""
    import gymnasium as gym
    import numpy as np

    from agents.baselines import WallFollowExplorer

    reloc: dict = {"fast_path": not args.reference}
    if args.particles:
        reloc["n_particles"] = args.particles
    if args.robots:
        return print_batched_split(
            batched_split(
                args.robots, args.steps, args.seed, layout=args.layout, lidar={"n_beams": args.beams}, relocalizer=reloc
            )
        )
    env = gym.make("SemReloc-v22", layout=args.layout, lidar={"n_beams": args.beams}, relocalizer=reloc).unwrapped
    if args.policy == "random":
        rng = np.random.default_rng(args.seed)

        def policy(obs) -> int:
            return int(rng.integers(0, 4))
    else:
        policy = WallFollowExplorer()
    # unprofiled CPU time per step, for scale
    plain = step_cpu_time(env, policy, args.steps, args.seed)
    stages, total, stats = stage_breakdown(env, policy, args.steps, args.seed)
    print(f"# {args}")
    print(f"step without profiler: {plain * 1e3:.3f} ms CPU ({1 / plain:.0f} steps per CPU-second)")
    print(f"step under cProfile:   {total * 1e3:.3f} ms CPU")
    for k, v in stages.items():
        print(f"{k:<36} {v * 1e3:8.3f} ms  {100 * v / total:5.1f} %")
    if args.top:
        stats.sort_stats("cumulative").print_stats(args.top)
    return stages


@command
def main(argv: list[str] | None = None) -> int:
    """The command: parse ``argv`` (default ``sys.argv[1:]``), profile, print the stages."""
    run(parse(Args, argv, __doc__))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
