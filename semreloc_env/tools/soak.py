"""Long random soak of the envs: random layouts, settings and actions, every step checked.

Usage (``semreloc-soak`` is the same command)::

    python scripts/soak.py                 # 10^6 steps of SemReloc-v22 and SemSlam-v2
    python scripts/soak.py --steps 20000   # a short run
    python scripts/soak.py --env-ids SemReloc-v1 SemSlam-v0   # older ids (the soak's only ones before)
    python scripts/soak.py --layouts 10000 # layouts only: validate, mutate, build

Per step it checks: no exception, the observation inside its space, no NaN in the observation,
reward or info, the robot's clearance from every wall and object at least its radius (minus
1e-6 m). Between episodes it mutates a valid layout into an invalid one (must raise a
``LayoutError`` naming the entry), makes a rejected call (bad action, bad reset options or
seed: must raise ``ValueError``) and, every ``--twin-every`` episodes, runs a twin env beside the
one that saw the rejected call (their next steps must be bit-identical). It prints the count
of each check and of each failure; the exit status is 1 if anything failed.

Settings are drawn per episode: robot, physics, lidar and camera for every id; for ``SemReloc-*`` a global,
tracking or tracking-then-kidnapped start (`reset_options`); the SLAM filter's
for ``SemSlam-*``; for ``SemReloc-v2`` and newer the relocalizer's particle counts, proposals, audit
candidates, resampling, injection and backend, and a mapping-run map (``map_source="mapping"``) in
one episode of six (its maps go to a temporary on-disk cache, removed at the end, so a soak leaves
nothing in the user's cache).

Memory: the process's resident size is read at the end of each episode (Linux ``/proc``); the run
fails (``FAIL_memory_growth``) if the median of its last tenth of steps exceeds the median of the
tenth after its first quarter (the warm-up: compiled kernels, caches filling) by more than
``--memory-growth-mb``. Elsewhere the check is skipped and says so.
"""

from __future__ import annotations

import copy
import math
import os
import sys
import tempfile
import time
import traceback
from collections import Counter
from dataclasses import dataclass
from unittest import mock

import gymnasium as gym
import numpy as np

import semreloc_env
from filters.experiments.cli import command, parse
from semreloc_env.layouts import CLASS_NAMES, LayoutError, layout_from_dict

CELL = 2.0
SOAK_ENV_IDS = ("SemReloc-v22", "SemSlam-v2")
"""The ids a soak runs unless told otherwise: the newest."""


def random_layout(rng: np.random.Generator) -> dict:
    """A valid layout by construction (the same construction as tests/test_properties.py draws with
    Hypothesis): cells, walls on cell lines, one polygon strictly inside each chosen cell."""
    nx, ny = int(rng.integers(2, 7)), int(rng.integers(2, 6))
    w, h = nx * CELL, ny * CELL
    cut = set()
    outer = [[0.0, 0.0], [w, 0.0], [w, h], [0.0, h]]
    if nx >= 3 and ny >= 3 and rng.random() < 0.5:
        cx, cy = int(rng.integers(2, nx)), int(rng.integers(2, ny))
        outer = [[0.0, 0.0], [w, 0.0], [w, cy * CELL], [cx * CELL, cy * CELL], [cx * CELL, h], [0.0, h]]
        cut = {(i, j) for i in range(cx, nx) for j in range(cy, ny)}
    cells = [(i, j) for i in range(nx) for j in range(ny) if (i, j) not in cut]
    walls = []
    for _ in range(int(rng.integers(0, 4))):
        i, j = cells[int(rng.integers(len(cells)))]
        if i >= 1 and (i - 1, j) in cells:
            walls.append([[i * CELL, j * CELL], [i * CELL, (j + float(rng.uniform(0.2, 0.8))) * CELL]])
    objects = []
    for idx in rng.permutation(len(cells))[: int(rng.integers(0, 7))]:
        i, j = cells[idx]
        n = int(rng.integers(3, 7))
        radius, phase = float(rng.uniform(0.1, 0.45)), float(rng.uniform(0, 2 * math.pi))
        ang = phase + 2 * math.pi * np.arange(n) / n
        c = ((i + 0.5) * CELL, (j + 0.5) * CELL)
        poly = [[c[0] + radius * math.cos(a), c[1] + radius * math.sin(a)] for a in ang]
        objects.append({"class": str(rng.choice(CLASS_NAMES)), "polygon": poly, "name": f"o{i}_{j}"})
    return {"name": "soak", "outer": outer, "walls": walls, "objects": objects}


def mutate(data: dict, rng: np.random.Generator) -> tuple[dict, str, str]:
    """``(invalid copy, entry the error must name, what was done)``."""
    d = copy.deepcopy(data)
    kinds = ["outer_str", "outer_nan", "unknown_key"]
    if d["objects"]:
        kinds += ["obj_out", "obj_overlap", "obj_wall", "obj_class", "obj_inf", "obj_bool"]
    kind = kinds[int(rng.integers(len(kinds)))]
    k = int(rng.integers(len(d["objects"]))) if d["objects"] else 0
    if kind == "outer_str":
        d["outer"][1][0] = str(d["outer"][1][0])
        return d, "outer", kind
    if kind == "outer_nan":
        d["outer"][2][1] = math.nan
        return d, "outer", kind
    if kind == "unknown_key":
        d["furniture"] = []
        return d, "furniture", kind
    obj = d["objects"][k]
    if kind == "obj_out":
        obj["polygon"] = [[x + 1000.0, y] for x, y in obj["polygon"]]
    elif kind == "obj_overlap":
        twin = copy.deepcopy(obj)
        twin["polygon"] = [[x + float(rng.uniform(0.01, 0.1)), y] for x, y in twin["polygon"]]
        twin["name"] = "twin"
        d["objects"].append(twin)
        return d, "(twin)", kind
    elif kind == "obj_wall":
        c = np.mean(obj["polygon"], axis=0)
        d["walls"].append([[c[0] - 0.6, c[1]], [c[0] + 0.6, c[1]]])
        return d, f"walls[{len(d['walls']) - 1}]", kind
    elif kind == "obj_class":
        obj["class"] = "sofa"
    elif kind == "obj_inf":
        obj["polygon"][0][1] = math.inf
    else:
        obj["polygon"][0][0] = True
    return d, f"objects[{k}]", kind


def check_mutation(data: dict, rng: np.random.Generator, c: Counter) -> None:
    """Mutate the valid layout ``data`` into an invalid one (`mutate`) and count in ``c`` whether
    ``layout_from_dict`` rejects it (``FAIL_mutation_accepted``) naming the entry (``FAIL_mutation_unnamed``)."""
    bad, entry, what = mutate(data, rng)
    c["mutations"] += 1
    try:
        layout_from_dict(bad)
        c["FAIL_mutation_accepted"] += 1
        print(f"mutation {what} accepted", file=sys.stderr)
    except LayoutError as e:
        c["FAIL_mutation_unnamed"] += entry not in str(e)


def _common_settings(rng: np.random.Generator) -> dict:
    """Random (valid) robot, physics, lidar and camera settings, shared by every env id."""
    radius = float(rng.uniform(0.1, 0.3))
    return {
        "action_type": "continuous" if rng.random() < 0.5 else "discrete",
        "robot": {"radius_m": radius, "max_linear_mps": float(rng.uniform(0.2, 1.0))},
        "physics": {"substeps": int(rng.integers(3, 9)), "control_hz": float(rng.uniform(8.0, 20.0))},
        "lidar": {
            "n_beams": int(rng.integers(1, 120)),
            "fov_rad": float(rng.uniform(0.5, 2 * math.pi)),
            "noise_std_m": float(rng.uniform(0.0, 0.05)),
            "dropout_prob": float(rng.uniform(0.0, 0.2)),
        },
        "camera": {"n_beams": int(rng.integers(1, 64)), "miss_rate": float(rng.uniform(0.0, 0.5))},
    }


def _relocalizer_settings(rng: np.random.Generator) -> dict:
    """Random (valid) overrides of a ``SemReloc-v2``-or-newer relocalizer, small enough for a soak:
    adaptive (KLD) or fixed particle counts, proposal and audit candidates, resampling, injection,
    backend, whether a still step draws its motion noise."""
    low = int(rng.integers(20, 300))
    kw = {
        "min_particles": low,
        "max_particles": low + int(rng.integers(0, 3000)),
        "global_particles_per_m2": float(rng.uniform(1.0, 20.0)),
        "proposal_candidates": int(rng.integers(1, 500)),
        "audit_candidates": int(rng.integers(1, 500)),
        "audit_candidates_per_m2": float(rng.uniform(0.0, 14.0)),
        "resample_mode": ["global", "clustered"][int(rng.integers(2))],
        "injection": ["uniform", "scan"][int(rng.integers(2))],
        "backend": ["numba", "numpy"][int(rng.integers(2))],
        "kld": bool(rng.random() < 0.8),
        "lidar_on_rotation": bool(rng.random() < 0.2),
        "predict_when_still": bool(rng.random() < 0.5),
        "proposal_candidates_per_particle": float(rng.uniform(1.0, 30.0)),
    }
    if rng.random() < 0.3:
        kw["n_particles"] = int(rng.integers(20, 400))
    return kw


def random_settings(rng: np.random.Generator, env_ids: tuple[str, ...] = SOAK_ENV_IDS) -> tuple[str, dict]:
    """One of ``env_ids`` (drawn uniformly) and random (valid) keyword arguments for it."""
    kw = _common_settings(rng)
    env_id = env_ids[int(rng.integers(len(env_ids)))] if len(env_ids) > 1 else env_ids[0]
    if env_id.startswith("SemSlam-"):
        slam = {"n_particles": int(rng.integers(1, 30))}
        if env_id != "SemSlam-v0":
            slam |= {
                "version": int(rng.integers(1, 3)),
                "woc_k": [1.0, 2.0, 5.0, math.inf][int(rng.integers(4))],
                "known_association": bool(rng.random() < 0.3),
                "resample_ess_fraction": float(rng.uniform(0.3, 1.0)),
            }
        return env_id, {**kw, "slam": slam}
    version = int(env_id.rsplit("v", 1)[1])
    mapped = version >= 2 and rng.random() < 1 / 6
    relocalizer = _relocalizer_settings(rng) if version >= 2 else {"n_particles": int(rng.integers(20, 300))}
    return env_id, {
        **kw,
        "map_source": "mapping" if mapped else "perfect",
        "semantic": bool(rng.random() < 0.7),
        "relocalizer": relocalizer,
    }


def reset_options(rng: np.random.Generator, env_id: str, max_steps: int) -> dict:
    """How a ``SemReloc-*`` episode starts, drawn: a global start (a third), a tracking start (a third) or a
    tracking start kidnapped to a random free pose at a step within the time limit; ``"kind"`` names it (the
    rest are the reset's options). ``SemSlam-*`` episodes start as they do (``{}``, no kind)."""
    if not env_id.startswith("SemReloc-"):
        return {}
    kind = ["global", "tracking", "kidnap"][int(rng.integers(3))]
    if kind == "global":
        return {"kind": kind}
    out = {"kind": kind, "tracking": True}
    if kind == "kidnap":
        out["kidnap_at_step"] = int(rng.integers(1, max_steps + 1))
    return out


def resident_mb() -> float | None:
    """This process's resident set size in MB (Linux ``/proc/self/statm``), or None where unreadable."""
    try:
        with open("/proc/self/statm") as f:
            pages = int(f.read().split()[1])
    except (OSError, ValueError, IndexError):
        return None
    return pages * os.sysconf("SC_PAGE_SIZE") / 1e6


def memory_growth_mb(samples: list[tuple[int, float]], steps: int) -> float | None:
    """Median resident MB of the samples ``(step, MB)`` in the last tenth of ``steps`` minus the
    median of those in the tenth after the first quarter; None if either window holds no sample."""

    def median_in(lo: float, hi: float) -> float | None:
        v = [mb for k, mb in samples if lo <= k <= hi]
        return float(np.median(v)) if v else None

    early = median_in(0.25 * steps, 0.35 * steps)
    late = median_in(0.9 * steps, math.inf)
    return None if early is None or late is None else late - early


def all_finite(x) -> bool:
    """No NaN in any number of an observation or info, nested dicts / lists / arrays included (None
    stands for 'not computed' and passes; so does inf, which the spaces' bounds check)."""
    if isinstance(x, dict):
        return all(all_finite(v) for v in x.values())
    if isinstance(x, (list, tuple)):
        return all(all_finite(v) for v in x)
    if isinstance(x, np.ndarray):
        return x.dtype.kind not in "fc" or not np.isnan(x).any()
    if isinstance(x, float):
        return not math.isnan(x)
    return True


def _action(env, rng):
    if isinstance(env.action_space, gym.spaces.Discrete):
        return int(rng.integers(0, env.action_space.n))
    return rng.uniform(-1, 1, 2).astype(np.float32)


BAD_CALLS = [
    ("bad_action", lambda env: env.step(99 if isinstance(env.action_space, gym.spaces.Discrete) else [2.0, 0.0])),
    ("bad_pose", lambda env: env.reset(options={"pose": [-50.0, -50.0, 0.0]})),
    ("bad_option", lambda env: env.reset(options={"nope": 1})),
    ("bad_seed", lambda env: env.reset(seed=-1)),
]


def _same(a, b) -> bool:
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, (list, tuple)):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    if isinstance(a, np.ndarray):
        return np.array_equal(a, b)
    return a == b


FAILURES = (
    "FAIL_crash",
    "FAIL_obs_outside_space",
    "FAIL_nan",
    "FAIL_inside_obstacle",
    "FAIL_mutation_accepted",
    "FAIL_mutation_unnamed",
    "FAIL_bad_call_accepted",
    "FAIL_twin_diverged",
    "FAIL_not_ended",
    "FAIL_memory_growth",
)


def soak(
    steps: int,
    seed: int,
    episode_steps: int,
    twin_every: int,
    env_ids: tuple[str, ...] = SOAK_ENV_IDS,
    growth_limit_mb: float = math.inf,
) -> Counter:
    """Run ``steps`` checked env steps (see the module's docstring); the counts of every check and
    failure. ``growth_limit_mb``: resident growth that counts as ``FAIL_memory_growth``."""
    rng = np.random.default_rng(seed)
    c: Counter = Counter({k: 0 for k in FAILURES})
    memory: list[tuple[int, float]] = []
    t0, last = time.perf_counter(), time.perf_counter()
    while c["steps"] < steps:
        c["episodes"] += 1
        kind = rng.random()
        if kind < 0.6:
            data = random_layout(rng)
            layout = layout_from_dict(data)
            check_mutation(data, rng, c)
            layout_kw = {"layout": layout}
        else:
            name = ["procedural", "procedural_sym", "lab", "twin_rooms"][int(rng.integers(4))]
            layout_seed = int(rng.integers(0, 10**6))  # drawn for every name, so the stream stays as it was
            layout_kw = {"layout": name, **({"layout_seed": layout_seed} if name.startswith("procedural") else {})}
        c["layouts"] += 1
        env_id, kw = random_settings(rng, env_ids)
        c["mapping_runs"] += kw.get("map_source") == "mapping"
        ep_seed = int(rng.integers(0, 2**31 - 1))
        max_steps = int(rng.integers(5, episode_steps + 1))
        start = reset_options(rng, env_id, max_steps)
        if "kind" in start:
            c[f"starts_{start['kind']}"] += 1
        options = {k: v for k, v in start.items() if k != "kind"} or None
        try:
            env = gym.make(env_id, max_episode_steps=max_steps, **layout_kw, **kw)
            twin = (
                gym.make(env_id, max_episode_steps=max_steps, **layout_kw, **kw)
                if c["episodes"] % twin_every == 0
                else None
            )
            obs, info = env.reset(seed=ep_seed, options=options)
            if twin is not None:
                twin.reset(seed=ep_seed, options=options)
            world = env.unwrapped.world
            r = world.robot_params.radius_m
            bad_at = int(rng.integers(0, max_steps))
            for k in range(max_steps):
                if k == bad_at:
                    label, call = BAD_CALLS[int(rng.integers(len(BAD_CALLS)))]
                    c["rejected_calls"] += 1
                    try:
                        call(env)
                        c["FAIL_bad_call_accepted"] += 1
                        print(f"{label} accepted", file=sys.stderr)
                    except ValueError:
                        pass
                act = _action(env, rng)
                out = env.step(act)
                obs, reward, term, trunc, info = out
                c["steps"] += 1
                if twin is not None:
                    c["twin_steps"] += 1
                    c["FAIL_twin_diverged"] += not _same(out, twin.step(act))
                c["FAIL_obs_outside_space"] += not env.observation_space.contains(obs)
                c["FAIL_nan"] += not (all_finite(obs) and all_finite(info) and math.isfinite(reward))
                gap = world.clearance(world.pose[:2]) - r
                c["FAIL_inside_obstacle"] += gap < -1e-6
                c["min_clearance_minus_radius_nm"] = min(c.get("min_clearance_minus_radius_nm", 10**9), int(gap * 1e9))
                c["collided_steps"] += bool(info["collided"])
                if term or trunc:
                    c["terminated" if term else "truncated"] += 1
                    break
            c["FAIL_not_ended"] += not (term or trunc)
            env.close()
        except Exception:
            c["FAIL_crash"] += 1
            print(
                f"crash: {env_id} {layout_kw.get('layout') if isinstance(layout_kw.get('layout'), str) else ''}",
                file=sys.stderr,
            )
            traceback.print_exc()
        mb = resident_mb()
        if mb is not None:
            memory.append((c["steps"], mb))
        if time.perf_counter() - last > 30:
            last = time.perf_counter()
            rate = c["steps"] / (last - t0)
            rss = f", {memory[-1][1]:.0f} MB resident" if memory else ""
            print(
                f"... {c['steps']} steps, {c['episodes']} episodes, {rate:.0f} steps/s{rss}",
                file=sys.stderr,
                flush=True,
            )
    c["seconds"] = int(time.perf_counter() - t0)
    growth = memory_growth_mb(memory, c["steps"])
    if growth is None:
        c["memory_check_skipped"] = 1
    else:
        c["resident_mb_at_end"] = int(round(memory[-1][1]))
        c["resident_growth_mb"] = int(round(growth))
        c["FAIL_memory_growth"] += growth > growth_limit_mb
    return c


def soak_layouts(n: int, seed: int) -> Counter:
    """Validate ``n`` random layouts (half generated here, half procedural), one mutation of each
    generated one, and build each one's world, a free start pose and its perfect map."""
    from semreloc_env.layouts import get_layout
    from semreloc_env.rasterize import rasterize
    from semreloc_env.world import build_world

    rng = np.random.default_rng(seed)
    c: Counter = Counter({k: 0 for k in ("FAIL_crash", "FAIL_mutation_accepted", "FAIL_mutation_unnamed")})
    t0 = time.perf_counter()
    for i in range(n):
        try:
            if i % 2 == 0:
                data = random_layout(rng)
                layout = layout_from_dict(data)
                check_mutation(data, rng, c)
            else:
                layout = get_layout(["procedural", "procedural_sym"][i % 4 // 2], seed=int(rng.integers(0, 10**9)))
            world = build_world(layout)
            world.set_pose(world.sample_free_pose(rng))
            rasterize(layout)
            c["layouts"] += 1
        except Exception:
            c["FAIL_crash"] += 1
            traceback.print_exc()
    c["seconds"] = int(time.perf_counter() - t0)
    return c


@dataclass(frozen=True)
class Args:
    """Long random soak of the envs: random layouts, settings and actions, every step checked."""

    steps: int = 1_000_000
    """env steps in all"""
    seed: int = 0
    """seed of layouts, settings, actions and the env id of each episode"""
    env_ids: tuple[str, ...] = SOAK_ENV_IDS
    """registered single-robot ids to soak (each episode draws one)"""
    memory_growth_mb: float = 300.0
    """resident growth (MB, after the warm-up) that fails the run"""
    episode_steps: int = 200
    """longest episode (time limit drawn up to this)"""
    twin_every: int = 10
    """run a twin env in every k-th episode"""
    layouts: int = 0
    """instead of stepping: validate and build this many layouts"""

    def __post_init__(self) -> None:
        if self.steps < 1 or self.episode_steps < 5 or self.twin_every < 1 or self.layouts < 0:
            raise ValueError("steps >= 1, episode_steps >= 5, twin_every >= 1 and layouts >= 0 are required")
        unknown = [i for i in self.env_ids if i not in semreloc_env.ENV_IDS]
        if unknown or not self.env_ids:
            raise ValueError(
                f"env_ids must name registered single-robot ids {semreloc_env.ENV_IDS}, got {unknown or '()'}"
            )
        if len(set(self.env_ids)) != len(self.env_ids):
            raise ValueError(f"env_ids lists an id twice: {self.env_ids}")
        if not self.memory_growth_mb > 0:
            raise ValueError(f"memory_growth_mb must be > 0 (inf: no limit), got {self.memory_growth_mb}")


@command
def main(argv: list[str] | None = None) -> int:
    """The command: parse ``argv``, soak, print every count; exit status 1 if any check failed."""
    a = parse(Args, argv, __doc__)
    if a.layouts:
        c = soak_layouts(a.layouts, a.seed)
    else:
        # mapped maps of random layouts go to a temporary cache, not the user's
        with (
            tempfile.TemporaryDirectory(prefix="semreloc-soak-") as cache,
            mock.patch.dict(os.environ, {"SEMRELOC_CACHE_DIR": cache}),
        ):
            c = soak(a.steps, a.seed, a.episode_steps, a.twin_every, a.env_ids, a.memory_growth_mb)
    fails = {k: v for k, v in c.items() if k.startswith("FAIL_")}
    for k in sorted(c, key=lambda k: (k.startswith("FAIL_"), k)):
        print(f"{k:<34} {c[k]}")
    bad = sum(fails.values())
    print("RESULT", "ok: no failure" if bad == 0 else f"{bad} failures")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
