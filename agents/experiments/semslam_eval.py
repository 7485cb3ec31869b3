"""Measure SemSlam: SLAM pose and landmark error over seeds with the wall-following explorer.

For every seed one episode is driven by `agents.baselines.WallFollowExplorer` (deterministic
given the observations); every filter variant runs on its own env with the same seed. Because the
filter draws from its own generator, the drive (world, sensors, odometry) is identical across
variants as long as the policy only reads the observations -- so differences are paired.

Variants: WOCPF (FastSLAM 2.0 + WOC, K = ``--woc-k``, ML association), plain FastSLAM 2.0 (K = inf),
WOCPF with known association, and dead reckoning (the odometry increments composed, no SLAM).

Prints a markdown table: mean over seeds +- half-width of a 95 % normal interval. Run
``python scripts/semslam_eval.py --help`` (or ``semreloc-semslam-eval --help``) for options.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import gymnasium as gym
import numpy as np

import semreloc_env  # noqa: F401  (registers the envs)
from agents.baselines import FORWARD, TURN_LEFT, TURN_RIGHT, WallFollowExplorer
from filters.experiments.cli import Runner, command, parse
from filters.experiments.report import fmt_ci, markdown_table
from filters.experiments.runner import RunnerConfig, run_jobs
from filters.experiments.stats import normal_mean_interval
from filters.pose import compose, wrap_angle
from semreloc_env.layouts import check_layout_option


@dataclass(frozen=True)
class Args:
    layout: str = "lab"
    """layout name or file"""
    env_id: Literal["SemSlam-v2", "SemSlam-v1", "SemSlam-v0"] = "SemSlam-v2"
    """env id: SemSlam-v2 (the newest), or v1 and v0 to repeat the tables made with them (v1 and v0 differ only in
    their observation's layout and info's missing landmark error, so they give the same table; v2 differs from v1
    in its odometry, which reads no slide along a wall and moves a step under 1 cm in its own direction, and in its
    association, which chooses among the landmarks inside the gate)"""
    seeds: int = 10
    """episodes (seeds 0..seeds-1)"""
    steps: int = 300
    """control steps per episode (10 Hz)"""
    particles: int = 100
    """SLAM particles"""
    woc_k: float = 2.0
    """WOC scaling factor K of the WOCPF rows"""
    policy: Literal["wallfollow", "look_around"] = "wallfollow"
    """"wallfollow" (WallFollowExplorer) or "look_around" (60 steps turning left, then repeatedly 10 forward
    and 50 turning right / left: keeps re-observing the same objects)"""
    odometry_alpha: float = -1.0
    """if >= 0: the simulator's odometry noise alpha1 = alpha2 = alpha3 = this, alpha4 = half (default: env's)"""
    figure: str = ""
    """if set, save the last frame of seed 0 (default variant) to this PNG path"""
    runner: Runner = RunnerConfig()

    def __post_init__(self) -> None:
        if self.seeds < 1 or self.steps < 1 or self.particles < 1:
            raise ValueError("seeds, steps and particles must be >= 1")
        if not self.woc_k >= 1:  # NaN fails too; WOC needs K >= 1 (paper 000), inf is plain FastSLAM
            raise ValueError(f"woc_k must be >= 1 (inf: plain FastSLAM), got {self.woc_k}")
        if math.isnan(self.odometry_alpha) or math.isinf(self.odometry_alpha):
            raise ValueError(
                f"odometry_alpha must be a finite number (< 0: the env's default), got {self.odometry_alpha}"
            )
        check_layout_option(self.layout)  # a usage error before any episode, not a traceback
        if self.figure and Path(self.figure).suffix.lower() != ".png":  # else Pillow fails after seed 0's episode
            raise ValueError(f"figure must be a .png path, got {self.figure!r}")


class LookAround:
    """Turn left for 60 steps, then alternate 10 steps forward with 50 steps turning right / left."""

    def __init__(self) -> None:
        self.t = 0

    def __call__(self, obs: dict) -> int:
        t, self.t = self.t, self.t + 1
        if t < 60:
            return TURN_LEFT
        phase = (t - 60) % 120
        return FORWARD if phase % 60 < 10 else (TURN_RIGHT if phase < 60 else TURN_LEFT)


def run(args: Args, seed: int, slam: dict, figure: str = "") -> dict[str, float]:
    """One episode; returns the metrics of the SLAM estimate and of dead reckoning (metres, degrees)."""
    kw = {}
    if args.odometry_alpha >= 0:
        a = args.odometry_alpha
        kw["odometry"] = {"alpha1": a, "alpha2": a, "alpha3": a, "alpha4": a / 2}
    env = gym.make(args.env_id, layout=args.layout, slam=slam, render_mode="rgb_array" if figure else None, **kw)
    obs, info = env.reset(seed=seed)
    policy = {"wallfollow": WallFollowExplorer, "look_around": LookAround}[args.policy]()
    dr = np.asarray(info["pose"], dtype=np.float64)  # dead reckoning from the true start pose
    pos, dr_pos = [], []
    for _ in range(args.steps):
        obs, _, _, trunc, info = env.step(policy(obs))
        dr = compose(dr, obs["odometry"].astype(np.float64))
        pos.append(info["slam_error"]["position"])
        dr_pos.append(float(np.hypot(*(dr[:2] - info["pose"][:2]))))
        if trunc:
            break
    if figure:
        from PIL import Image

        Path(figure).parent.mkdir(parents=True, exist_ok=True)
        Image.fromarray(env.render()).save(figure)
    e = info["slam_error"]
    out = {
        "mean position error (m)": float(np.mean(pos)),
        "final position error (m)": e["position"],
        "final heading error (deg)": math.degrees(e["heading"]),
        "landmark error (m)": math.nan if e.get("landmark") is None else e["landmark"],  # v1: absent, v0: None
        "objects seen": e["n_seen"],
        "landmarks": info["slam"]["n_landmarks"],
        "dr mean": float(np.mean(dr_pos)),
        "dr final": dr_pos[-1],
        "dr heading": math.degrees(abs(float(wrap_angle(dr[2] - info["pose"][2])))),
    }
    env.close()
    return out


def episode_job(job: tuple[Args, int, dict, str]) -> dict[str, float]:
    """`run` for the job ``(args, seed, slam overrides, figure path)``."""
    return run(*job)


def _fmt(values) -> str:
    v = np.asarray(values, dtype=np.float64)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return "-"
    mean, half = normal_mean_interval(v)
    return fmt_ci(mean, 0.0 if v.size < 2 else half)


COLUMNS = (
    "mean position error (m)",
    "final position error (m)",
    "final heading error (deg)",
    "landmark error (m)",
    "objects seen",
    "landmarks",
)


@command
def main(argv: list[str] | None = None) -> int:
    """The command: parse ``argv`` (default ``sys.argv[1:]``), run every variant on every seed, print the table."""
    args = parse(Args, argv, __doc__)
    variants = {
        f"WOCPF (K={args.woc_k:g}), ML association": {"n_particles": args.particles, "woc_k": args.woc_k},
        "FastSLAM 2.0 (K=inf), ML association": {"n_particles": args.particles, "woc_k": math.inf},
        f"WOCPF (K={args.woc_k:g}), known association": {
            "n_particles": args.particles,
            "woc_k": args.woc_k,
            "known_association": True,
        },
    }
    t0 = time.perf_counter()
    jobs = [
        (args, seed, slam, args.figure if (seed == 0 and i == 0) else "")
        for seed in range(args.seeds)
        for i, slam in enumerate(variants.values())
    ]
    out = run_jobs(episode_job, jobs, args.runner, desc="episodes")
    results = {name: out[i :: len(variants)] for i, name in enumerate(variants)}
    print(
        f"\n{args.layout}, {args.policy}, odometry alpha {args.odometry_alpha:g} (<0: default), {args.seeds} seeds "
        f"x {args.steps} steps, {args.particles} particles, {time.perf_counter() - t0:.0f} s\n"
    )
    rows = [[name, *(_fmt([r[c] for r in rs]) for c in COLUMNS)] for name, rs in results.items()]
    first = next(iter(results.values()))
    dr = [_fmt([r[k] for r in first]) for k in ("dr mean", "dr final", "dr heading")]
    rows.append(["dead reckoning (odometry only)", *dr, "-", "-", "-"])
    print(markdown_table(["variant", *COLUMNS], rows))
    n_undef = sum(math.isnan(r["landmark error (m)"]) for r in first)
    if n_undef:
        print(f"\n(landmark error undefined in {n_undef} episode(s) of the first row: no object observed)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
