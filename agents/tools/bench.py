"""Speed of semreloc, in one run: kernels, env steps, stages, resets, maps, scaling, PPO.

Usage::

    python scripts/bench.py                 # everything (~5 min on 2 shared cores)
    python scripts/bench.py --quick         # skip the building-size layout and PPO
    python scripts/bench.py --only env stages

(``semreloc-bench`` is the same command; ``--help`` lists every option.)

Every figure is given twice: per CPU-second of this process (``time.process_time``; what
counts on a machine shared with other jobs) and per wall-clock second. Each benchmark is a
function ``bench_*(args) -> list[Row]`` listed in `BENCHMARKS`. Numba compile time is
excluded (warm-up calls before timing); repeated timings report the median.
"""

from __future__ import annotations

import contextlib
import statistics
import sys
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numba
import numpy as np

from filters.experiments.cli import command, parse
from filters.localization.likelihood_field import LikelihoodFieldModel, log_likelihood_kernel
from filters.localization.likelihood_reference import log_likelihood_reference
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
    steps: int = 600
    """env steps per steps/s measurement."""
    ppo_steps: int = 6144
    """PPO training steps per vec env (1024-step rollouts: six, timed after the first)."""
    quick: bool = False
    """skip the building-size layout and PPO."""
    only: tuple[str, ...] = ()
    """benchmark names, space-separated (e.g. likelihood env); empty = all."""
    env_id: str = ""
    """the SemReloc id the env, batched, stages, scaling, reset and PPO benchmarks run (empty = the newest,
    SemReloc-v22; e.g. SemReloc-v21 to compare a version in the next run)"""

    def __post_init__(self) -> None:
        if self.env_id:
            from semreloc_env import semreloc_ids_since

            if self.env_id not in semreloc_ids_since(2):
                raise ValueError(f"env_id: {self.env_id!r} is not one of {list(semreloc_ids_since(2))}")
        names = [b.__name__.removeprefix("bench_") for b in BENCHMARKS]
        unknown = [o for o in self.only if o not in names]
        if unknown:
            raise ValueError(f"only: unknown benchmarks {unknown}; choose from {names}")
        positive = ("particles", "beams", "repeats", "steps", "ppo_steps")
        bad = [f"{k}={getattr(self, k)}" for k in positive if getattr(self, k) < 1]
        bad += [f"semantic_beams={self.semantic_beams}"] * (self.semantic_beams < 0)
        bad += [f"map_size_m={self.map_size_m}"] * (not 0 < self.map_size_m < float("inf"))
        if bad:
            raise ValueError(
                f"particles, beams, repeats, steps, ppo_steps must be >= 1, semantic_beams >= 0 and map_size_m a "
                f"finite number > 0; got {', '.join(bad)}"
            )
        if self.quick and self.only and set(self.only) <= {"ppo"}:
            raise ValueError("--quick skips the PPO benchmark: --only ppo with --quick runs nothing")
        if self.ppo_steps < 2 * PPO_ROLLOUT and not self.quick and (not self.only or "ppo" in self.only):
            raise ValueError(f"ppo_steps must be >= {2 * PPO_ROLLOUT} (two rollouts: PPO is timed after the first)")


PPO_ROLLOUT = 1024
"""Env steps per rollout of the PPO benchmark, summed over the vec env's envs."""


@dataclass(frozen=True)
class Row:
    """One figure: ``cpu`` per CPU-second of this process, ``wall`` per wall-clock second (or the
    same quantity measured both ways); ``wall`` is NaN where only one value makes sense."""

    name: str
    cpu: float
    wall: float
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


class Clock:
    """CPU (this process) and wall seconds of a block: ``with Clock() as c: ...; c.cpu, c.wall``."""

    def __enter__(self) -> Clock:
        self._c, self._w = time.process_time(), time.perf_counter()
        return self

    def __exit__(self, *exc) -> None:
        self.cpu = time.process_time() - self._c
        self.wall = time.perf_counter() - self._w


def _median_time(fn: Callable[[], object], repeats: int) -> tuple[float, float]:
    """Median (CPU s, wall s) of ``fn()`` over ``repeats`` calls after one warm-up call."""
    return _interleaved_median_times([fn], repeats)[0]


def _interleaved_median_times(fns: list[Callable[[], object]], repeats: int) -> list[tuple[float, float]]:
    """`_median_time` of each of ``fns``, called in turn round by round (after one warm-up round), so that a change in
    the machine's load moves them alike."""
    for fn in fns:
        fn()
    times: list[tuple[list[float], list[float]]] = [([], []) for _ in fns]
    for _ in range(repeats):
        for fn, (cpus, walls) in zip(fns, times):
            with Clock() as c:
                fn()
            cpus.append(c.cpu)
            walls.append(c.wall)
    return [(statistics.median(cpus), statistics.median(walls)) for cpus, walls in times]


@numba.njit(cache=True, nogil=True, fastmath=True)
def fused_probe(x, y, c_, s_, lx, ly, offset, flat, floors_b, ox, oy, inv_res, w, h, out):  # pragma: no cover
    """The reference probe: the same look-up-and-sum as the likelihood kernel, fused into one loop
    over all beams, everything float32, fastmath (what a hand-tuned kernel could reach)."""
    for i in range(x.shape[0]):
        px = x[i]
        py = y[i]
        c = c_[i]
        s = s_[i]
        acc = np.float32(0.0)
        for j in range(lx.shape[0]):
            fx = (px + c * lx[j] - s * ly[j] - ox) * inv_res
            fy = (py + s * lx[j] + c * ly[j] - oy) * inv_res
            if fx >= 0 and fx < w and fy >= 0 and fy < h:
                acc += flat[offset[j] + int(fy) * w + int(fx)]
            else:
                acc += floors_b[j]
        out[i] = acc


def bench_likelihood(args: Args) -> list[Row]:
    """Measurement update: the shipped kernel vs the NumPy reference vs the fused float32 probe."""
    grid, _, poses, lidar, semantic = _scene(args)
    model = LikelihoodFieldModel(grid)
    beams = model.beams(lidar, semantic)
    nb = beams.n_lidar + beams.n_semantic
    work = args.particles * nb
    k_cpu, k_wall = _median_time(lambda: model.log_likelihood_terms(poses, lidar, semantic), args.repeats)
    r_cpu, r_wall = _median_time(
        lambda: log_likelihood_reference(model, poses, lidar, semantic), max(3, args.repeats // 5)
    )
    tables, floors = model.log_tables(beams.lidar_range_max_m, beams.semantic_range_max_m)
    h, w = grid.shape
    f32 = np.float32
    ox, oy = grid.origin_xy_m
    probe_args = (
        poses[:, 0].astype(f32),
        poses[:, 1].astype(f32),
        np.cos(poses[:, 2]).astype(f32),
        np.sin(poses[:, 2]).astype(f32),
        beams.lx.astype(f32),
        beams.ly.astype(f32),
        beams.table * (h * w),
        tables.ravel().astype(f32),
        floors[beams.table].astype(f32),
        f32(ox),
        f32(oy),
        f32(1.0 / grid.resolution_m),
        w,
        h,
        np.zeros(args.particles, f32),
    )
    p_cpu, p_wall = _median_time(lambda: fused_probe(*probe_args), args.repeats)
    _, _, flat = model._log_tables(beams.lidar_range_max_m, beams.semantic_range_max_m)
    inv = 1.0 / grid.resolution_m
    out_l, out_s = np.zeros(args.particles), np.zeros(args.particles)
    kernel_args = (
        poses[:, 0].copy(),
        poses[:, 1].copy(),
        np.cos(poses[:, 2]),
        np.sin(poses[:, 2]),
        beams.lx * inv,
        beams.ly * inv,
        beams.table * (h * w),
        beams.table + model.distance_fields_m.size,
        beams.n_lidar,
        flat,
        float(ox),
        float(oy),
        inv,
        w,
        h,
        out_l,
        out_s,
    )
    c_cpu, c_wall = _median_time(lambda: log_likelihood_kernel(*kernel_args), args.repeats)
    b = log_likelihood_reference(model, poses, lidar, semantic)
    fused_probe(*probe_args)
    probe_err = float(np.max(np.abs(probe_args[-1] - b)))
    log_likelihood_kernel(*kernel_args)
    kernel_err = float(np.max(np.abs(out_l + out_s - b)))
    shape = f"N={args.particles}, B={nb}"
    unit = "M particle-beams/s"
    return [
        Row("likelihood kernel", work / c_cpu / 1e6, work / c_wall / 1e6, unit, f"{shape}, {c_cpu * 1e3:.3f} ms CPU"),
        Row(
            "  with beam prep (model call)", work / k_cpu / 1e6, work / k_wall / 1e6, unit, f"{k_cpu * 1e3:.3f} ms CPU"
        ),
        Row("likelihood NumPy reference", work / r_cpu / 1e6, work / r_wall / 1e6, unit, f"{r_cpu * 1e3:.3f} ms CPU"),
        Row("fused float32 probe", work / p_cpu / 1e6, work / p_wall / 1e6, unit, f"{p_cpu * 1e3:.3f} ms CPU"),
        Row("kernel / probe speed", p_cpu / c_cpu, p_wall / c_wall, "x", "target >= 0.9"),
        Row("model call / NumPy reference speed", r_cpu / k_cpu, r_wall / k_wall, "x", ""),
        Row("max |kernel - reference|", kernel_err, float("nan"), "nats", f"probe: {probe_err:.1e} (float32)"),
    ]


ENV_ID = "SemReloc-v22"
PREVIOUS_ENV_ID = "SemReloc-v21"
"""The version before `ENV_ID`, measured beside it (batched env, reset) for the ratio of one run."""
ISSUE_ENV_ID = "SemReloc-v0"
"""The env issue 8 measured and set its targets on (the default then: 2000 particles, 60 lidar + 32 camera beams, a
belief summary at every step). Its reset and batched targets are measured on it too, beside `ENV_ID`, whose
relocalizer does more work per update and reset (issue 7)."""


def _env(args: Args, env_id: str = "", **kwargs):
    """``gym.make(env_id or --env-id or the newest, **kwargs)``, unwrapped."""
    import gymnasium as gym

    import semreloc_env  # noqa: F401

    with _older_ids_quiet():
        return gym.make(env_id or args.env_id or ENV_ID, **kwargs).unwrapped


@contextlib.contextmanager
def _older_ids_quiet():
    """Gymnasium's "out of date" warning left out for an older id, which the bench runs on purpose."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=".*out of date.*", category=DeprecationWarning)
        yield


def _steps_per_s(env, steps: int, seed: int, policy=None) -> tuple[float, float]:
    """(CPU, wall) env steps per second under ``policy`` (default: the wall-following explorer);
    resets not counted."""
    from agents.baselines import WallFollowExplorer

    policy = WallFollowExplorer() if policy is None else policy
    obs, _ = env.reset(seed=seed)
    for _ in range(20):
        obs = env.step(policy(obs))[0]
    cpu = wall = 0.0
    s = seed
    for _ in range(steps):
        action = policy(obs)
        with Clock() as c:
            obs, _, term, trunc, _ = env.step(action)
        cpu += c.cpu
        wall += c.wall
        if term or trunc:
            s += 1
            obs, _ = env.reset(seed=s)
    return steps / cpu, steps / wall


class RandomPolicy:
    """Uniform random discrete actions from a seeded generator (what early RL does)."""

    def __init__(self, seed: int) -> None:
        self.rng = np.random.default_rng(seed)

    def __call__(self, obs) -> int:
        return int(self.rng.integers(0, 4))


def bench_env(args: Args) -> list[Row]:
    """Single ``SemReloc-v22`` (or ``--env-id``) at its defaults (lab, mapped map, map-sized particle set with KLD,
    60 + 32 beams): the fast path against the NumPy reference path (``relocalizer={"fast_path": False}``, the
    code before the fused kernels; the same episodes bit for bit), interleaved, under the wall-following
    explorer and under random actions (which stay near the start, so their belief is often tight: a mean of
    about 1,900 particles in an outside tester's count, and the cheaper row)."""
    from agents.baselines import WallFollowExplorer
    from agents.tools.profile_step import compiled_time, stage_breakdown
    from filters import _blas

    rows = []
    env_id = args.env_id or ENV_ID
    for label, make_policy in (("explorer", lambda: None), ("random", lambda: RandomPolicy(args.seed))):
        fast = ref = (0.0, 0.0)
        for _ in range(2):  # interleaved rounds: the load changes over minutes; best of each
            half = max(1, args.steps // 2)
            f = _steps_per_s(_env(args), half, args.seed, make_policy())
            r = _steps_per_s(_env(args, relocalizer={"fast_path": False}), half, args.seed, make_policy())
            fast = max(fast, f)
            ref = max(ref, r)
        steps = max(1, args.steps // 2)  # the same steps again under cProfile: their compiled kernels' time
        kernels, ref_kernels = (
            compiled_time(stage_breakdown(env, make_policy() or WallFollowExplorer(), steps, args.seed)[2])[0] / steps
            for env in (_env(args), _env(args, relocalizer={"fast_path": False}))
        )
        rows += [
            Row(f"{env_id} step, {label}, fast path", fast[0], fast[1], "steps/s", f"{1e3 / fast[0]:.3f} ms CPU"),
            Row(f"{env_id} step, {label}, reference path", ref[0], ref[1], "steps/s", f"{1e3 / ref[0]:.3f} ms CPU"),
            Row("  fast / reference", fast[0] / ref[0], fast[1] / ref[1], "x", "the issue's 3x: the filing rows"),
            Row(
                "  a fast-path step's compiled kernels", kernels * 1e3, 100 * kernels * fast[0], "ms CPU | %",
                "the same steps under cProfile; the rest of the step is Python and NumPy",
            ),
            Row(
                "  a reference-path step's compiled kernels", ref_kernels * 1e3, 100 * ref_kernels * ref[0],
                "ms CPU | %", "the heavy kernels are both paths' (the audit's window scoring, the weighing, ray casts)",
            ),
            Row(
                "  reference / kernels alone", 1.0 / (kernels * ref[0]), float("nan"), "x",
                "what fast / reference would be with no Python left in the fast path",
            ),
        ]  # fmt: skip
    rows.append(
        Row("NumPy's OpenBLAS threads", float(_blas.openblas_threads() or 0), float("nan"), "", "0 = not OpenBLAS")
    )
    return rows


FILING_COMMIT = "229f60e518928576a7089ed8c8c69bef994c37a4"
"""main when issue 8 was filed, where its first round branched off (the first release's code, its filters moved into
packages): the code whose default ``SemReloc-v0`` step the issue measured (1.47 ms of CPU then), and whose steps per
CPU-second its single-env target is 3x of."""

_TIMED_V0 = """
import sys, time, warnings
root, policy, steps = sys.argv[1], sys.argv[2], int(sys.argv[3])
sys.path.insert(0, root)
warnings.filterwarnings("ignore")
import gymnasium as gym, numpy as np
import agents, filters, semreloc_env
from agents.baselines import WallFollowExplorer
for package in (agents, filters, semreloc_env):
    assert package.__file__.startswith(root), package.__file__
env = gym.make("SemReloc-v0")
rng = np.random.default_rng(0)
act = WallFollowExplorer() if policy == "explorer" else (lambda obs: int(rng.integers(0, 4)))
obs, _ = env.reset(seed=0)
for _ in range(20):
    obs = env.step(act(obs))[0]
cpu, ended = 0.0, 0
for _ in range(steps):
    a = act(obs)
    t = time.process_time()
    obs, _, term, trunc, _ = env.step(a)
    cpu += time.process_time() - t
    if term or trunc:
        ended += 1
        obs, _ = env.reset(seed=ended)
print(cpu / steps, ended)
"""
"""A ``SemReloc-v0`` episode timed in a process of its own: ``python -c _TIMED_V0 ROOT POLICY STEPS`` imports the
package from ``ROOT`` and prints the CPU seconds per step and the episodes that ended (each reset, with the next seed,
is not timed). It uses only what the code at `FILING_COMMIT` already had."""


def _code_at(commit: str, dest: Path) -> bool:
    """Extract the repository's files at ``commit`` into ``dest`` (``git archive``); False where that cannot be done:
    no git, a package not run from a git checkout, or a commit not in its history (a shallow clone)."""
    import io
    import subprocess
    import tarfile

    root = Path(__file__).resolve().parents[2]
    try:
        out = subprocess.run(["git", "-C", str(root), "archive", commit], capture_output=True, check=True)
    except (OSError, subprocess.CalledProcessError):
        return False
    with tarfile.open(fileobj=io.BytesIO(out.stdout)) as tar:
        if hasattr(tarfile, "data_filter"):  # Python 3.10.12+, 3.11.4+: refuse links and paths out of ``dest``
            tar.extractall(dest, filter="data")
        else:  # pragma: no cover - older patch releases; the archive is this repository's own
            tar.extractall(dest)
    return True


def _timed_v0(root: Path, policy: str, steps: int, numba_cache: Path) -> tuple[float, int]:
    """``(CPU s per step, episodes ended)`` of `_TIMED_V0` run on the package at ``root``.

    Raises:
        RuntimeError: the process failed (the end of its stderr in the message)."""
    import os
    import subprocess

    env = {**os.environ, "NUMBA_CACHE_DIR": str(numba_cache), "PYTHONWARNINGS": "ignore"}
    cmd = [sys.executable, "-c", _TIMED_V0, str(root), policy, str(steps)]
    done = subprocess.run(cmd, capture_output=True, text=True, check=False, env=env, cwd=root)
    if done.returncode:
        raise RuntimeError(f"timing SemReloc-v0 on the code at {root} failed:\n{done.stderr[-2000:]}")
    out = done.stdout.strip().splitlines()[-1].split()  # the last line: whatever the code printed before it
    return float(out[0]), int(out[1])


def bench_filing(args: Args) -> list[Row]:
    """The single-env target as the issue put it: ``SemReloc-v0`` at its defaults (2000 particles, 60 + 32 beams), the
    code at `FILING_COMMIT` against this code, in processes of their own called in turn (one round first, untimed,
    compiles both codes' kernels). The same seeded actions under random actions; the explorer's depend on what it
    sees. Later fixes to the world and the sensors changed v0's episodes too, so the two codes do not run the same
    episodes (the rows count the episodes that ended in each). A last row per policy runs this code's steps again in
    this process under cProfile: the time in compiled kernels, and how much of the rest 3x would need gone."""
    import tempfile

    import gymnasium as gym

    from agents.baselines import WallFollowExplorer
    from agents.tools.profile_step import compiled_time, stage_breakdown

    rounds = max(1, min(3, args.repeats))
    steps = max(20, args.steps // 2)
    short = FILING_COMMIT[:7]
    here = Path(__file__).resolve().parents[2]
    with tempfile.TemporaryDirectory(prefix="semreloc-filing-") as tmp:
        old = Path(tmp) / "code"
        if not _code_at(FILING_COMMIT, old):
            note = f"skipped: no git checkout with {short} in its history (a shallow clone?)"
            return [Row(f"SemReloc-v0 step, code at {short}", float("nan"), float("nan"), "ms CPU", note)]
        roots = {"filing": (old, Path(tmp) / "numba-old"), "this": (here, Path(tmp) / "numba-this")}
        rows = []
        for policy in ("explorer", "random"):
            for root, cache in roots.values():  # compile (or load) the kernels, untimed
                _timed_v0(root, policy, 5, cache)
            got: dict[str, list[tuple[float, int]]] = {k: [] for k in roots}
            for _ in range(rounds):
                for k, (root, cache) in roots.items():
                    got[k].append(_timed_v0(root, policy, steps, cache))
            old_s = statistics.median(t for t, _ in got["filing"])
            new_s = statistics.median(t for t, _ in got["this"])
            paired = [o / n for (o, _), (n, _) in zip(got["filing"], got["this"], strict=True)]
            ended = f"episodes ended: {got['filing'][0][1]} and {got['this'][0][1]} in {steps} steps"
            act = WallFollowExplorer() if policy == "explorer" else RandomPolicy(0)  # _TIMED_V0's actions
            with _older_ids_quiet():
                stats = stage_breakdown(gym.make("SemReloc-v0"), act, steps, 0)[2]
            kernels = compiled_time(stats)[0] / steps
            gone = (new_s - old_s / 3.0) / (new_s - kernels)  # of the step's Python and NumPy, for 3x
            rows += [
                Row(f"SemReloc-v0 step, {policy}, code at {short}", old_s * 1e3, float("nan"), "ms CPU", ""),
                Row(f"SemReloc-v0 step, {policy}, this code", new_s * 1e3, float("nan"), "ms CPU", ended),
                Row(
                    "  this code / code at filing, speed", old_s / new_s, float("nan"), "x",
                    f"target >= 3; rounds {min(paired):.2f}-{max(paired):.2f}x",
                ),
                Row(
                    "  this code's v0 step, compiled kernels", kernels * 1e3, 100 * kernels / new_s, "ms CPU | %",
                    f"3x needs {1e3 * old_s / 3:.2f} ms a step: {100 * gone:.0f} % of the rest gone",
                ),
            ]  # fmt: skip
    return rows


def bench_belief(args: Args) -> list[Row]:
    """Belief summary of real particle sets (a spread global belief after the first update, and a
    converged one): the numba kernels against the NumPy reference (same Belief bit for bit)."""
    from filters.localization.belief import summarize

    env = _env(args)
    env.reset(seed=args.seed)
    mcl = env.mcl
    sets = [("spread", mcl.poses.copy(), mcl.weights)]
    env_t = _env(args)
    env_t.reset(seed=args.seed, options={"tracking": True})
    sets.append(("tracking", env_t.mcl.poses.copy(), env_t.mcl.weights))
    rows = []
    for name, p, w in sets:
        f_cpu, f_wall = _median_time(lambda p=p, w=w: summarize(p, w, backend="numba"), args.repeats)
        r_cpu, r_wall = _median_time(lambda p=p, w=w: summarize(p, w, backend="numpy"), max(5, args.repeats // 3))
        n = p.shape[0]
        rows += [
            Row(f"belief summary, {name} (N={n}), numba", f_cpu * 1e3, f_wall * 1e3, "ms", ""),
            Row(f"belief summary, {name} (N={n}), reference", r_cpu * 1e3, r_wall * 1e3, "ms", ""),
            Row("  reference / numba", r_cpu / f_cpu, r_wall / f_wall, "x", ""),
        ]
    return rows


def bench_batched(args: Args) -> list[Row]:
    """Robot-steps/s of the batched env (SemRelocLoopVectorEnv: a loop over R robots) at R = 1, 16, 64, each robot
    stepped the same number of times from its reset (so every R sees the same episode phases); then R = 64 again
    with a 1000-particle filter (what `agents.train_active` trains with), and with a 100-particle filter (100
    proposal and audit candidates): what a robot-step costs besides the particle work (world, sensors, the filter's
    per-call code, info, the loop); and R = 64 of the version before the newest (`PREVIOUS_ENV_ID`, whose KLD
    sampling's retry draws a second sequence, which shrinks a set a little), right after the default R = 64, with
    their ratio (the episodes differ), and R = 64 of the env the issue set its target on (`ISSUE_ENV_ID`); those two
    not when ``--env-id`` names an older version."""
    from semreloc_env.envs.batched import SemRelocLoopVectorEnv

    rows = []
    n = max(20, args.steps // 4)
    small = {"n_particles": 100, "proposal_candidates": 100, "audit_candidates": 100, "audit_candidates_per_m2": 0.0}
    env_id = args.env_id or ENV_ID
    previous = (
        [
            (64, PREVIOUS_ENV_ID, None, f", {PREVIOUS_ENV_ID}", "the version before"),
            (64, ISSUE_ENV_ID, None, f", {ISSUE_ENV_ID}", "the env the issue measured; target 5000"),
        ]
        if env_id == ENV_ID
        else []
    )
    cases = [
        (1, env_id, None, "", ""),
        (16, env_id, None, "", ""),
        (64, env_id, None, "", "target 5000 at R=64"),
        *previous,
        (64, env_id, {"n_particles": 1000}, ", 1000-particle filter", "agents.train_active's particle count"),
        (64, env_id, small, ", 100-particle filter", "the cost that is not particle work"),
    ]
    for r, case_id, relocalizer, what, why in cases:
        kwargs = {} if relocalizer is None else {"relocalizer": relocalizer}
        with _older_ids_quiet():
            venv = SemRelocLoopVectorEnv(num_envs=r, env_id=case_id, **kwargs)
        venv.reset(seed=args.seed)
        rng = np.random.default_rng(args.seed)
        with Clock() as c:
            for _ in range(n):
                venv.step(rng.integers(0, 4, r))
        venv.close()
        note = f"random actions, {n} steps per robot" + (f"; {why}" if why else "")
        rows.append(Row(f"batched env R={r}{what}", n * r / c.cpu, n * r / c.wall, "robot-steps/s", note))
        if case_id == PREVIOUS_ENV_ID != env_id:  # the previous version, right after the newest at R = 64
            d, e = rows[-2], rows[-1]
            rows.append(Row(f"  {env_id} / {PREVIOUS_ENV_ID}", d.cpu / e.cpu, d.wall / e.wall, "x", ""))
    return rows


def bench_batched_split(args: Args) -> list[Row]:
    """Where a batched robot-step's CPU goes (`agents.tools.profile_step.batched_split`: R = 64, random actions): steps
    with a measurement update (and the convergence audits within them), steps without, autoresets, the vector env's
    own work; and the time in compiled kernels (a second run of the same steps under cProfile), with the robot-steps
    per CPU-second that would be left if nothing but those kernels ran; the last two for the env the issue measured
    (`ISSUE_ENV_ID`) too, with its heaviest kernels, unless ``--env-id`` names an older version."""
    from agents.tools.profile_step import batched_split, dispatch_seconds

    env_id = args.env_id or ENV_ID
    with _older_ids_quiet():
        s = batched_split(64, max(1, args.steps // 15), args.seed, env_id)
        issue = batched_split(64, max(1, args.steps // 15), args.seed, ISSUE_ENV_ID) if env_id == ENV_ID else None
    n, us = s.robot_steps, 1e6 / s.robot_steps
    dispatch = dispatch_seconds()
    fused = s.kernel_calls * dispatch  # what one call for all robots saves in dispatch (timed in a tight loop)
    audits = (
        f"{s.audits} searches for another place, {1e3 * s.audit_s / s.audits:.1f} ms of audit time per search"
        if s.audits
        else "no search for another place"
    )

    def part(name: str, seconds: float, note: str) -> Row:
        return Row(name, seconds * us, 100 * seconds / s.total_s, "us CPU | %", note)

    def each(seconds: float, count: int, what: str) -> str:
        return f"{count} of {n} robot-steps ({100 * count / n:.0f} %), {1e3 * seconds / max(count, 1):.2f} ms {what}"

    return [
        Row("batched R=64: one robot-step", s.total_s * us, float("nan"), "us CPU", f"{n} robot-steps, random actions"),
        part("  steps with a measurement update", s.update_s, each(s.update_s, s.update_steps, "each")),
        part("    of which convergence audits", s.audit_s, audits),
        part("  steps without an update", s.plain_s, each(s.plain_s, s.plain_steps, "each")),
        part("  autoresets", s.reset_s, each(s.reset_s, s.resets, "each")),
        part("  the vector env's own", s.loop_s, "actions checked, observations and infos batched"),
        part("compiled kernels (cProfile, same steps)", s.kernel_s, "numba calls; NumPy's random draws not counted"),
        Row("  robot-steps per CPU-s, kernels alone", n / s.kernel_s, float("nan"), "robot-steps/s", "no Python"),
        Row("  compiled calls per robot-step", s.kernel_calls / n, float("nan"), "calls", ""),
        Row("  one compiled call's dispatch", dispatch * 1e6, float("nan"), "us CPU", "an empty log_likelihood_kernel"),
        part("  dispatch one call for all robots saves", fused, "each kernel's calls fused over the robots"),
        Row(
            "  stacked (R, N_max, 3) / held particles",
            s.weighed_stacked / s.weighed if s.weighed else float("nan"),
            float("nan"),
            "x",
            "the sets the updates weigh first, padded to the largest (candidates, audits, resets not counted)",
        ),
        *([] if issue is None else _kernels_alone_rows(issue, ISSUE_ENV_ID, "the env the issue measured")),
    ]


def bench_robots_fused(args: Args) -> list[Row]:
    """A filter batched over robots, prototyped on the motion predict and the likelihood weighing
    (`agents.tools.robots_fused`): the kernel calls of R = 64 batched robots (``--env-id`` or the newest, random
    actions) recorded, then timed as the env makes them (one call per robot) against one call per batched step for
    all its robots, on inputs already laid out flat and with the laying out; CPU us per recorded robot-step."""
    from agents.tools.robots_fused import compare, record_calls

    with _older_ids_quiet():
        recorded = record_calls(64, max(1, args.steps // 15), args.seed, args.env_id or ENV_ID)
    rows = []
    for name, t in compare(recorded, max(3, args.repeats // 2)).items():
        bits = "the same bits" if t.same_bits else "RESULTS DIFFER"
        rows += [
            Row(f"{name} kernel, one call per robot", t.per_robot_us, float("nan"), "us CPU per robot-step",
                f"{t.calls} calls in {recorded.robot_steps} robot-steps"),
            Row("  one call for all robots, arrays flat", t.fused_us, float("nan"), "us CPU per robot-step",
                f"{t.groups} calls; {bits}"),
            Row("  the same, laying the arrays out", t.fused_laid_out_us, float("nan"), "us CPU per robot-step",
                "what the batched env would pay"),
            Row("  per robot / fused, arrays flat", t.per_robot_us / t.fused_us, float("nan"), "x", ""),
        ]  # fmt: skip
    return rows


def _kernels_alone_rows(s, env_id: str, what: str) -> list[Row]:
    """A batched split's robot-step, the robot-steps per CPU-second its compiled kernels alone would allow, and its
    three heaviest kernels (``s``: a `agents.tools.profile_step.BatchedSplit`)."""
    from agents.tools.profile_step import heaviest_text

    n, top = s.robot_steps, heaviest_text(s)
    return [
        Row(f"batched R=64, {env_id}: one robot-step", s.total_s * 1e6 / n, float("nan"), "us CPU", f"{what}; {n} "
            "robot-steps, random actions"),
        Row(f"  {env_id}: robot-steps per CPU-s, kernels alone", n / s.kernel_s, float("nan"), "robot-steps/s",
            f"{s.kernel_s * 1e6 / n:.0f} us per robot-step; heaviest: {top}"),
    ]  # fmt: skip


def bench_stages(args: Args) -> list[Row]:
    """Per-stage CPU time of a default step (cProfile, process clock; inflates short calls)."""
    from agents.baselines import WallFollowExplorer
    from agents.tools.profile_step import stage_breakdown

    stages, total, _ = stage_breakdown(_env(args), WallFollowExplorer(), max(200, args.steps // 2), args.seed)
    rows = [Row("step under cProfile", total * 1e3, float("nan"), "ms CPU", "stages below")]
    for k, v in stages.items():
        rows.append(Row(f"  {k}", v * 1e3, 100 * v / total, "ms CPU | %", ""))
    return rows


def bench_scaling(args: Args) -> list[Row]:
    """time(10000 particles, 180 beams) / time(2000, 60) per env step (all lidar beams used), on particle sets that
    hold those counts: `ISSUE_ENV_ID`'s (a set of fixed size, the filter the issue measured) and the version run's
    (``--env-id``, else the newest) with KLD sampling off (KLD shrinks a tight belief's set: a 10,000 budget held
    about 730 particles, and the ratio measured the beams alone). Each row's note gives the counts the sets held after
    their last step."""
    newest = args.env_id or ENV_ID
    runs = [(ISSUE_ENV_ID, {}, ISSUE_ENV_ID), (newest, {"kld": False}, f"{newest}, KLD off")]
    rows = []
    for env_id, extra, label in runs:
        out, held = {}, {}
        for n, b in ((2000, 60), (10000, 180)):
            relocalizer = {"n_particles": n, "lidar_field": {"max_beams": b}, **extra}
            env = _env(args, env_id=env_id, lidar={"n_beams": b}, relocalizer=relocalizer)
            out[n] = _steps_per_s(env, max(100, args.steps // 3), args.seed)
            held[n] = env.mcl.n_particles
        note = (
            f"{1e3 / out[10000][0]:.2f} vs {1e3 / out[2000][0]:.2f} ms CPU per step; the sets held {held[10000]:,} "
            f"and {held[2000]:,} particles at the end; target <= 12"
        )
        ratio = (out[2000][0] / out[10000][0], out[2000][1] / out[10000][1])
        rows.append(Row(f"time(10000, 180) / time(2000, 60), {label}", *ratio, "x", note))
    return rows


def _compiled_median(fns: list[Callable[[], object]]) -> float:
    """The median over ``fns`` of the CPU seconds each call spends inside this package's compiled kernels (each call
    under a cProfile of its own, which adds about 0.6 us to each kernel call)."""
    import cProfile
    import pstats

    from agents.tools.profile_step import compiled_time

    seconds = []
    for fn in fns:
        prof = cProfile.Profile(time.process_time)
        prof.enable()
        try:
            fn()
        finally:
            prof.disable()
        seconds.append(compiled_time(pstats.Stats(prof))[0])
    return statistics.median(seconds)


def bench_reset(args: Args) -> list[Row]:
    """reset() with a cached map (the newest version's, beside the version before and the env the issue measured,
    `ISSUE_ENV_ID`, on the same seeds in turn), gym.make with a cached map, and a new layout (no disk cache)."""
    import os

    repeats = max(20, args.repeats)
    env = _env(args)
    env.reset(seed=0)
    envs = [env]
    if (args.env_id or ENV_ID) == ENV_ID:  # the version before and the issue's env, beside the newest: the same seeds
        envs += [_env(args, env_id=PREVIOUS_ENV_ID), _env(args, env_id=ISSUE_ENV_ID)]
        for e in envs[1:]:
            e.reset(seed=0)
    streams = [iter(range(1, 10**6)) for _ in envs]
    timed = _interleaved_median_times([lambda e=e, s=s: e.reset(seed=next(s)) for e, s in zip(envs, streams)], repeats)
    r_cpu, r_wall = timed[0]
    n_spread = env.mcl.global_particle_count()
    # the timed resets' own seeds again (after the warm-up's seed 1), so the kernels' median is of the same resets
    kernels = _compiled_median([lambda s=s: env.reset(seed=s) for s in range(2, repeats + 2)])
    previous = []
    if len(envs) > 1:
        (b_cpu, b_wall), n_before = timed[1], envs[1].mcl.global_particle_count()
        what = f"reset() (cached map), {PREVIOUS_ENV_ID}"
        previous = [
            Row(what, b_cpu * 1e3, b_wall * 1e3, "ms", f"global, {n_before} particles; the same seeds, in turn"),
            Row(f"  {ENV_ID} / {PREVIOUS_ENV_ID} reset time", r_cpu / b_cpu, r_wall / b_wall, "x", ""),
        ]
    if len(envs) > 2:
        (v0_cpu, v0_wall), n_v0 = timed[2], envs[2].mcl.global_particle_count()
        note = f"the env the issue measured (14-24 ms then): global, {n_v0} particles, the same seeds; target <= 2 ms"
        previous.append(Row(f"reset() (cached map), {ISSUE_ENV_ID}", v0_cpu * 1e3, v0_wall * 1e3, "ms", note))
    seeds = streams[0]
    t_cpu, t_wall = _median_time(lambda: env.reset(seed=next(seeds), options={"tracking": True}), repeats)
    small = _env(args, relocalizer={"n_particles": 2000})
    small.reset(seed=0)
    s_cpu, s_wall = _median_time(lambda: small.reset(seed=next(seeds)), repeats)
    m_cpu, m_wall = _median_time(lambda: _env(args), 5)
    old = os.environ.get("SEMRELOC_CACHE_DIR")
    os.environ["SEMRELOC_CACHE_DIR"] = ""
    try:
        from semreloc_env.layouts import get_layout
        from semreloc_env.mapping_run import build_maps

        build_maps(get_layout("twin_rooms"))  # the mapping run's numba kernels compiled (or loaded): not counted
        rows = []
        for name, seed in (("procedural", 1001), ("procedural", 1002)):
            with Clock() as c:
                e = _env(args, layout=name, layout_seed=seed)
                e.reset(seed=0)
            rows.append((c.cpu, c.wall, e.layout.bounds()))
    finally:
        if old is None:
            del os.environ["SEMRELOC_CACHE_DIR"]
        else:
            os.environ["SEMRELOC_CACHE_DIR"] = old
    n_cpu = statistics.median(r[0] for r in rows)
    n_wall = statistics.median(r[1] for r in rows)
    x0, x1, y0, y1 = rows[0][2]
    return [
        Row("reset() (cached map)", r_cpu * 1e3, r_wall * 1e3, "ms", f"global, {n_spread} particles; target <= 2 ms"),
        Row(
            "  of which compiled kernels",
            kernels * 1e3,
            100 * kernels / r_cpu,
            "ms CPU | %",
            "median, the same seeds under cProfile: the first update weighs the draw and its injection's candidates",
        ),  # fmt: skip
        Row("reset() (cached map), tracking", t_cpu * 1e3, t_wall * 1e3, "ms", "500 particles around the pose"),
        Row("reset() (cached map), n_particles=2000", s_cpu * 1e3, s_wall * 1e3, "ms", "global, 2000 particles"),
        *previous,
        Row("gym.make (cached map)", m_cpu * 1e3, m_wall * 1e3, "ms", ""),
        Row(
            "new layout: gym.make + reset",
            n_cpu,
            n_wall,
            "s",
            f"procedural ~{x1 - x0:.0f} x {y1 - y0:.0f} m, mapping run; target <= 0.3 s",
        ),
    ]


_READY_CHILD = r"""
import json, os, resource, sys, time
os.environ["SEMRELOC_CACHE_DIR"] = ""


def peak_rss_mb():
    # VmHWM starts afresh at exec; ru_maxrss would carry the parent's peak into this child (Linux)
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) / 1024
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


import gymnasium as gym, numpy as np
import semreloc_env
from semreloc_env.layouts import get_layout
from semreloc_env.layouts.tiling import tiled_layout
from semreloc_env.mapping_run import build_maps, mapping_drive
build_maps(get_layout("twin_rooms"))  # warm numba caches (not counted)
gym.make("SemReloc-v22", layout="twin_rooms").reset(seed=0)
base_rss = peak_rss_mb()
nx, ny = int(sys.argv[1]), int(sys.argv[2])
layout = tiled_layout(get_layout("lab"), nx, ny)
n_poses = len(mapping_drive(layout, narrow=True)[0])  # the drive of SemReloc-v12 to v22 (mapping run version 6)
c0, w0 = time.process_time(), time.perf_counter()
env = gym.make("SemReloc-v22", layout=layout)
env.reset(seed=0)
c1, w1 = time.process_time(), time.perf_counter()
x0, x1, y0, y1 = layout.bounds()
print(json.dumps({"area": (x1 - x0) * (y1 - y0), "w": x1 - x0, "h": y1 - y0, "poses": n_poses,
                  "cpu": c1 - c0, "wall": w1 - w0, "base_rss_mb": base_rss,
                  "peak_rss_mb": peak_rss_mb()}))
"""


def _child_env() -> dict[str, str]:
    """This process's environment with the folder holding the imported packages first on ``PYTHONPATH``,
    so a child process imports the same code (a checkout or worktree, not another installed copy)."""
    import os

    import semreloc_env

    root = str(Path(semreloc_env.__file__).resolve().parents[1])
    paths = [root, *(p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p)]
    return {**os.environ, "PYTHONPATH": os.pathsep.join(paths)}


def bench_mapping(args: Args) -> list[Row]:
    """New layout ready (gym.make: mapping run + likelihood field, then reset) against area: copies of
    the lab, each in a fresh process (so peak RSS is that of the run; imports and numba warm-up excluded)."""
    import json
    import subprocess

    tiles = [(1, 1), (2, 2), (4, 4)] + ([] if args.quick else [(7, 6)])
    rows = []
    for nx, ny in tiles:
        out = subprocess.run(
            [sys.executable, "-c", _READY_CHILD, str(nx), str(ny)],
            capture_output=True,
            text=True,
            check=True,
            env=_child_env(),
        )
        r = json.loads(out.stdout.strip().splitlines()[-1])
        note = (
            f"{r['w']:.0f} x {r['h']:.0f} m, {r['poses']} poses; peak RSS {r['peak_rss_mb']:.0f} MB "
            f"(after imports {r['base_rss_mb']:.0f} MB)"
        )
        rows.append(Row(f"ready: {r['area']:.0f} m^2 ({nx}x{ny} labs)", r["cpu"], r["wall"], "s", note))
    return rows


def _workers_cpu(venv) -> float:
    """The CPU seconds so far of ``venv``'s worker processes (`agents.worker_vec_env.WorkersVecEnv`), 0 for an
    in-process vec env."""
    cpu = getattr(venv, "worker_cpu_seconds", None)
    return float(sum(cpu())) if cpu is not None else 0.0


def _env_clock(raw=None):
    """An SB3 callback that marks every rollout's end with the CPU and wall clocks of this process, the CPU of the
    VecEnv's worker processes (`agents.worker_vec_env.WorkersVecEnv`; 0 in one process) and the time spent in the
    VecEnv's ``step_wait`` so far: its `steady` gives a PPO run's rates from the first rollout's end to the last's
    (the same number of rollouts collected and trained on; the first rollout, with the workers' start, numba's and
    torch's first calls, left out), and the env's share of that time (same episodes, same actions). A SubprocVecEnv's
    workers are other processes, whose CPU time this process does not see. (SB3 is imported here, when the PPO
    benchmark runs.)

    ``raw``: ``(venv, rng)``, a second vec env of the same config: after each rollout's end the callback steps it for
    a rollout's worth of seeded random actions, timed on its own and left out of PPO's clocks, so that the raw rate
    is measured in the same minutes as PPO's (`steady`'s ``raw_*`` figures, over the rollouts PPO's cover)."""
    from stable_baselines3.common.callbacks import BaseCallback

    class EnvClock(BaseCallback):
        env_cpu = env_wall = 0.0
        paused_cpu = paused_wall = 0.0

        def _on_training_start(self) -> None:
            self.marks: list[tuple[float, ...]] = []
            self.raw_chunks: list[tuple[int, float, float]] = []
            env, orig = self.training_env, self.training_env.step_wait

            def timed():
                with Clock() as c:
                    out = orig()
                self.env_cpu += c.cpu
                self.env_wall += c.wall
                return out

            env.step_wait = timed  # an instance attribute: VecEnv.step calls it

        def _on_rollout_end(self) -> None:
            now = (
                time.process_time() - self.paused_cpu,
                time.perf_counter() - self.paused_wall,
                _workers_cpu(self.training_env),
                self.env_cpu,
                self.env_wall,
            )
            self.marks.append(now)
            if raw is not None:
                venv, rng = raw
                before = _workers_cpu(venv)
                with Clock() as c:
                    for _ in range(self.model.n_steps):
                        venv.step(rng.integers(0, 4, venv.num_envs))
                self.paused_cpu += c.cpu
                self.paused_wall += c.wall
                steps = self.model.n_steps * venv.num_envs
                self.raw_chunks.append((steps, c.cpu + _workers_cpu(venv) - before, c.wall))

        def _on_training_end(self) -> None:
            vars(self.training_env).pop("step_wait", None)  # the class's method again

        def _on_step(self) -> bool:
            return True

        def steady(self) -> dict[str, float]:
            """``steps``, ``cpu`` (this process's plus the workers'), ``wall``, ``env_cpu``, ``env_wall`` between
            the first and the last rollout's end (ValueError with fewer than two rollouts)."""
            if len(self.marks) < 2:
                raise ValueError(f"the PPO benchmark needs at least two rollouts (ppo_steps >= {2 * PPO_ROLLOUT})")
            (c0, w0, k0, e0, f0), (c1, w1, k1, e1, f1) = self.marks[0], self.marks[-1]
            steps = (len(self.marks) - 1) * self.model.n_steps * self.training_env.num_envs
            out = {"steps": steps, "cpu": c1 - c0 + k1 - k0, "wall": w1 - w0, "env_cpu": e1 - e0, "env_wall": f1 - f0}
            chunks = self.raw_chunks[: len(self.marks) - 1]  # those stepped between the first and the last mark
            if chunks:
                out.update(raw_steps=sum(c[0] for c in chunks), raw_cpu=sum(c[1] for c in chunks))
                out["raw_wall"] = sum(c[2] for c in chunks)
            return out

    return EnvClock()


def ppo_own_work(clock: dict[str, float]) -> tuple[float, float]:
    """``(PPO's own CPU seconds per env step, the env's)`` from `_env_clock`'s ``steady()``: what the run spent outside
    the vec env's ``step_wait`` (the policy's forward passes, the gradient steps, the callbacks), and inside it."""
    return (clock["cpu"] - clock["env_cpu"]) / clock["steps"], clock["env_cpu"] / clock["steps"]


def bench_ppo(args: Args) -> list[Row]:
    """PPO training steps/s vs raw steps/s of the same vec env (``agents.train``: BeliefObservation,
    metrics callback, rollout 1024 steps): DummyVecEnv x4, the batched env (SB3 adapter) x16, and the same 16
    robots in two worker processes (`agents.worker_vec_env.WorkersVecEnv`; its CPU figures add the workers' CPU
    to this process's, and its last row is the wall-clock gain over one process).

    Both rates leave out the start: PPO's covers the rollouts after the first (`_env_clock`), and the raw rate a second
    vec env of the same config stepped with seeded random actions for a rollout's worth of steps after each of those
    rollouts' ends (after one such warm-up before training), its time left out of PPO's: the two rates are measured
    in the same minutes, so a change in the machine's load moves both. The raw env's episodes still differ from PPO's
    (the belief's spread sets a step's cost); the env's share of the PPO run itself (its ``step_wait`` time, same
    episodes) isolates what PPO adds."""
    if args.quick:
        return []
    from agents.train import TrainConfig, make_venv, train

    rows, one_process_wall = [], None
    for vec_env, n_envs, workers in (("dummy", 4, 1), ("batched", 16, 1), ("batched", 16, 2)):
        cfg = TrainConfig(
            n_envs=n_envs, n_steps=PPO_ROLLOUT // n_envs, vec_env=vec_env, workers=workers,
            total_timesteps=args.ppo_steps, seed=args.seed, **({"env_id": args.env_id} if args.env_id else {}),
        )  # fmt: skip
        name = f"{vec_env} x{n_envs}" + (f" in {workers} workers" if workers > 1 else "")
        with _older_ids_quiet():
            venv = make_venv(cfg)
        try:
            venv.reset()
            rng = np.random.default_rng(args.seed)
            for _ in range(cfg.n_steps):  # warm-up, as PPO's first rollout
                venv.step(rng.integers(0, 4, n_envs))
            clock = _env_clock(raw=(venv, rng))
            with _older_ids_quiet():
                model = train(cfg, callbacks=[clock])
            model.get_env().close()
        finally:
            venv.close()
        ppo = clock.steady()
        raw_cpu, raw_wall = ppo["raw_steps"] / ppo["raw_cpu"], ppo["raw_steps"] / ppo["raw_wall"]
        ppo_cpu, ppo_wall = ppo["steps"] / ppo["cpu"], ppo["steps"] / ppo["wall"]
        rows += [
            Row(f"{name}: raw vec env", raw_cpu, raw_wall, "steps/s", "random actions, between PPO's rollouts"),
            Row(f"{name}: PPO training", ppo_cpu, ppo_wall, "steps/s", f"{ppo['steps']} steps after the first rollout"),
            Row("  PPO / raw", ppo_cpu / raw_cpu, ppo_wall / raw_wall, "x", "target >= 0.8"),
        ]
        if workers == 1:  # the workers' env time is wall time this process waits, not CPU it spends
            own, env_s = ppo_own_work(ppo)
            env_us = 1e6 * env_s
            rows += [
                Row(
                    "  env's share of the PPO run",
                    ppo["env_cpu"] / ppo["cpu"],
                    ppo["env_wall"] / ppo["wall"],
                    "x",
                    "PPO / env-only steps/s of the same episodes",
                ),
                Row(
                    "  PPO's own work per env step", own * 1e6, float("nan"), "us CPU",
                    f"forwards, gradient steps, callbacks; the env's {env_us:.0f} us: a share of 0.8 needs a quarter",
                ),
            ]  # fmt: skip
        if vec_env == "batched" and workers == 1:
            one_process_wall = ppo_wall
        elif one_process_wall is not None:
            rows.append(
                Row(
                    f"  PPO wall steps/s, {workers} workers / one process",
                    float("nan"),
                    ppo_wall / one_process_wall,
                    "x",
                    "the same 16 robots and episodes",
                )
            )
    return rows


def bench_mappers(args: Args) -> list[Row]:
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

    cpu, wall = _median_time(run, max(1, min(args.repeats, 5)))
    return [Row("mappers: lab-sized run", cpu, wall, "s", "1000 poses x 60 beams, 200 x 300 cells (was a < 3 s test)")]


BENCHMARKS: list[Callable[[Args], list[Row]]] = [
    bench_likelihood,
    bench_env,
    bench_filing,
    bench_belief,
    bench_batched,
    bench_batched_split,
    bench_robots_fused,
    bench_stages,
    bench_scaling,
    bench_reset,
    bench_mapping,
    bench_mappers,
    bench_ppo,
]


def print_table(rows: list[Row]) -> None:
    """The rows as a table: name, the CPU figure, the second figure (wall time's, or a share in % where the unit says
    ``... | %``), unit and note."""
    if not rows:
        print("(no rows: the benchmarks chosen measured nothing)")
        return
    w = max(len(r.name) for r in rows)
    print(f"{'':<{w}}  {'CPU':>12}  {'wall or %':>12}")
    for r in rows:
        wall = "" if r.wall != r.wall else f"{r.wall:12.3f}"
        cpu = f"{r.cpu:12.3g}" if abs(r.cpu) < 1e-3 and r.cpu else f"{r.cpu:12.3f}"
        cpu = "" if r.cpu != r.cpu else cpu  # a wall-only figure
        print(f"{r.name:<{w}}  {cpu:>12}  {wall:>12}  {r.unit:<20} {r.note}")


def run(args: Args) -> list[Row]:
    """Run the benchmarks ``args`` selects and print their table; returns the rows."""
    import os

    print(f"# semreloc bench: {args}")
    print(f"# {os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.2f} at start")
    wanted = set(args.only)
    rows: list[Row] = []
    for bench in BENCHMARKS:
        if wanted and bench.__name__.removeprefix("bench_") not in wanted:
            continue
        print(f"... {bench.__name__}", file=sys.stderr, flush=True)
        rows.extend(bench(args))
    print_table(rows)
    print(f"# load average {os.getloadavg()[0]:.2f} at the end")
    return rows


@command
def main(argv: list[str] | None = None) -> int:
    """The command: parse ``argv`` (default ``sys.argv[1:]``), run the benchmarks, print the table."""
    run(parse(Args, argv, __doc__))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
