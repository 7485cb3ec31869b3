"""Benchmarks of the relocalizer: measurement kernel (numba vs NumPy reference) and a full MCL step.

Usage::

    python scripts/bench.py                    # defaults: N=2000 particles, B=60 beams
    python scripts/bench.py --particles 5000 --beams 120 --repeats 50

Each benchmark is a function ``bench_*(args) -> list[Row]``; :func:`main` runs them
all and prints one table. Add a benchmark by writing a function and listing it in
:data:`BENCHMARKS`. Single-threaded numba kernels; numba compile time is excluded
(one warm-up call before timing). Times are the median over ``--repeats`` runs.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np

try:
    import filters  # noqa: F401
except ImportError:  # running from a checkout without `pip install -e .`
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from filters.localization.likelihood_field import LikelihoodFieldModel, log_likelihood_kernel
from filters.localization.likelihood_reference import log_likelihood_reference
from filters.localization.mcl import MCLConfig, MonteCarloLocalizer
from filters.mapping.grid import DEFAULT_CLASS_NAMES, GridMap
from filters.simulators.grid_raycast import simulate_lidar, simulate_semantic


@dataclass(frozen=True)
class Args:
    """Benchmark options (each one is a ``--flag``)."""

    particles: int = 2000
    """N: particles."""
    beams: int = 60
    """B: lidar beams per scan (all within range)."""
    semantic_beams: int = 0
    """labelled semantic beams added to each scan for the likelihood benchmark (0 = lidar only)."""
    map_size_m: float = 20.0
    """edge of the square synthetic map, metres (0.05 m cells)."""
    repeats: int = 30
    """timed repetitions (median reported)."""
    seed: int = 0
    """seed of the synthetic map, poses and scans."""


@dataclass(frozen=True)
class Row:
    name: str
    value: float
    unit: str
    note: str = ""


def synthetic_map(size_m: float, seed: int) -> GridMap:
    """A square room with random boxes, some of them labelled with a class."""
    res = 0.05
    n = int(round(size_m / res))
    rng = np.random.default_rng(seed)
    occ = np.zeros((n, n), np.float32)
    occ[0, :] = occ[-1, :] = occ[:, 0] = occ[:, -1] = 1.0
    sem = np.zeros((len(DEFAULT_CLASS_NAMES), n, n), np.float32)
    for k in range(int(size_m * size_m / 8)):
        r, c = rng.integers(10, n - 30, 2)
        h, w = rng.integers(4, 20, 2)
        occ[r : r + h, c : c + w] = 1.0
        if k % 3 == 0:
            sem[k % len(DEFAULT_CLASS_NAMES), r : r + h, c : c + w] = 1.0
    return GridMap(occ, res, (0.0, 0.0), sem, DEFAULT_CLASS_NAMES)


def _scene(args: Args):
    grid = synthetic_map(args.map_size_m, args.seed)
    rng = np.random.default_rng(args.seed)
    free = np.argwhere(grid.free_mask())
    cell = free[rng.integers(len(free))]
    pose = np.array([(cell[1] + 0.5) * grid.resolution_m, (cell[0] + 0.5) * grid.resolution_m, 0.3])
    angles = np.linspace(-np.pi, np.pi, args.beams, endpoint=False)
    lidar = simulate_lidar(grid, pose, angles, 1e3)  # huge range: every beam returns
    lidar = type(lidar)(np.minimum(lidar.ranges, 29.0), lidar.angles, 30.0)
    semantic = None
    if args.semantic_beams:
        sa = np.linspace(-0.5, 0.5, args.semantic_beams)
        semantic = simulate_semantic(grid, pose, sa, 30.0)
        labels = np.where(semantic.labels > 0, semantic.labels, 1 + np.arange(sa.size) % len(DEFAULT_CLASS_NAMES))
        semantic = type(semantic)(np.minimum(semantic.ranges, 29.0), sa, labels, 30.0)
    xy = free[rng.integers(len(free), size=args.particles)]
    poses = np.column_stack(
        [
            (xy[:, 1] + rng.random(args.particles)) * grid.resolution_m,
            (xy[:, 0] + rng.random(args.particles)) * grid.resolution_m,
            rng.uniform(-np.pi, np.pi, args.particles),
        ]
    )
    return grid, pose, poses, lidar, semantic


def _median_time(fn: Callable[[], object], repeats: int) -> float:
    fn()  # warm-up (numba compile, table cache)
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def bench_likelihood(args: Args) -> list[Row]:
    """Measurement model: particle-beams per second, numba kernel vs NumPy reference."""
    grid, _, poses, lidar, semantic = _scene(args)
    model = LikelihoodFieldModel(grid)
    beams = model.beams(lidar, semantic)
    nb = beams.n_lidar + beams.n_semantic
    work = args.particles * nb
    t_numba = _median_time(lambda: model.log_likelihood(poses, lidar, semantic), args.repeats)
    t_numpy = _median_time(lambda: log_likelihood_reference(model, poses, lidar, semantic), max(3, args.repeats // 5))
    tables, floors = model.log_tables(beams.lidar_range_max_m, beams.semantic_range_max_m)
    x, y = poses[:, 0].copy(), poses[:, 1].copy()
    c, s = np.cos(poses[:, 2]), np.sin(poses[:, 2])
    out_l, out_s = np.zeros(args.particles), np.zeros(args.particles)
    ox, oy = grid.origin_xy_m
    kernel_args = (
        x,
        y,
        c,
        s,
        beams.lx,
        beams.ly,
        beams.table,
        beams.n_lidar,
        tables,
        floors,
        ox,
        oy,
        1.0 / grid.resolution_m,
        out_l,
        out_s,
    )
    t_kernel = _median_time(lambda: log_likelihood_kernel(*kernel_args), args.repeats)
    a = model.log_likelihood(poses, lidar, semantic)
    b = log_likelihood_reference(model, poses, lidar, semantic)
    shape = f"N={args.particles}, B={nb}"
    unit = "M particle-beams/s"
    return [
        Row("likelihood numba", work / t_numba / 1e6, unit, f"{shape}, {t_numba * 1e3:.3f} ms/update"),
        Row("  of which kernel", work / t_kernel / 1e6, unit, f"{t_kernel * 1e3:.3f} ms (no beam prep)"),
        Row("likelihood numpy ref", work / t_numpy / 1e6, unit, f"{shape}, {t_numpy * 1e3:.3f} ms/update"),
        Row("speed-up numba/numpy", t_numpy / t_numba, "x", f"max |diff| = {np.max(np.abs(a - b)):.1e}"),
    ]


def bench_mcl_step(args: Args) -> list[Row]:
    """A full filter step: predict + update (forced) + resample (every step), steps per second."""
    grid, pose, _, lidar, semantic = _scene(args)
    rows = []
    for sem_on in (False, True) if semantic is not None else (False,):
        cfg = MCLConfig(n_particles=args.particles, resample_ess_frac=1.0, use_semantic=sem_on)
        mcl = MonteCarloLocalizer(grid, cfg, np.random.default_rng(args.seed))
        mcl.init_global()

        def step(mcl=mcl, delta=ODOM_STEP):
            mcl.predict(delta)
            d = mcl.update(lidar, semantic, force=True)
            assert d.resampled

        t = _median_time(step, args.repeats)
        label = "+semantic" if sem_on else ""
        rows.append(Row(f"MCL step{label}", 1.0 / t, "steps/s", f"N={args.particles}, {t * 1e3:.3f} ms/step"))
        t_b = _median_time(mcl.belief, args.repeats)
        if not sem_on:
            rows.append(Row("belief summary", 1.0 / t_b, "calls/s", f"{t_b * 1e3:.3f} ms/call"))
    return rows


ODOM_STEP = (0.05, 0.0, 0.02)
"""Odometry increment of one benchmarked MCL step (dx m, dy m, dtheta rad)."""


def bench_env(args: Args) -> list[Row]:
    """``SemReloc-v1`` steps per second (N particles, B lidar beams, semantic camera), against
    the same world + sensors without any filter, measured in the same run."""
    import gymnasium as gym

    import semreloc_env  # noqa: F401
    from agents.baselines import WallFollowExplorer

    kwargs = dict(map_source="perfect", lidar={"n_beams": args.beams}, relocalizer={"n_particles": args.particles})
    env = gym.make("SemReloc-v1", **kwargs).unwrapped
    n_steps = 20 * args.repeats

    def episode(step_fn) -> float:
        policy = WallFollowExplorer()
        obs, _ = env.reset(seed=args.seed)
        for _ in range(10):  # warm-up: numba, caches
            obs = step_fn(policy(obs))
        t0 = time.perf_counter()
        for _ in range(n_steps):
            obs = step_fn(policy(obs))
        return n_steps / (time.perf_counter() - t0)

    full = episode(lambda a: env.step(a)[0])

    def world_only(a):
        env._move(a)
        lidar, semantic = env._sense()
        from semreloc_env.envs.spaces import make_observation

        return make_observation(lidar, semantic, np.zeros(3))

    bare = episode(world_only)
    note = f"N={args.particles}, {args.beams} lidar + {env.camera.params.n_beams} semantic beams"
    return [
        Row("SemReloc-v1 step", full, "steps/s", note),
        Row("  world + sensors only", bare, "steps/s", "pymunk + ray casting, no filter"),
        Row("  filter share of a step", 1.0 - full / bare, "fraction", ""),
    ]


def bench_mapping(args: Args) -> list[Row]:
    """Occupancy + semantic mapping of a lab-sized run: 1000 poses x 60 beams into a 15 m x 10 m grid."""
    from filters.mapping.occupancy import OccupancyMapper, SemanticMapper
    from filters.robot_data.scans import LaserScan, SemanticScan

    rng = np.random.default_rng(args.seed)
    n, b = 1000, 60
    poses = np.column_stack([rng.uniform(0.5, 14.5, n), rng.uniform(0.5, 9.5, n), rng.uniform(-np.pi, np.pi, n)])
    angles = np.linspace(-np.pi, np.pi, b, endpoint=False)
    lidar = [LaserScan(rng.uniform(0.2, 12.0, b), angles, 10.0) for _ in range(n)]
    camera = [SemanticScan(rng.uniform(0.2, 5.0, b), angles, rng.integers(0, 5, b), 4.0) for _ in range(n)]

    def run():
        occ, sem = OccupancyMapper((200, 300), 0.05), SemanticMapper((200, 300), 0.05)
        for p, s in zip(poses, lidar, strict=True):
            occ.update(p, s)
        sem.update_many(poses, camera)
        return occ.to_grid(sem)

    t = _median_time(run, max(1, min(args.repeats, 5)))
    return [Row("mapping_lab_run", t, "s", "1000 poses x 60 beams, 200 x 300 cells (was a < 3 s test)")]


BENCHMARKS: list[Callable[[Args], list[Row]]] = [bench_likelihood, bench_mcl_step, bench_env, bench_mapping]


def parse_args(argv: list[str] | None = None) -> Args:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    for f in fields(Args):
        parser.add_argument(f"--{f.name.replace('_', '-')}", type=type(f.default), default=f.default)
    return Args(**vars(parser.parse_args(argv)))


def print_table(rows: list[Row]) -> None:
    w = max(len(r.name) for r in rows)
    for r in rows:
        print(f"{r.name:<{w}}  {r.value:>12.2f}  {r.unit:<20} {r.note}")


def main(argv: list[str] | None = None) -> list[Row]:
    args = parse_args(argv)
    print(f"# semreloc bench: {args}")
    rows: list[Row] = []
    for bench in BENCHMARKS:
        print(f"... {bench.__name__}", file=sys.stderr, flush=True)
        rows.extend(bench(args))
    print_table(rows)
    return rows


if __name__ == "__main__":
    main()
