"""Reproduce paper 004's relocalization experiments: lidar-only vs lidar + semantic MCL.

For each case (``twin_rooms``, ``lab``, ``lab`` with obstacles added after mapping)
and each seed, a global relocalization runs from a belief uniform over free
space while the robot follows a fixed, documented exploration motion
(`agents.baselines.WallFollowExplorer`: forward; when the +-0.5 rad front
sector is closer than 0.7 m, turn toward the side with more room until clear).
The same seed gives the same start pose, sensor noise and drive for both filter
variants up to the point where their (different) beliefs stop the episode.

Per case and variant it reports the success rate (belief converged within 0.5 m
and 15 deg of the truth before the time limit), the wrong-convergence rate
(converged elsewhere at the end), the median and 90th-percentile steps to
success, and writes into ``--out`` (default ``docs/``; ``--quick``: 5 seeds, 200 steps,
``build/paper004_quick/``): ``paper004.md`` (table + command), ``figures/paper004_mean_weight.png``
(mean per-beam lidar likelihood against iteration: paper 004 Fig. 15/21) and ``figures/paper004_particles.png``
(particle snapshots: Fig. 14).

Run from the repository root: ``python scripts/repro_paper004.py`` (or ``semreloc-repro-paper004``);
``--help`` lists every option.
"""

from __future__ import annotations

import dataclasses
import math
import sys
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np

from filters.experiments.cli import JsonDict, Runner, command, command_line, parse
from filters.experiments.report import markdown_table, pyplot, replace_block, save_figure
from filters.experiments.runner import RunnerConfig, run_jobs
from filters.experiments.stats import wilson_interval

CASES = {
    "twin_rooms": {"layout": "twin_rooms"},
    "lab": {"layout": "lab"},
    "lab_changed": {"layout": "lab", "scenario": "changed"},
}


SNAPSHOT_STEPS = (1, 10, 30, 60)
"""Steps of the particle snapshots (first seed of each case)."""


@dataclass(frozen=True)
class Args:
    seeds: int = 50
    """episodes per case and variant (seeds first_seed .. first_seed+seeds-1)"""
    first_seed: int = 1000
    """first episode seed; the default keeps seeds 0-99 (used while choosing defaults) out of the table"""
    max_steps: int = 400
    """time limit per episode, control steps at 10 Hz"""
    particles: int = 2000
    """particles of the relocalizer"""
    cases: tuple[Literal["twin_rooms", "lab", "lab_changed"], ...] = ("twin_rooms", "lab", "lab_changed")
    """cases to run (the first one's first seed gives the particle snapshots)"""
    mcl: JsonDict = field(default_factory=dict)
    """MCLConfig overrides (filters.localization.mcl) for both variants, one JSON object, e.g.
    '{"likelihood_scale": 0.05}'; checked before any episode runs"""
    env_id: str = "SemReloc-v0"
    """env id: docs/paper004.md was made with SemReloc-v0 (the first release's relocalizer)"""
    out: str = ""
    """folder for paper004.md and figures/ (default docs, with --quick build/paper004_quick)"""
    quick: bool = False
    """smoke run: at most 5 seeds per row and at most 200 steps, written into build/"""
    runner: Runner = RunnerConfig(workers=2)

    def __post_init__(self) -> None:
        if self.seeds < 1 or self.max_steps < 1 or self.particles < 1 or not self.cases:
            raise ValueError("seeds, max_steps and particles must be >= 1 and cases not empty")
        if len(set(self.cases)) < len(self.cases):  # the same seeded episodes would count twice
            raise ValueError(f"cases: a case given more than once in {list(self.cases)}")
        from filters.localization.mcl import check_overrides
        from semreloc_env import default_relocalizer

        if isinstance(self.mcl, dict) and "n_particles" in self.mcl:
            raise ValueError("mcl: set the particle count with --particles (the report states it)")
        check_overrides({"n_particles": self.particles, **self.mcl}, "mcl", default_relocalizer(self.env_id))

    def resolved(self) -> Args:
        """Apply ``--quick`` and the default output folder (relative to the working directory)."""
        a = self
        if a.quick:
            a = dataclasses.replace(a, seeds=min(a.seeds, 5), max_steps=min(a.max_steps, 200))
        return dataclasses.replace(a, out=a.out or ("build/paper004_quick" if a.quick else "docs"))


def run_episode(job: tuple) -> dict:
    """One global relocalization; returns outcome, steps and the per-step traces."""
    import gymnasium as gym

    import semreloc_env  # noqa: F401
    from agents.baselines import WallFollowExplorer

    case, semantic, seed, max_steps, particles, mcl, snapshot, env_id = job
    with warnings.catch_warnings():  # an older version is this command's documented choice (--env-id)
        warnings.filterwarnings("ignore", message=".*is out of date", category=DeprecationWarning)
        env = gym.make(
            env_id,
            **CASES[case],
            semantic=semantic,
            relocalizer={"n_particles": particles, **mcl},
            max_episode_steps=max_steps,
        )
    policy = WallFollowExplorer()
    obs, info = env.reset(seed=seed)
    weights, errors = [], []
    snapshots = {}
    success_step = None
    for step in range(1, max_steps + 1):
        obs, _, terminated, truncated, info = env.step(policy(obs))
        # not computed in this step: key left out (SemReloc-v2 and newer) or None (v1, v0)
        w = info["mcl"].get("mean_lidar_beam_likelihood") if info["mcl"]["updated"] else None
        weights.append(np.nan if w is None else w)
        errors.append(info["pose_error"]["position"])
        if snapshot and step in SNAPSHOT_STEPS:
            snapshots[step] = (env.unwrapped.mcl.poses[::4].copy(), info["pose"].copy())
        if terminated:
            success_step = step
        if terminated or truncated:
            break
    converged = info["belief"]["converged"]
    outcome = "success" if success_step else ("wrong" if converged else "not_converged")
    env.close()
    return {
        "case": case,
        "semantic": semantic,
        "seed": seed,
        "outcome": outcome,
        "steps": success_step,
        "weights": weights,
        "snapshots": snapshots,
        "final_error": errors[-1],
    }


def summarise(results: list[dict]) -> dict:
    n = len(results)
    steps = np.array([r["steps"] for r in results if r["steps"] is not None], dtype=float)
    succ = sum(r["outcome"] == "success" for r in results)
    wrong = sum(r["outcome"] == "wrong" for r in results)

    def ci(k):  # Wilson 95% interval of a rate, in percent
        return tuple(100 * v for v in wilson_interval(k, n))

    return {
        "n": n,
        "success": 100 * succ / n,
        "success_ci": ci(succ),
        "wrong": 100 * wrong / n,
        "wrong_ci": ci(wrong),
        "median_steps": float(np.median(steps)) if steps.size else math.nan,
        "p90_steps": float(np.percentile(steps, 90)) if steps.size else math.nan,
    }


@command
def main(argv: list[str] | None = None) -> int:
    """The command: parse ``argv`` (default ``sys.argv[1:]``), run the episodes, write table and figures."""
    argv = sys.argv[1:] if argv is None else list(argv)
    args = parse(Args, argv, __doc__).resolved()
    cases = list(args.cases)
    jobs = [
        (c, sem, s, args.max_steps, args.particles, args.mcl, s == args.first_seed, args.env_id)
        for c in cases
        for sem in (False, True)
        for s in range(args.first_seed, args.first_seed + args.seeds)
    ]
    t0 = time.perf_counter()
    results = run_jobs(run_episode, jobs, args.runner, desc="episodes")
    elapsed = time.perf_counter() - t0
    out = Path(args.out)
    table = {
        (c, sem): summarise([r for r in results if r["case"] == c and r["semantic"] == sem])
        for c in cases
        for sem in (False, True)
    }
    _plot_weights(results, cases, out / "figures" / "paper004_mean_weight.png")
    _plot_snapshots(results, cases[0], out / "figures" / "paper004_particles.png")
    _write_markdown(table, args, command_line("scripts/repro_paper004.py", argv), elapsed, out / "paper004.md")
    for (c, sem), s in table.items():
        print(
            f"{c:12s} {'lidar+semantic' if sem else 'lidar only':15s} success {s['success']:5.1f}% "
            f"wrong {s['wrong']:5.1f}% median steps {s['median_steps']:.0f} p90 {s['p90_steps']:.0f}"
        )
    return 0


def _plot_weights(results, cases, path):
    plt = pyplot()
    fig, axes = plt.subplots(1, len(cases), figsize=(4.2 * len(cases), 3.2), dpi=100, squeeze=False)
    for ax, case in zip(axes[0], cases):
        for sem, color in ((False, "tab:orange"), (True, "tab:blue")):
            runs = [r["weights"] for r in results if r["case"] == case and r["semantic"] == sem]
            length = max(len(w) for w in runs)
            mat = np.full((len(runs), length), np.nan)
            for i, w in enumerate(runs):
                mat[i, : len(w)] = w
            # a finished (successful) episode keeps its last value: the filter stays where it was
            mat = _ffill(mat)
            seen = ~np.isnan(mat)  # steps before any run's first update have no value (no warning)
            mean = np.divide(
                np.where(seen, mat, 0.0).sum(axis=0),
                seen.sum(axis=0),
                out=np.full(length, np.nan),
                where=seen.any(axis=0),
            )
            ax.plot(
                np.arange(1, length + 1),
                mean,
                color=color,
                label="lidar + semantic" if sem else "lidar only",
            )
        ax.set_title(case, fontsize=9)
        ax.set_xlabel("iteration (step)")
        ax.set_ylabel("mean per-beam lidar likelihood")
        ax.legend(fontsize=7)
    fig.tight_layout()
    save_figure(fig, path)


def _ffill(mat: np.ndarray) -> np.ndarray:
    """Each NaN takes the last non-NaN value to its left in its row (leading NaNs stay NaN)."""
    idx = np.where(np.isnan(mat), 0, np.arange(mat.shape[1]))
    np.maximum.accumulate(idx, axis=1, out=idx)
    return mat[np.arange(mat.shape[0])[:, None], idx]


def _plot_snapshots(results, case, path):
    plt = pyplot()
    from semreloc_env.layouts import get_layout
    from semreloc_env.render import draw_layout

    layout = get_layout(CASES[case]["layout"])
    fig, axes = plt.subplots(2, 4, figsize=(14, 5.5), dpi=90)
    for row, sem in enumerate((False, True)):
        r = next(r for r in results if r["case"] == case and r["semantic"] == sem and r["snapshots"])
        for col, step in enumerate(SNAPSHOT_STEPS):
            ax = axes[row, col]
            draw_layout(ax, layout)
            if step in r["snapshots"]:
                poses, truth = r["snapshots"][step]
                ax.plot(poses[:, 0], poses[:, 1], ".", ms=1, color="#aa00aa")
                ax.plot(truth[0], truth[1], "k*", ms=10)
                ax.set_title(f"{'lidar+semantic' if sem else 'lidar only'}, step {step}", fontsize=8)
            else:
                ax.set_title(f"{'lidar+semantic' if sem else 'lidar only'}, step {step}: episode over", fontsize=8)
            ax.set_xticks([])
            ax.set_yticks([])
    fig.tight_layout()
    save_figure(fig, path)


def _write_markdown(table, args: Args, cmd: str, elapsed: float, path: Path) -> None:
    rows = [
        [
            c,
            "lidar + semantic" if sem else "lidar only",
            f"{s['success']:.0f} ({s['success_ci'][0]:.0f}-{s['success_ci'][1]:.0f})",
            f"{s['wrong']:.0f} ({s['wrong_ci'][0]:.0f}-{s['wrong_ci'][1]:.0f})",
            f"{s['median_steps']:.0f}",
            f"{s['p90_steps']:.0f}",
        ]
        for (c, sem), s in table.items()
    ]
    header = ["case", "relocalizer", "success % (95% CI)", "wrong convergence % (95% CI)", "median steps", "p90 steps"]
    block = "\n".join(
        [
            f"Made by `{cmd}` ({args.seeds} seeds per row, {args.particles} particles, "
            f"time limit {args.max_steps} steps, {elapsed / 60:.1f} min on {args.runner.describe()}).",
            "",
            markdown_table(header, rows),
            "",
            "![mean lidar weight](figures/paper004_mean_weight.png)",
            "",
            "![particle snapshots](figures/paper004_particles.png)",
        ]
    )
    title = "Paper 004 reproduced: lidar-only vs lidar + semantic relocalization"
    replace_block(path, block, "<!-- results:start -->", "<!-- results:end -->", title)


if __name__ == "__main__":
    raise SystemExit(main())
