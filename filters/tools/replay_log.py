"""Replay a robot log (CARMEN) through the Monte Carlo localizer against the log's corrected poses.

Tracking (``--mode track``, cloud around the first pose) or global localization
(``--mode global``, uniform over free space) from scan ``--start``. The map is a ROS map
(``--map x.yaml``) or, by default, built from the log's own corrected poses and saved as
``<out>/map.yaml`` (so tracking measures the filter against the scan matcher that made the
poses, on a map of the same data).

Prints error statistics and writes into ``--out`` (default ``out/replay``):

* ``error.png``: position error of the belief mean and particle spread against scan;
* ``particles.gif``: particles on the map, reference pose (green) and estimate (magenta).

``--trials N`` (global mode) also runs `filters.robot_data.replay.global_localization_trials`
from N evenly spaced start scans (``--trial-steps`` scans each) and prints the outcome counts.

Example: ``python scripts/replay_log.py --mode global --particles 10000 --trials 44`` (``semreloc-replay-log``
is the same command).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np

from filters.experiments.cli import command, parse, usage_error
from filters.experiments.report import pyplot, save_figure
from filters.localization.mcl import MCLConfig
from filters.mapping.from_scans import map_from_scans
from filters.mapping.grid import GridMap
from filters.mapping.ros_map import MapFormatError, load_map
from filters.robot_data import ACES_LOG
from filters.robot_data.carmen import CarmenLogError, read_carmen
from filters.robot_data.replay import MapMismatchError, Track, global_localization_trials, summarize_trials, track

DEFAULT_LOG = ACES_LOG
"""The ACES log, shipped with the package (`filters.robot_data.ACES_LOG`)."""


@dataclass(frozen=True)
class Args:
    """Replay a robot log (CARMEN) through the Monte Carlo localizer against the log's corrected poses."""

    log: str = str(DEFAULT_LOG)
    """CARMEN log (.log or .log.gz); default: the ACES log shipped with the package (filters.robot_data.ACES_LOG)"""
    map: str = ""
    """ROS map .yaml/.yml; empty = built from the log's poses"""
    resolution: float = 0.05
    """cell size of a map built from the log (m)"""
    mode: Literal["track", "global"] = "track"
    """track: cloud around the start pose; global: uniform over free space"""
    particles: int = 2000
    """particles of the localizer"""
    seed: int = 0
    """seed of the localizer's draws"""
    start: int = 0
    """first scan"""
    steps: int = 0
    """scans to replay (0 = to the end)"""
    trials: int = 0
    """global mode: evenly spaced start scans to try"""
    trial_steps: int = 60
    """scans per global-localization trial"""
    frame_every: int = 2
    """one GIF frame every this many scans (0 = no GIF)"""
    gif_px: int = 480
    """longer side of the GIF in pixels"""
    out: str = "out/replay"
    """output folder (map.yaml when built, error.png, particles.gif)"""

    def __post_init__(self) -> None:
        if self.particles < 1 or self.start < 0 or self.steps < 0 or self.trials < 0 or self.frame_every < 0:
            raise ValueError("particles >= 1 and start, steps, trials, frame_every >= 0 are required")
        if not self.resolution > 0 or self.trial_steps < 1 or self.gif_px < 16:
            raise ValueError("resolution > 0, trial_steps >= 1 and gif_px >= 16 are required")
        if self.trials and self.mode != "global":
            raise ValueError("--trials runs global localization trials: it needs --mode global")


class LogArgumentError(ValueError):
    """An option that does not fit the log it is given (``--start`` or ``--trials`` beyond its scans)."""


def _map(args: Args, log, out: Path) -> GridMap:
    if args.map:
        return load_map(args.map)
    return map_from_scans(log.poses, log.scans(), resolution_m=args.resolution, save_to=out / "map.yaml")


def _plot(tr: Track, path: Path, title: str) -> None:
    fig, ax = pyplot().subplots(figsize=(7, 3.2), dpi=100)
    ax.plot(tr.scan_index, np.maximum(tr.pos_error_m, 1e-3), label="position error of the estimate (m)")
    ax.plot(tr.scan_index, np.maximum(tr.pos_std_m, 1e-3), label="particle spread (m)", alpha=0.8)
    ax.set_yscale("log")
    ax.set_xlabel("scan")
    ax.set_title(title, fontsize=9)
    ax.legend(fontsize=8)
    fig.tight_layout()
    save_figure(fig, path)


def _gif(tr: Track, log, grid: GridMap, path: Path, every: int, px: int) -> None:
    from PIL import Image, ImageDraw

    f = max(1, math.ceil(max(grid.shape) / px))  # cells per pixel; a pixel is a wall if any of its cells is
    h, w = (math.ceil(n / f) for n in grid.shape)

    def pooled(mask):
        m = np.zeros((h * f, w * f), bool)
        m[: mask.shape[0], : mask.shape[1]] = mask
        return m.reshape(h, f, w, f).any(axis=(1, 3))

    grey = np.full((h, w), 170, np.uint8)
    grey[pooled(grid.free_mask())] = 255
    grey[pooled(grid.occupied_mask())] = 0
    base = Image.fromarray(grey[::-1]).convert("RGB")
    ox, oy = grid.origin_xy_m
    k = 1.0 / (f * grid.resolution_m)

    def to_px(xy):
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        return np.column_stack([(xy[:, 0] - ox) * k, base.height - (xy[:, 1] - oy) * k])

    frames = []
    for i in range(0, len(tr.scan_index), every):
        im = base.copy()
        d = ImageDraw.Draw(im)
        parts = tr.particles[i]
        sel = parts[:: max(1, parts.shape[0] // 3000)]
        for x, y in to_px(sel[:, :2]):
            d.rectangle((x - 1, y - 1, x, y), fill=(30, 90, 255))
        for pose, colour in ((log.poses[tr.scan_index[i]], (0, 170, 0)), (tr.estimate[i], (220, 0, 200))):
            (x, y), r = to_px(pose[:2])[0], 4
            d.ellipse((x - r, y - r, x + r, y + r), outline=colour, width=2)
            d.line((x, y, x + 10 * math.cos(pose[2]), y - 10 * math.sin(pose[2])), fill=colour, width=2)
        d.text((4, 4), f"scan {tr.scan_index[i]}  error {tr.pos_error_m[i]:.2f} m", fill=(0, 0, 0))
        frames.append(im)
    frames[0].save(path, save_all=True, append_images=frames[1:], duration=120, loop=0)


def run(args: Args) -> dict:
    """Replay as ``args`` says, print the statistics, write the files; returns ``{"track": Track.stats(),
    "trials": summarize_trials(...)}`` (trials in global mode with ``--trials`` only)."""
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    log = read_carmen(args.log)
    if args.start >= len(log):
        raise LogArgumentError(f"--start {args.start} is beyond the log's {len(log)} scans (0..{len(log) - 1})")
    if args.trials > len(log):
        raise LogArgumentError(f"--trials {args.trials} is more than the log's {len(log)} scans (one start scan each)")
    grid = _map(args, log, out)
    cfg = MCLConfig(n_particles=args.particles)
    stop = len(log) if args.steps <= 0 else min(len(log), args.start + args.steps)
    gif = args.frame_every > 0
    tr = track(
        log, grid, cfg, rng_seed=args.seed, start=args.start, stop=stop, global_init=args.mode == "global",
        record_particles=gif,
    )  # fmt: skip
    stats = tr.stats()
    label = f"{Path(args.log).name}: {args.mode}, {args.particles} particles, seed {args.seed}"
    print(
        f"{label}: scans {args.start}..{stop - 1}, map {grid.shape[1]} x {grid.shape[0]} @ {grid.resolution_m} m; "
        f"position error median {stats['pos_median_m']:.3f} m, mean {stats['pos_mean_m']:.3f}, "
        f"p95 {stats['pos_p95_m']:.3f}, max {stats['pos_max_m']:.3f}; heading median "
        f"{stats['theta_median_deg']:.2f} deg, p95 {stats['theta_p95_deg']:.2f}"
    )
    if args.mode == "global":
        conv = np.flatnonzero(tr.converged)
        print("  first converged at scan", int(tr.scan_index[conv[0]]) if conv.size else "never")
    _plot(tr, out / "error.png", label)
    if gif:
        _gif(tr, log, grid, out / "particles.gif", args.frame_every, args.gif_px)
    result = {"track": stats}
    if args.mode == "global" and args.trials > 0:
        starts = np.linspace(0, len(log) - 1, args.trials).round().astype(int)
        res = global_localization_trials(log, grid, cfg, starts, args.trial_steps, rng_seed=args.seed)
        summary = summarize_trials(res)
        correct = (
            f"correct ones after a median {summary['median_steps_correct']:.0f} scans, "
            f"error {summary['median_pos_error_correct_m']:.3f} m"
            if summary["correct"]
            else "none correct"
        )
        print(
            f"  global localization from {summary['trials']} start scans ({args.trial_steps} scans each): "
            f"{summary['correct']} correct, {summary['wrong']} wrong, {summary['unconverged']} unconverged; {correct}"
        )
        result["trials"] = summary
    wrote = f"{out}/error.png" + (f", {out}/particles.gif" if gif else "")
    print(f"  wrote {wrote} in {time.perf_counter() - t0:.1f} s")
    return result


@command
def main(argv: list[str] | None = None) -> int:
    """The command: parse ``argv`` (default ``sys.argv[1:]``) and `run`. A log or map that cannot be read,
    a map that does not hold the log's poses, or an option beyond the log, prints the reason and
    returns 2 (no traceback)."""
    args = parse(Args, argv, __doc__)
    try:
        run(args)
    except (CarmenLogError, MapFormatError, MapMismatchError, FileNotFoundError, LogArgumentError) as e:
        return usage_error("replay_log", e)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
