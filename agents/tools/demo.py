"""Main demo: a global relocalization on the ``lab`` layout, drawn and plotted.

Writes into ``--out`` (default ``out/demo``):

* ``world.png`` — the lab at the start: walls, objects in paper 004's colours,
  lidar beams (orange) and semantic beams (class colours; grey where they hit no object);
* ``relocalization.gif`` — the episode: particles (magenta), true pose (black), estimate (dashed brown);
* ``error.png`` — position error, the heaviest hypothesis's spread and its share of the mass against step;

and prints a one-line result. Run ``python scripts/demo.py --help`` for options.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path

import gymnasium as gym
import numpy as np

import semreloc_env  # noqa: F401  (registers the envs)
from agents.baselines import WallFollowExplorer
from filters.experiments.cli import command, parse
from filters.experiments.report import pyplot, save_figure


@dataclass(frozen=True)
class Args:
    layout: str = "lab"
    """layout name or file"""
    seed: int = 2
    """episode seed (start pose, sensor noise, filter draws); 2 shows a typical success,
    other seeds fail now and then (rates over many seeds: docs/paper004.md)"""
    steps: int = 400
    """maximum control steps (10 Hz)"""
    lidar_only: bool = False
    """run the relocalizer without the semantic factor"""
    frame_every: int = 2
    """keep one animation frame every this many steps"""
    out: str = "out/demo"
    """output folder"""

    def __post_init__(self) -> None:
        if self.steps < 1 or self.frame_every < 1:
            raise ValueError(f"steps and frame_every must be >= 1, got {self.steps} and {self.frame_every}")
        if self.seed < 0:
            raise ValueError(f"seed must be >= 0, got {self.seed}")
        from semreloc_env.layouts import check_layout_option

        check_layout_option(self.layout)  # an unknown name or a malformed file: the parser's message


@command
def main(argv: list[str] | None = None) -> int:
    """The command: parse ``argv`` (default ``sys.argv[1:]``), run one episode, write the pictures."""
    args = parse(Args, argv, __doc__)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    env = gym.make("SemReloc-v22", layout=args.layout, semantic=not args.lidar_only, render_mode="rgb_array")
    policy = WallFollowExplorer()
    obs, info = env.reset(seed=args.seed)
    from PIL import Image

    Image.fromarray(_world_picture(env)).save(out / "world.png")
    frames = [env.render()]
    errors, spreads, masses, converged_at = [], [], [], None
    for step in range(1, args.steps + 1):
        obs, reward, terminated, truncated, info = env.step(policy(obs))
        errors.append(info["pose_error"]["position"])
        best = _best(info)
        spreads.append(best[1])
        masses.append(best[0])
        if converged_at is None and info["belief"]["converged"]:
            converged_at = step
        if step % args.frame_every == 0 or terminated:
            frames.append(env.render())
        if terminated or truncated:
            break
    images = [Image.fromarray(f) for f in frames]
    images[0].save(out / "relocalization.gif", save_all=True, append_images=images[1:], duration=150, loop=0)
    _plot(errors, spreads, masses, converged_at, out / "error.png", args)
    env.close()
    err = info["pose_error"]
    verdict = "SUCCESS" if terminated else ("converged WRONG" if info["belief"]["converged"] else "not converged")
    print(
        f"{args.layout} seed {args.seed} ({'lidar only' if args.lidar_only else 'lidar + semantic'}): {verdict} "
        f"after {step} steps; final error {err['position']:.2f} m / {math.degrees(err['heading']):.1f} deg, "
        f"heaviest hypothesis {100 * _best(info)[0]:.0f} % of the mass, spread {_best(info)[1]:.2f} m; "
        f"wrote {out}/world.png, relocalization.gif, error.png "
        f"in {time.perf_counter() - t0:.1f} s"
    )
    return 0


def _best(info) -> tuple[float, float]:
    """(weight, position std m) of the belief's heaviest hypothesis (0 and the whole spread if none)."""
    hyps = info["belief"]["hypotheses"]
    if not hyps:
        return 0.0, info["belief"]["pos_std_m"]
    cov = np.asarray(hyps[0]["cov"])
    return hyps[0]["weight"], float(np.sqrt(max(cov[0, 0] + cov[1, 1], 0.0)))


def _world_picture(env) -> np.ndarray:
    """The world with the robot's lidar and semantic beams, without the belief."""
    from semreloc_env.render import Renderer

    base = env.unwrapped
    renderer = Renderer(base.layout)
    state = {
        **base._render_state(),
        "particles": None,
        "estimate": None,
        "title": f"{base.layout.name}: world and beams",
    }
    frame = renderer.draw(state)
    renderer.close()
    return frame


def _plot(errors, spreads, masses, converged_at, path: Path, args: Args) -> None:
    fig, ax = pyplot().subplots(figsize=(7, 3.2), dpi=100)
    steps = np.arange(1, len(errors) + 1)
    ax.plot(steps, errors, label="position error of the estimate (m)")
    ax.plot(steps, spreads, label="spread of the heaviest hypothesis (m)")
    ax.plot(steps, masses, label="its share of the mass", color="tab:green", alpha=0.8)
    if converged_at is not None:
        ax.axvline(converged_at, color="k", ls=":", label=f"converged (step {converged_at})")
    ax.set_yscale("log")
    ax.set_xlabel("step (0.1 s)")
    ax.set_title(f"global relocalization, {args.layout}, seed {args.seed}")
    ax.legend(fontsize=8)
    fig.tight_layout()
    save_figure(fig, path)


if __name__ == "__main__":
    raise SystemExit(main())
