"""A filter batched over robots, prototyped on the two kernels issue 8 names first: what one compiled call for all of
a batched step's robots saves against one call per robot.

The batched env (`semreloc_env.envs.batched.SemRelocLoopVectorEnv`) steps each robot's own relocalizer, so every
robot makes its own compiled calls. The issue sketched one filter for all robots instead, each kernel batched over
robots. This module measures that on real inputs, for the motion predict (`filters.motion.odometry._sample_kernel`)
and the likelihood weighing (`filters.localization.likelihood_field.log_likelihood_kernel`):

1. `record_calls` steps a batched env with seeded random actions and records the inputs of every call of the two
   kernels, by batched step;
2. `motion_fused` and `likelihood_fused` do the work of all of one step's calls in one compiled call: the robots'
   particles (and, for the weighing, their beams) one after another in flat arrays with per-robot offsets (a ragged
   batch, so no robot's set is padded to the largest);
3. `compare` checks that the fused calls give the per-robot calls' results bit for bit and times, over the recorded
   steps: one call per robot, one fused call per step on inputs already laid out flat (what a filter that kept its
   robots' arrays so would pay), and the fused call with the laying out (what the batched env would pay today).

`scripts/bench.py --only robots_fused` prints the figures; docs/performance.md has them. Nothing in the envs uses the
fused kernels.
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable
from dataclasses import dataclass

import numba
import numpy as np

from filters.localization.likelihood_field import _beam_cells, _gather_sum, log_likelihood_kernel
from filters.motion.odometry import _sample_kernel, move_particle

LIKELIHOOD, MOTION = "likelihood", "motion"


@dataclass(frozen=True)
class Recorded:
    """The compiled calls of a batched run (`record_calls`).

    Attributes:
        robot_steps: robot-steps recorded (``steps * num_envs``).
        calls: ``{LIKELIHOOD: groups, MOTION: groups}``: each group is the calls of one batched step (for the
            weighing: of one step that read the same tables), each call its kernel's argument tuple (input arrays
            copied; the likelihood tables, which are never written, shared).
    """

    robot_steps: int
    calls: dict[str, list[list[tuple]]]


def record_calls(num_envs: int = 64, steps: int = 40, seed: int = 0, env_id: str = "SemReloc-v22") -> Recorded:
    """Reset a batched env of ``num_envs`` ``env_id`` robots with ``seed``, step it 5 times (not recorded), then record
    the motion and likelihood kernel calls of ``steps`` more steps (seeded random actions, as
    `agents.tools.profile_step.batched_split`)."""
    from filters.localization import likelihood_field
    from filters.motion import odometry
    from semreloc_env.envs.batched import SemRelocLoopVectorEnv

    kernels = {LIKELIHOOD: (likelihood_field, "log_likelihood_kernel"), MOTION: (odometry, "_sample_kernel")}
    by_step: dict[str, dict[tuple, list[tuple]]] = {LIKELIHOOD: {}, MOTION: {}}
    step = [0]

    def recorder(name: str, kernel):
        def call(*args):
            kept = tuple(a.copy() if isinstance(a, np.ndarray) and a.flags.writeable else a for a in args)
            key = (step[0], id(args[9])) if name == LIKELIHOOD else (step[0],)  # args[9]: the tables read
            by_step[name].setdefault(key, []).append(kept)
            return kernel(*args)

        return call

    venv = SemRelocLoopVectorEnv(num_envs=num_envs, env_id=env_id)
    rng = np.random.default_rng(seed)
    originals = {name: getattr(module, attr) for name, (module, attr) in kernels.items()}
    try:
        venv.reset(seed=seed)
        for _ in range(5):
            venv.step(rng.integers(0, 4, num_envs))
        for name, (module, attr) in kernels.items():
            setattr(module, attr, recorder(name, originals[name]))
        for step[0] in range(steps):
            venv.step(rng.integers(0, 4, num_envs))
    finally:
        for name, (module, attr) in kernels.items():
            setattr(module, attr, originals[name])
        venv.close()
    return Recorded(steps * num_envs, {name: list(groups.values()) for name, groups in by_step.items()})


@numba.njit(nogil=True)
def motion_fused(p, starts, params, noise, out):  # pragma: no cover - compiled
    """`filters.motion.odometry._sample_kernel` for several robots in one call: robot ``r``'s particles are
    ``p[starts[r]:starts[r + 1]]``, its ``(rot1, trans, rot2, std rot1, std trans, std rot2)`` ``params[r]`` and its
    draws ``noise[:, starts[r]:starts[r + 1]]``. Not cached: numba's cache would not see a change to the other
    file's `move_particle` it inlines."""
    for r in range(starts.shape[0] - 1):
        rot1, trans, rot2 = params[r, 0], params[r, 1], params[r, 2]
        s_r1, s_t, s_r2 = params[r, 3], params[r, 4], params[r, 5]
        for i in range(starts[r], starts[r + 1]):
            move_particle(p, i, rot1, trans, rot2, s_r1, s_t, s_r2, noise, out)


@numba.njit(nogil=True)
def likelihood_fused(
    x, y, cos_t, sin_t, p_starts, lu, lv, offset, outside, b_starts, n_lidar, flat, ox, oy, inv_res, w, h, out_l, out_s
):  # pragma: no cover - compiled
    """`filters.localization.likelihood_field.log_likelihood_kernel` for several robots in one call: robot ``r``'s
    particles are ``p_starts[r]:p_starts[r + 1]`` of ``x, y, cos_t, sin_t, out_l, out_s``, its beams
    ``b_starts[r]:b_starts[r + 1]`` of ``lu, lv, offset, outside``, the first ``n_lidar[r]`` of them lidar. Not
    cached: numba's cache would not see a change to the other file's `_beam_cells` and `_gather_sum` it inlines."""
    idx = np.empty(lu.shape[0], np.int64)
    acc = np.empty(16)
    for r in range(p_starts.shape[0] - 1):
        b0, b1 = b_starts[r], b_starts[r + 1]
        nb = b1 - b0
        lu_r, lv_r, off_r, out_r, idx_r = lu[b0:b1], lv[b0:b1], offset[b0:b1], outside[b0:b1], idx[:nb]
        for i in range(p_starts[r], p_starts[r + 1]):
            pu, pv = (x[i] - ox) * inv_res, (y[i] - oy) * inv_res
            _beam_cells(pu, pv, cos_t[i], sin_t[i], lu_r, lv_r, off_r, out_r, w, h, idx_r)
            out_l[i] = _gather_sum(flat, idx_r, 0, n_lidar[r], acc)
            out_s[i] = _gather_sum(flat, idx_r, n_lidar[r], nb, acc)


def _starts(sizes) -> np.ndarray:
    return np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)


def motion_inputs(group: list[tuple]) -> tuple:
    """`motion_fused`'s arguments for one step's `_sample_kernel` calls ``group`` (their outputs laid out flat)."""
    p = np.concatenate([a[0] for a in group])
    params = np.array([a[1:7] for a in group], dtype=np.float64)
    return p, _starts([a[0].shape[0] for a in group]), params, np.concatenate([a[7] for a in group], axis=1), \
        np.empty_like(p)  # fmt: skip


def likelihood_inputs(group: list[tuple]) -> tuple:
    """`likelihood_fused`'s arguments for one step's `log_likelihood_kernel` calls ``group`` (which read the same
    tables, with the same map geometry)."""
    first = group[0]
    flat_in = [np.concatenate([a[k] for a in group]) for k in range(4)]
    beams = [np.concatenate([a[k] for a in group]) for k in range(4, 8)]
    n = flat_in[0].shape[0]
    return (
        *flat_in, _starts([a[0].shape[0] for a in group]), *beams, _starts([a[4].shape[0] for a in group]),
        np.array([a[8] for a in group], dtype=np.int64), *first[9:15], np.zeros(n), np.zeros(n),
    )  # fmt: skip


@dataclass(frozen=True)
class _Kernel:
    """How one kernel is called alone and fused: ``per_robot(*call)`` with a recorded ``call`` (its first ``n_in``
    arguments inputs, the rest outputs); ``fused(*inputs(group))``, whose arguments ``starts`` and ``outputs`` are the
    robots' particle offsets and the outputs."""

    per_robot: Callable
    n_in: int
    fused: Callable
    inputs: Callable[[list[tuple]], tuple]
    starts: int
    outputs: tuple[int, ...]


_KERNELS = {
    MOTION: _Kernel(_sample_kernel, 8, motion_fused, motion_inputs, 1, (4,)),
    LIKELIHOOD: _Kernel(log_likelihood_kernel, 15, likelihood_fused, likelihood_inputs, 4, (-2, -1)),
}


def _fused_outputs(name: str, group: list[tuple]) -> tuple[tuple, list[tuple[np.ndarray, ...]]]:
    """The fused call's arguments for ``group`` and, after running it, each robot's slice of its outputs."""
    k = _KERNELS[name]
    args = k.inputs(group)
    k.fused(*args)
    s = args[k.starts]
    return args, [tuple(args[j][s[r] : s[r + 1]] for j in k.outputs) for r in range(len(group))]


def _per_robot_outputs(name: str, group: list[tuple]) -> list[tuple[np.ndarray, ...]]:
    """Run each of ``group``'s calls with its own kernel into copies of its outputs (which the kernels overwrite
    whole); returns them."""
    k = _KERNELS[name]
    outs = []
    for a in group:
        out = tuple(o.copy() for o in a[k.n_in :])
        k.per_robot(*a[: k.n_in], *out)
        outs.append(out)
    return outs


@dataclass(frozen=True)
class FusedTimes:
    """One kernel's figures from `compare`, in CPU microseconds per recorded robot-step (medians over the repeats).

    Attributes:
        calls: the per-robot calls recorded.
        groups: the fused calls that replace them (one per batched step, for the weighing one per step and tables).
        per_robot_us: the calls as the env makes them, one per robot.
        fused_us: one fused call per group, its inputs already laid out flat.
        fused_laid_out_us: the same with the laying out (copying each robot's arrays into the flat ones).
        same_bits: every fused result equals the per-robot call's, bit for bit.
    """

    calls: int
    groups: int
    per_robot_us: float
    fused_us: float
    fused_laid_out_us: float
    same_bits: bool


def compare(recorded: Recorded, repeats: int = 15) -> dict[str, FusedTimes]:
    """`FusedTimes` of each kernel of ``recorded`` that was called (a kernel never called is left out): the three ways
    timed in turn, ``repeats`` rounds over all the recorded steps (after one untimed round, which also compiles)."""
    return {
        name: _compared(name, groups, recorded.robot_steps, repeats)
        for name, groups in recorded.calls.items()
        if groups
    }


def _compared(name: str, groups: list[list[tuple]], robot_steps: int, repeats: int) -> FusedTimes:
    """`compare` of one kernel's call ``groups``."""
    same = True
    laid_out = []
    for g in groups:
        args, fused = _fused_outputs(name, g)
        laid_out.append(args)
        for mine, theirs in zip(fused, _per_robot_outputs(name, g), strict=True):
            same &= all(np.array_equal(a, b) for a, b in zip(mine, theirs, strict=True))
    calls = [a for g in groups for a in g]
    k = _KERNELS[name]

    def per_robot():  # into the recorded calls' own outputs
        for a in calls:
            k.per_robot(*a)

    def fused():
        for args in laid_out:
            k.fused(*args)

    def fused_laid_out():
        for g in groups:
            k.fused(*k.inputs(g))

    ways = (per_robot, fused, fused_laid_out)
    times: list[list[float]] = [[] for _ in ways]
    for fn in ways:
        fn()
    for _ in range(repeats):
        for fn, t in zip(ways, times):
            t0 = time.process_time()
            fn()
            t.append(time.process_time() - t0)
    us = [1e6 * statistics.median(t) / robot_steps for t in times]
    return FusedTimes(len(calls), len(groups), *us, same_bits=bool(same))
