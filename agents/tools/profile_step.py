"""Where the time of a default ``SemReloc-v20`` step goes: CPU time per stage (cProfile).

Usage::

    python scripts/profile_step.py                 # 1000 steps, lab, defaults
    python scripts/profile_step.py --steps 300 --top 30
    python scripts/profile_step.py --policy random --particles 2000
    python scripts/profile_step.py --reference     # the NumPy reference path

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
    """relocalizer particles (0 = SemReloc-v20's default: sized by the map, KLD)"""
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

    def __post_init__(self) -> None:
        if self.steps < 1 or self.beams < 1 or self.particles < 0 or self.top < 0:
            raise ValueError(
                f"steps and beams must be >= 1, particles and top >= 0; got steps={self.steps}, "
                f"beams={self.beams}, particles={self.particles}, top={self.top}"
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


def run(args: Args) -> dict[str, float]:
    """Profile as ``args`` says and print the stages; returns ``{stage: CPU s per step}``."""
    import gymnasium as gym
    import numpy as np

    from agents.baselines import WallFollowExplorer

    reloc: dict = {"fast_path": not args.reference}
    if args.particles:
        reloc["n_particles"] = args.particles
    env = gym.make("SemReloc-v20", layout=args.layout, lidar={"n_beams": args.beams}, relocalizer=reloc).unwrapped
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
