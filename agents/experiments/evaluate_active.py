"""Evaluate active-relocalization policies on the same held-out (layout, start) pairs.

Layouts: the first ``--layouts-per-kind`` held-out seeds
(`semreloc_env.layout_sampling.HELD_OUT_LAYOUT_SEEDS`, never drawn for training) of
``procedural``, ``procedural_sym`` and ``procedural_lookalike``, then ``twin_rooms``, ``lab``,
the changed lab (``scenario="changed"``), the first ``--ring-layouts`` held-out seeds of
``procedural_ring`` and the first ``--corridor-layouts`` of ``procedural_corridor`` (none by default),
and every ``--layout-files`` entry. Each layout gets
``--starts`` start poses, drawn from a generator seeded by the layout's index and the start's;
every policy runs from the same start with the same episode seed (sensor noise and filter
draws), a global relocalization of at most ``--max-steps`` steps.

Starts "from which nothing telling is in sensor range": in a ``procedural_lookalike`` layout,
every other start is drawn inside a room where the exact all-round view (lidar to its range, the
semantic classes to the camera's) equals the view from the same place in another, identical
room; spinning in place cannot tell them apart, only moving out can; in a ``procedural_ring``
layout, every other start is one whose view equals that of a quarter-turned image of it; in a
``procedural_corridor`` layout, one whose view equals that of a shift of it along the corridor
(each where one is found in 300 draws; a random start otherwise). These are flagged
``uninformative`` and summarised on their own.

Per policy (overall, per layout kind, and on the uninformative starts): success within the
step limit (the env's own test, `agents.metrics`), wrong convergence (converged, wrong
place, at the end), unconverged, *first convergence wrong* (the belief first said "converged"
at a wrong pose, whatever it did after: a robot that stopped when its belief said so would have
stopped there; the env ends an episode only on a correct convergence), each with a Wilson 95 %
interval (``scipy.stats.binomtest(...).proportion_ci(method="wilson")``), median steps of the
successes, mean steps in collision per episode. Into ``--out``: ``episodes.json`` (one row per
episode, with the count of every discrete action taken, or with ``--action-type continuous`` of
every kind of motion, `motion_kind`), ``summary.json``, ``table.md`` and ``success.png`` (bar
plot with the intervals).

The same arguments give the same numbers whatever the runner (``--executor``, ``--workers``,
``--address``): every episode is seeded on its own and results are put back in job order.

    python scripts/evaluate_active.py --policies random spin wall_follow info_gain ppo=out/active/policy.zip \\
        --layouts-per-kind 10 --starts 10 --workers 2 --out out/evaluate_active

(``semreloc-evaluate-active`` is the same command; list options take space-separated values;
``--reuse A B`` keeps the rows of earlier runs' ``episodes.json`` for the policies they hold.)
"""

from __future__ import annotations

import ast
import functools
import hashlib
import importlib
import importlib.util
import json
import math
import os
import re
import sys
import time
import types
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np

from filters.experiments.cli import JsonDict, Runner, command, command_line, parse, usage_error
from filters.experiments.runner import RunnerConfig, run_jobs
from filters.experiments.stats import wilson_interval
from semreloc_env import semreloc_ids_since

EVALUATED_ENV_IDS = semreloc_ids_since(3)
"""The ids ``--env-id`` takes: ``SemReloc-v3`` and newer (typed observations, the look-alike generator of v3)."""
EvaluatedEnvId = Literal[EVALUATED_ENV_IDS]

DEFAULT_POLICIES = ("random", "spin", "spin_backup", "wall_follow", "info_gain")


@dataclass(frozen=True)
class Args:
    """Evaluate active-relocalization policies on the same held-out (layout, start) pairs."""

    policies: tuple[str, ...] = DEFAULT_POLICIES
    """names from agents.policies.POLICIES, NAME=PATH for a trained policy saved by
    agents.learned.save_policy or a checkpoint in a train_active run's checkpoints/ (loaded with
    agents.load_policy), or NAME=MODULE:CLASS /
    NAME=path/to/file.py:CLASS for your own: CLASS(seed) must give an object with wrap(env), reset() and
    act(obs), as agents.policies.Policy (--reuse tracks edits to the .py files of its folder, or of its
    top package); space-separated"""
    reuse: tuple[str, ...] = ()
    """folders of earlier runs with the same cases: their episodes.json rows are kept for the policies
    listed here, and only the other policies are run (a row is kept only if it was made with the same
    settings and the same code: `policy_code` and `env_code`; a layout file's rows also need the same file bytes)"""
    layouts_per_kind: int = 10
    """held-out seeds per procedural kind (procedural, procedural_sym, procedural_lookalike)"""
    ring_layouts: int = 0
    """held-out seeds of procedural_ring (a ring corridor whose four quarters look alike; its cases come
    after the built-in layouts', so those and the procedural cases keep their indices and episode seeds;
    --layout-files cases come after the ring cases, so they move)"""
    corridor_layouts: int = 0
    """held-out seeds of procedural_corridor (a long corridor whose furniture repeats at one period; its
    cases come after the ring cases, so every earlier case keeps its index and episode seed; --layout-files
    cases come after them)"""
    seed_set: Literal["held_out", "tuning"] = "held_out"
    """held_out: the held-out layout seeds plus twin_rooms and the lab (what results are reported
    on); tuning: procedural seeds 0, 1, ... of the training range and other starts, for choosing
    a policy's settings without touching the held-out cases"""
    starts: int = 10
    """start poses per layout"""
    noise_seed_offset: int = 0
    """added to every pair's episode seed: the same (layout, start) pairs under other sensor, odometry and filter
    noise (and other draws of a policy that draws), to tell what is a pair's from what is the draw's"""
    layout_files: tuple[str, ...] = ()
    """layout files (.json / .yaml) to add (a file's starts and episode seeds follow from its position in
    the case list: adding or reordering files gives the later files other starts, and --reuse then keeps
    none of their rows)"""
    max_steps: int = 200
    """steps per episode (success must come within them)"""
    action_type: Literal["discrete", "continuous"] = "discrete"
    """the env's actions: discrete (forward, left, right, stop) or continuous ((v, omega) in [-1, 1],
    scaled by the robot's maximum speeds; the baselines and learned policies send their discrete
    choices as such pairs, the viewpoint planner (and a learned policy's planner option) drives arcs)"""
    particles: int = 2000
    """relocalizer particles (``n_particles``: drawn at the reset and at most per KLD resampling; clustered
    resampling's floors and the audit can add to a set)"""
    env_id: EvaluatedEnvId = "SemReloc-v22"
    """the env the episodes run in: SemReloc-v22 (the newest), SemReloc-v21, SemReloc-v20, SemReloc-v19,
    SemReloc-v18, SemReloc-v17, SemReloc-v16, SemReloc-v15, SemReloc-v14, SemReloc-v13, SemReloc-v12, SemReloc-v11,
    SemReloc-v10, SemReloc-v9, SemReloc-v8, SemReloc-v7, SemReloc-v6, SemReloc-v5, SemReloc-v4 or SemReloc-v3 (to
    repeat the tables made with them; v21 differs from v22 only in its odometry and motion model, which take a step
    under 1 cm along the heading whatever its direction, and in KLD sampling's retry, which draws a second sequence;
    v20 differs from v21 only in drawing a still step's motion noise (and in a map-sized draw at a global start,
    twice v21's, which ``--particles`` replaces here); v19 differs from v20 only in the belief it reports between
    updates, its moved set summarised again; v18 differs from v19 in its odometry, which reads a slide along a wall,
    its KLD sampling, which allows a third of v19's error (more particles), and its remembered places, which stay
    put between updates; v17 differs from v18 only in its audit after a hold lost without a surprise, v16 from v17
    only in its tracking start, v15 from v16 only in its audit after a lost hold and v14 from v15 only in its audit
    after a surprise, both in tracking episodes only, v13 and v12 also in their relocalizer's surprise tests, which
    no global start meets before its first convergence; the same worlds and sensors, the maps of the mapping run's
    version 5, whose drive skips passages between its lattice's rows and columns (v11), also with space beyond the
    lidar's returns left unknown (v10), the maps of the mapping run's version 3, with stray class cells, and the
    screen's pause blind to place (v9), the relocalizer's audit without its screen of the whole map (v8 and older),
    the maps of the mapping run's version 2 (v7 and older), the relocalizer with the audit's coarse-to-fine search
    only (v6), also without the hold of a convergence (v5), without the convergence audit (v4) and without negative
    evidence (v3))"""
    relocalizer: JsonDict = field(default_factory=dict)
    """relocalizer overrides (`MCLConfig` fields) on top of the env's defaults, one JSON object, e.g.
    '{"negative_evidence": {"p_detect": 0.5}}'; --particles sets n_particles"""
    map_source: str = "mapping"
    """the filter's map: mapping (a simulated mapping run of each case's layout), perfect (the layout
    rasterised), or one map for every case: a layout (a built-in name or a layout file; its mapping
    run) or a ROS map (.yaml with its image, and a .semantic.yaml sidecar for the semantic factor);
    the worlds of --layout-files (alone: --layouts-per-kind 0 --no-builtin-layouts) may then differ
    from it, objects moved, missing or added"""
    builtin_layouts: bool = True
    """with the held-out seed set: also twin_rooms, the lab and the changed lab (--no-builtin-layouts:
    only the procedural held-out layouts and --layout-files)"""
    gif_case: int = -1
    """if >= 0: also write gif_<policy>.gif of every policy on this case (index into the cases, in this
    order, --starts per layout: the procedural kinds' layouts, twin_rooms, lab, lab changed, the ring
    layouts, the corridor layouts, then the layout files; episodes.json lists every case with its index)"""
    sample_learned: bool = False
    """learned policies sample their actions (seeded by the episode) instead of taking the most likely"""
    out: str = "out/evaluate_active"
    """output folder"""
    runner: Runner = RunnerConfig(workers=2)

    GENERATED = ("layouts_per_kind", "ring_layouts", "corridor_layouts")
    """The fields that count generated layouts (held-out or tuning seeds)."""

    def generates(self) -> bool:
        """Whether any generated layout is asked for (`GENERATED`)."""
        return any(getattr(self, name) for name in self.GENERATED)

    def _check_map_source(self) -> None:
        """A map layout must fit every case's world (checked here, with its mapping run, not in a worker)."""
        if self.map_source in ("mapping", "perfect"):
            return
        from semreloc_env.config import CameraParams, LidarParams
        from semreloc_env.layouts import LayoutError, get_layout
        from semreloc_env.maps import check_map_source_name, maps_for

        check_map_source_name(self.map_source)
        if self.generates() or self.builtin_layouts or not self.layout_files:
            raise ValueError(
                "map_source: one map for every case needs worlds that fit it: --layout-files alone "
                "(--layouts-per-kind 0 --no-builtin-layouts)"
            )
        semantic = self.relocalizer.get("use_semantic", True) if isinstance(self.relocalizer, dict) else True
        from semreloc_env import semreloc_class

        version = semreloc_class(self.env_id).mapping_run_version
        for f in self.layout_files:
            try:
                maps_for(get_layout(f), self.map_source, LidarParams(), CameraParams(), semantic, version)
            except (LayoutError, ValueError, OSError) as e:  # MapFormatError is a ValueError
                hint = " (lidar only: --relocalizer '{\"use_semantic\": false}')" if semantic else ""
                raise ValueError(f"map_source {self.map_source!r} for layout file {f!r}: {e}{hint}") from None

    def relocalizer_overrides(self) -> dict:
        """``--relocalizer`` as a dict, with ``n_particles`` from ``--particles``; checked against `MCLConfig`."""
        from filters.localization.mcl import check_overrides
        from semreloc_env import default_relocalizer

        extra = self.relocalizer
        if not isinstance(extra, dict):
            raise ValueError(f"relocalizer: a dict (a JSON object) of MCLConfig fields, got {extra!r}")
        if "n_particles" in extra:
            raise ValueError("relocalizer: set the particle count with --particles")
        overrides = {**extra, "n_particles": self.particles}
        check_overrides(overrides, "relocalizer", default_relocalizer(self.env_id))
        return overrides

    def __post_init__(self) -> None:
        check_policy_specs(self.policies)
        if Path(self.out).exists() and not Path(self.out).is_dir():
            raise ValueError(f"out: {self.out!r} is a file; the outputs go into a folder")
        missing = [d for d in self.reuse if not (Path(d) / "episodes.json").is_file()]
        if missing:
            raise ValueError(f"reuse: no episodes.json in {missing}")
        for name in (*self.GENERATED, "starts", "max_steps", "particles", "noise_seed_offset"):
            least = 0 if name in (*self.GENERATED, "noise_seed_offset") else 1
            if getattr(self, name) < least:
                raise ValueError(f"{name} must be >= {least}, got {getattr(self, name)}")
        self.relocalizer_overrides()  # a bad JSON object or field is an error now, not in every worker
        from semreloc_env.layout_sampling import HELD_OUT_LAYOUT_SEEDS

        for name in self.GENERATED:
            if self.seed_set == "held_out" and getattr(self, name) > len(HELD_OUT_LAYOUT_SEEDS):
                raise ValueError(
                    f"{name}: at most {len(HELD_OUT_LAYOUT_SEEDS)} held-out seeds per kind, got {getattr(self, name)}"
                )
        if self.seed_set == "tuning" and not self.generates():
            raise ValueError(
                "layouts_per_kind (or ring_layouts, or corridor_layouts) must be >= 1 with seed_set tuning (it has no "
                "fixed layouts)"
            )
        from semreloc_env.layouts import find_layout_file

        # a path, or a name on $SEMRELOC_LAYOUT_PATH, as get_layout takes them
        missing = [f for f in self.layout_files if not Path(f).is_file() and find_layout_file(f) is None]
        if missing:
            raise ValueError(f"layout_files: no such file (nor a name on $SEMRELOC_LAYOUT_PATH): {missing}")
        from semreloc_env.layouts import LAYOUT_NAMES

        shadowed = [f for f in self.layout_files if f in LAYOUT_NAMES and not Path(f).is_file()]
        if shadowed:  # get_layout would take the built-in layout, never the file on the search path
            raise ValueError(f"layout_files: {shadowed} name built-in layouts; give the files' paths")
        where = [Path(f).resolve() if Path(f).is_file() else find_layout_file(f).resolve() for f in self.layout_files]
        twice = sorted({f for f, w in zip(self.layout_files, where) if where.count(w) > 1})
        if twice:
            raise ValueError(f"layout_files: the same file given more than once: {twice}")
        from semreloc_env.layouts import check_layout_option

        for f in self.layout_files:  # a malformed file fails here, not in a worker with a traceback
            check_layout_option(f, "layout_files")
        if not self.generates() and not self.layout_files and not self.builtin_layouts:
            raise ValueError(
                "no layouts: --layouts-per-kind 0 and --no-builtin-layouts need --layout-files, --ring-layouts or "
                "--corridor-layouts"
            )
        self._check_map_source()


ENV_ID = "SemReloc-v22"
"""The env episodes run in unless ``--env-id`` says otherwise; its cases' procedural layouts come from the newest
generator, as v3's to v15's do.
(The v3 tables of docs/active.md were made with ``SemReloc-v3``, the v2 tables with ``SemReloc-v2``; v3
gives the same episodes as v2 on every pair but those in the 30 look-alike pairs whose layouts it
draws again; v4 to v7 change the relocalizer and v8 the maps, so every episode.)"""

# ---------------------------------------------------------------------- cases
PROCEDURAL_KINDS = ("procedural", "procedural_sym", "procedural_lookalike")
RING_KIND = "procedural_ring"
CORRIDOR_KIND = "procedural_corridor"
BUILTIN_ROWS = (
    *PROCEDURAL_KINDS, "twin_rooms", "lab", "lab_changed", RING_KIND, CORRIDOR_KIND, "all", "uninformative starts",
    "paired",
)  # fmt: skip
"""The rows (and summary keys) the built-in cases fill (`groups`); a layout file never shares one."""


def layout_file_kinds(files: tuple[str, ...] | list[str]) -> dict[str, str]:
    """The ``kind`` (table row) of each layout file's cases: its name without the extension, or
    ``file:`` and the path as given where that name is a built-in row's (`BUILTIN_ROWS`) or another
    file's."""
    stems = [Path(f).stem for f in files]
    return {f: (s if s not in BUILTIN_ROWS and stems.count(s) == 1 else f"file:{f}") for f, s in zip(files, stems)}


def _view(world, pose, lidar_max, cam_max, angles):
    """The exact view from ``pose`` along ``angles`` (rad) relative to its heading: ranges and class labels."""
    from semreloc_env.lookalike import exact_views

    r, lab = exact_views(world, np.asarray(pose[:2])[None], (pose[2] + angles)[None], lidar_max, cam_max)
    return r[0], lab[0]


def _image(frame, local):
    fx, fy, ft = frame
    c, s = math.cos(ft), math.sin(ft)
    u, v, phi = local
    return np.array([fx + c * u - s * v, fy + s * u + c * v, math.remainder(ft + phi, 2 * math.pi)])


def uninformative_start(layout_seed: int, world, rng, lidar_max: float, cam_max: float, tries: int = 300):
    """A pose in a room of the lookalike layout ``layout_seed`` whose exact all-round view equals
    that of its image in another room, or None if none was found in ``tries`` draws."""
    from semreloc_env.layouts import ProceduralParams, lookalike_layout

    _, frames = lookalike_layout(np.random.default_rng(layout_seed), ProceduralParams(lookalike=True))
    width = frames[1][0] - frames[0][0] if len(frames) > 2 else 3.0
    depth = min(y for w in world.layout.walls for _, y in w if y > 0)
    angles = np.linspace(-math.pi, math.pi, 360, endpoint=False)
    for _ in range(tries):
        room = int(rng.integers(0, len(frames)))
        local = np.array([rng.uniform(0.4, width - 0.4), rng.uniform(0.4, depth - 0.4), rng.uniform(-math.pi, math.pi)])
        pose = _image(frames[room], local)
        if world.clearance(pose[:2]) < 0.45:
            continue
        r0, l0 = _view(world, pose, lidar_max, cam_max, angles)
        for other in range(len(frames)):
            if other == room:
                continue
            q = _image(frames[other], local)
            r1, l1 = _view(world, q, lidar_max, cam_max, angles)
            if np.allclose(r0, r1, atol=1e-6) and np.array_equal(l0, l1):
                return pose
    return None


def _start_seen_alike(world, rng, lidar_max: float, cam_max: float, images, tries: int):
    """The first of ``tries`` free poses drawn from ``rng`` whose exact all-round view equals that of one of its
    ``images(pose)`` (candidate poses; those not free are skipped), or None."""
    angles = np.linspace(-math.pi, math.pi, 360, endpoint=False)
    for _ in range(tries):
        pose = world.sample_free_pose(rng, margin_m=0.3)
        r0, l0 = _view(world, pose, lidar_max, cam_max, angles)
        for q in images(pose):
            if not world.is_free(q[:2], 0.3):
                continue
            r1, l1 = _view(world, q, lidar_max, cam_max, angles)
            if np.allclose(r0, r1, atol=1e-6) and np.array_equal(l0, l1):
                return pose
    return None


def uninformative_ring_start(world, rng, lidar_max: float, cam_max: float, tries: int = 300):
    """A pose in a `ring_layout` whose exact all-round view equals that of one of its quarter-turned
    images about the hall's centre, or None if none was found in ``tries`` draws."""
    from semreloc_env.layouts.procedural import quarter_turn

    x0, x1, y0, y1 = world.layout.bounds()
    side = x1 - x0

    def turned(pose):  # k quarter turns counter-clockwise about the hall's centre
        for k in (1, 2, 3):
            xy = quarter_turn(pose[:2] - (x0, y0), k, side) + (x0, y0)
            yield np.array([xy[0], xy[1], math.remainder(pose[2] + k * math.pi / 2, 2 * math.pi)])

    return _start_seen_alike(world, rng, lidar_max, cam_max, turned, tries)


def uninformative_corridor_start(world, rng, lidar_max: float, cam_max: float, tries: int = 300):
    """A pose in a `corridor_layout` whose exact all-round view equals that of the same pose shifted along the
    corridor, or None if none was found in ``tries`` draws. The shifts tried are the x distances between two
    objects of one class whose centres have the same y (among them the whole periods)."""
    objects = world.layout.objects
    centres = [o.centroid() for o in objects]
    shifts = sorted(
        {
            round(abs(float(ca[0] - cb[0])), 6)
            for i, (a, ca) in enumerate(zip(objects, centres))
            for b, cb in zip(objects[i + 1 :], centres[i + 1 :])
            if a.cls == b.cls and abs(ca[1] - cb[1]) < 1e-6 and abs(ca[0] - cb[0]) > 0.5
        }
    )

    def shifted(pose):
        for dx in shifts:
            yield pose + (dx, 0.0, 0.0)
            yield pose - (dx, 0.0, 0.0)

    return _start_seen_alike(world, rng, lidar_max, cam_max, shifted, tries)


SEEN_ALIKE_STARTS = {RING_KIND: uninformative_ring_start, CORRIDOR_KIND: uninformative_corridor_start}
"""The search for an uninformative start of each generated kind whose images are poses of the same layout."""


def build_cases(args: Args) -> list[dict]:
    """Every (layout, start) pair, in a fixed order."""
    from semreloc_env.config import CameraParams, LidarParams
    from semreloc_env.layout_sampling import HELD_OUT_LAYOUT_SEEDS
    from semreloc_env.layouts import get_layout
    from semreloc_env.scenarios import changed_obstacles
    from semreloc_env.world import build_world

    tuning = args.seed_set == "tuning"
    seeds = range(args.layouts_per_kind) if tuning else HELD_OUT_LAYOUT_SEEDS[: args.layouts_per_kind]
    layouts = [(k, int(s), "nominal") for k in PROCEDURAL_KINDS for s in seeds]
    if not tuning and args.builtin_layouts:
        layouts += [("twin_rooms", 0, "nominal"), ("lab", 0, "nominal"), ("lab", 0, "changed")]
    for kind, n in ((RING_KIND, args.ring_layouts), (CORRIDOR_KIND, args.corridor_layouts)):
        layouts += [(kind, int(s), "nominal") for s in (range(n) if tuning else HELD_OUT_LAYOUT_SEEDS[:n])]
    n_fixed = len(layouts)  # the layout files' cases come after these
    layouts += [(f, 0, "nominal") for f in args.layout_files]
    lidar_max, cam_max = LidarParams().range_max_m, CameraParams().range_max_m
    file_kinds = layout_file_kinds(args.layout_files)
    cases = []
    for li, (spec, seed, scenario) in enumerate(layouts):
        layout = get_layout(spec, seed=seed)
        is_file = li >= n_fixed
        digest = {"layout_digest": file_digest(spec)} if is_file else {}
        extra = changed_obstacles(layout, seed) if scenario == "changed" else []
        world = build_world(layout, extra_obstacles=extra)
        for si in range(args.starts):
            rng = np.random.default_rng([li, si, 7008 if tuning else 7007])
            pose, flag = None, False
            if spec == "procedural_lookalike" and si % 2 == 0:
                pose = uninformative_start(seed, world, rng, lidar_max, cam_max)
                flag = pose is not None
            elif spec in SEEN_ALIKE_STARTS and not is_file and si % 2 == 0:
                pose = SEEN_ALIKE_STARTS[spec](world, rng, lidar_max, cam_max)
                flag = pose is not None
            if pose is None:
                pose = world.sample_free_pose(rng, margin_m=0.3)
            if is_file:
                kind = file_kinds[spec]
            else:
                kind = "lab_changed" if scenario == "changed" else spec
            cases.append(
                {
                    "case": len(cases),
                    "kind": kind,
                    "layout": spec,
                    "layout_seed": seed,
                    "scenario": scenario,
                    "start": [float(v) for v in pose],
                    "episode_seed": (60_000 if tuning else 50_000) + len(cases) + args.noise_seed_offset,
                    "uninformative": flag,
                    **digest,
                }
            )
    return cases


# ---------------------------------------------------------------------- episodes
def run_case(job: tuple[dict, tuple[str, ...], Args]) -> list[dict]:
    """Every policy on one (layout, start) pair: a row per policy (`run_episode`), or for a policy that failed
    on this pair ``{"case", "policy", "error"}`` (its message names the policy and the case), so that one
    policy's failure does not cost the others' episodes."""
    case, policies, args = job
    rows = []
    for spec in policies:
        try:
            rows.append(run_episode(case, spec, args))
        except Exception as e:  # a user's class or a saved model can fail in any way: keep the message
            rows.append({"case": case["case"], "policy": spec.partition("=")[0], "error": str(e)})
    return rows


def run_episode(case: dict, spec: str, args: Args, max_steps: int | None = None) -> dict:
    """One episode of policy ``spec`` on ``case``: its row of episodes.json (``max_steps``: stop after that many
    steps, a check rather than an episode to score).

    Raises:
        ValueError: the policy cannot be built with the case's seed, or the env refused its action (the
            message names the policy and the case); whatever else the policy raises, with the same prefix.
    """
    from agents.metrics import EpisodeTracker

    name = spec.partition("=")[0]
    where = f"policy {name!r} on case {case['case']} ({case['kind']})"
    env = case_env(case, args)
    try:
        try:
            policy = make_policy(spec, case["episode_seed"], args.sample_learned)
        except Exception as e:  # a user's constructor that fails for this seed
            raise ValueError(
                f"{where}: cannot build it with seed {case['episode_seed']}: {type(e).__name__}: {e}"
            ) from None
        tracker = EpisodeTracker()
        collisions = 0
        t0 = time.perf_counter()
        actions: dict[str, int] = {}  # discrete actions taken (for learned policies: options included)
        try:
            env = policy.wrap(env)
            policy.reset()
            obs, info = env.reset(seed=case["episode_seed"], options={"pose": case["start"]})
            tracker.observe(info, is_step=False)
            while True:
                action = policy.act(obs)
                obs, reward, term, trunc, info = env.step(action)
                key = str(int(action)) if isinstance(action, (int, np.integer)) else motion_kind(action)
                actions[key] = actions.get(key, 0) + 1
                tracker.observe(info, reward)
                collisions += bool(info["collided"])
                if term or trunc or tracker.length == max_steps:
                    break
        except ValueError as e:  # the env refused the action, or the policy its observation: say whose, and where
            raise ValueError(f"{where}, step {tracker.length + 1}: {e}") from None
        except Exception as e:
            raise RuntimeError(f"{where}, step {tracker.length + 1}: {type(e).__name__}: {e}") from e
    finally:
        env.close()
    res = tracker.finish()
    return {
        **case,
        "policy": name,
        "outcome": res.outcome,
        "length": res.length,
        "steps_to_success": res.steps_to_converge,
        "first_convergence_wrong": res.first_convergence_wrong,
        "collisions": collisions,
        "final_position_error_m": res.final_position_error_m,
        "seconds": time.perf_counter() - t0,
        "actions": actions,
        "settings": settings(args, spec),
    }


def check_policy_runs(spec: str, case: dict, args: Args) -> None:
    """ValueError unless policy ``spec`` builds with ``case``'s seed, wraps ``case``'s env, and takes a first
    step in it: a saved model whose spaces do not fit the env (another action space, algorithm or sensor) or a
    class of your own that fails at once is refused before any episode runs."""
    try:
        run_episode(case, spec, args, max_steps=1)
    except Exception as e:  # anything a user's class or a saved model raises: name it, no traceback
        raise ValueError(f"policies: {spec}: fails on its first step: {e}") from None


def motion_kind(action) -> str:
    """What a continuous action ``(v, omega)`` does: ``"turn"`` on the spot, ``"arc"`` (drive and turn),
    ``"straight"``, ``"reverse"`` (backward, turning or not) or ``"stop"``."""
    v, w = (float(x) for x in np.asarray(action, dtype=np.float64).reshape(2))
    if v < 0:
        return "reverse"
    if v == 0:
        return "turn" if w != 0 else "stop"
    return "arc" if w != 0 else "straight"


def settings(args: Args, spec: str) -> dict:
    """What an episode row depends on besides its case: checked before ``--reuse`` keeps a row."""
    return {
        "particles": args.particles,
        "max_steps": args.max_steps,
        "map_source": args.map_source,
        **({"map_digest": file_digest(args.map_source)} if _map_is_file(args.map_source) else {}),
        "spec": spec,
        "code": policy_code(spec),
        "env_code": env_code(),
        "sample_learned": args.sample_learned and is_learned(spec),
        **({"seed_set": args.seed_set} if args.seed_set != "held_out" else {}),
        **({"action_type": args.action_type} if args.action_type != "discrete" else {}),
        "env_id": args.env_id,
        **({"relocalizer": args.relocalizer_overrides()} if args.relocalizer else {}),
    }


_PROJECT = ("agents", "filters", "semreloc_env")

_USER_SPEC = re.compile(r"^(?P<source>[A-Za-z_][\w.]*|.+\.py):(?P<attr>[A-Za-z_]\w*)$")


def _user_target(spec: str) -> re.Match | None:
    """For ``NAME=SOURCE:ATTR`` (SOURCE a module name or a ``.py`` file; not an existing file, which
    would be a saved policy) the match, else None."""
    rhs = spec.partition("=")[2]
    if not rhs or Path(rhs).is_file():
        return None
    return _USER_SPEC.match(rhs)


def is_learned(spec: str) -> bool:
    """Whether ``spec`` is ``NAME=PATH``, a policy file `agents.load_policy` loads."""
    return "=" in spec and _user_target(spec) is None


def _user_module(source: str) -> types.ModuleType:
    """The module of a user policy: a ``.py`` file (loaded under a name of its own) or a module
    importable from the current folder or ``sys.path``."""
    if source.endswith(".py"):
        path = Path(source).resolve()
        if not path.is_file():
            raise ValueError(f"no such file {source!r}")
        name = "semreloc_user_" + hashlib.sha256(str(path).encode()).hexdigest()[:12]
        if str(path.parent) not in sys.path:
            sys.path.append(str(path.parent))  # its sibling modules import as they would beside it
        if name not in sys.modules:
            loader = importlib.util.spec_from_file_location(name, path)
            module = importlib.util.module_from_spec(loader)
            sys.modules[name] = module
            try:
                loader.loader.exec_module(module)
            except BaseException:
                del sys.modules[name]
                raise
        return sys.modules[name]
    if "" not in sys.path and str(Path.cwd()) not in sys.path:
        sys.path.append(str(Path.cwd()))  # as `python -m` would find it
    return importlib.import_module(source)


def user_factory(spec: str):
    """The callable ``f(seed) -> policy`` a ``NAME=MODULE:CLASS`` spec names; ValueError saying whether the
    spec, the import or the name failed."""
    m = _user_target(spec)
    if m is None:
        raise ValueError(f"{spec!r} is not NAME=MODULE:CLASS")
    try:
        module = _user_module(m["source"])
    except Exception as e:  # a missing file or module, or its import failing
        raise ValueError(f"cannot import {m['source']}: {type(e).__name__}: {e}") from None
    factory = getattr(module, m["attr"], None)
    if factory is None:
        raise ValueError(f"{m['source']} has no {m['attr']!r}")
    return factory


def check_policy_specs(policies: Sequence[str], known: Sequence[str] | None = None) -> None:
    """ValueError unless every one of ``policies`` is a name of ``known`` (default: `agents.policies.POLICIES`),
    ``NAME=PATH`` of an existing policy file that `agents.load_policy` loads with no settings given (its saved
    settings read, `agents.learned.saved_settings`) or a ``NAME=MODULE:CLASS`` that builds (`check_user_policy`),
    with unique, non-empty names; at least one."""
    from agents.policies import POLICIES

    known = sorted(POLICIES) if known is None else list(known)
    if not policies:
        raise ValueError("policies: give at least one")
    comma = [x for x in policies if "," in x]
    if comma:
        raise ValueError(f"policies: {comma} holds a comma; separate the policies with spaces")
    unknown = [x for x in policies if x not in known and "=" not in x]
    if unknown:
        raise ValueError(
            f"policies: unknown {unknown}; choose from {known}, NAME=PATH (a saved policy) or "
            "NAME=MODULE:CLASS (your own)"
        )
    py = [x for x in policies if is_learned(x) and x.endswith(".py")]
    if py:
        raise ValueError(f"policies: {py}: name the class too, NAME=path/to/file.py:CLASS")
    bad_files = [x for x in policies if is_learned(x) and not Path(x.split("=", 1)[1]).is_file()]
    if bad_files:
        raise ValueError(
            f"policies: no policy file for {bad_files} (your own policy class: NAME=MODULE:CLASS or "
            "NAME=path/to/file.py:CLASS)"
        )
    for x in policies:
        if is_learned(x):
            from agents.learned import saved_settings

            try:  # learned policies load as agents.load_policy(path) does, with no settings given
                saved_settings(x.split("=", 1)[1])
            except ValueError as e:
                raise ValueError(f"policies: {x}: {e}") from None
        elif "=" in x:
            check_user_policy(x)
    names = [x.partition("=")[0] for x in policies]
    if len(set(names)) < len(names) or not all(names):
        raise ValueError(f"policies: names must be unique and non-empty, got {names}")


def check_user_policy(spec: str) -> None:
    """ValueError unless ``spec`` (``NAME=MODULE:CLASS`` or ``NAME=file.py:CLASS``) builds, called with a
    seed, an object with ``wrap(env)``, ``reset()`` and ``act(obs)``."""
    if _user_target(spec) is None:
        raise ValueError(
            f"policies: {spec}: expected NAME=PATH (a file saved by agents.learned.save_policy), "
            "NAME=MODULE:CLASS or NAME=path/to/file.py:CLASS"
        )
    try:
        factory = user_factory(spec)
    except ValueError as e:
        raise ValueError(f"policies: {spec}: {e}") from None
    try:
        policy = factory(0)
    except Exception as e:  # the user's constructor
        raise ValueError(f"policies: {spec}: cannot build it with a seed: {type(e).__name__}: {e}") from None
    from agents.policies import Policy

    missing = [m for m in ("wrap", "reset", "act") if not callable(getattr(policy, m, None))]
    if isinstance(policy, Policy) and type(policy).act is Policy.act:
        missing.append("act")  # the base class's act only raises NotImplementedError
    if missing:
        raise ValueError(
            f"policies: {spec}: a policy needs wrap(env), reset() and act(obs) (agents.policies.Policy); "
            f"{type(policy).__name__} lacks {missing}"
        )


def _local_files(module: types.ModuleType) -> list[Path]:
    """The files a user policy's fingerprint covers, whatever is loaded when it is taken: its module's
    file and, transitively, the ``.py`` files of the modules it imports (anywhere in a file, by ``import``
    or ``from ... import``, relative imports included) that lie in its folder tree (a file's folder, or
    for a module of a package the top package's folder, with the ``__init__.py`` of every package on its
    dotted name), less the project's own packages (`policy_modules` covers those) and whatever lies
    outside that tree (installed packages). Other files in the folder do not count, so a scratch folder's
    unrelated files do not make ``--reuse`` run the policy again."""
    start = Path(module.__file__).resolve()
    dotted = module.__name__.split(".")
    top = sys.modules.get(dotted[0], module)
    package = getattr(top, "__path__", None)
    if package is not None:  # a module of a package, or the package itself
        root = Path(next(iter(package))).resolve()  # the top package's folder: imports resolve from its parent
        base = root.parent
        todo = [start, *_files_loaded(base, dotted)]  # and each package its import runs
    else:
        root = base = start.parent  # a file: its folder is on the import path
        todo = [start]
    project = [Path(importlib.import_module(p).__file__).resolve().parent for p in _PROJECT]
    seen: set[Path] = set()
    skipped: set[Path] = set()
    while todo:
        f = todo.pop()
        if f in seen or f in skipped or not f.is_relative_to(root) or any(f.is_relative_to(p) for p in project):
            continue
        try:
            tree = ast.parse(f.read_bytes(), str(f))
        except (SyntaxError, ValueError, OSError):  # the import itself reports a broken or unreadable file
            skipped.add(f)
            continue
        seen.add(f)
        for name in _imported_names(tree, f, base):
            todo += _files_loaded(base, name.split("."))
    return sorted(seen)


def _keyed(files: list[Path]) -> list[tuple[str, Path]]:
    """``(key, file)`` for the fingerprint: each file keyed by its path below the files' common folder (not its
    bare name, so that two ``helper.py`` in different folders, or a file moved within the tree, count apart)."""
    common = Path(os.path.commonpath([f.parent for f in files])) if files else Path()
    return [(f.relative_to(common).as_posix(), f) for f in files]


def _files_loaded(base: Path, parts: list[str]) -> list[Path]:
    """The existing files below ``base`` that importing the dotted name ``parts`` runs: the module's file
    (or its package's ``__init__.py``) and the ``__init__.py`` of each package the name passes through."""
    found = [base.joinpath(*parts).with_suffix(".py"), base.joinpath(*parts, "__init__.py")]
    found += [base.joinpath(*parts[:k], "__init__.py") for k in range(1, len(parts))]
    return [f.resolve() for f in found if f.is_file()]


def _imported_names(tree: ast.AST, path: Path, base: Path) -> list[str]:
    """Dotted names (relative to ``base``) that the imports of a parsed file may load: ``import a.b`` gives
    ``a.b``; ``from a import b`` gives ``a`` and ``a.b`` (``b`` may be a module); relative imports are
    resolved from the file's folder."""
    out: list[str] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                folder = path.parent
                for _ in range(node.level - 1):
                    folder = folder.parent
                if not folder.is_relative_to(base):
                    continue
                prefix = ".".join(folder.relative_to(base).parts)
                module = ".".join(p for p in (prefix, node.module or "") if p)
            else:
                module = node.module or ""
            if module:
                out.append(module)
            out += [f"{module}.{a.name}" if module else a.name for a in node.names if a.name != "*"]
    return out


def policy_modules(spec: str) -> list[str]:
    """The project modules (`agents`, `filters`, `semreloc_env`) the policy of ``spec`` draws on: its
    class's module and, transitively, those its module-level imports come from (for a learned
    policy: `agents.learned`, the motion options and the feature extractor, which it imports when
    loading and wrapping; for a user's class, the project modules its module imports)."""
    name, _, path = spec.partition("=")
    user = _user_target(spec)
    if user is not None:
        todo = _module_names(_user_module(user["source"]))
    elif path:
        todo = ["agents.learned", "agents.options", "agents.viewpoint", "agents.active_features"]
    else:
        from agents.policies import POLICIES

        todo = [type(POLICIES[name](0)).__module__]
    seen: set[str] = set()
    while todo:
        mod = todo.pop()
        if mod in seen or not mod.startswith(_PROJECT):
            continue
        seen.add(mod)
        todo += [m for m in _module_names(importlib.import_module(mod)) if m.startswith(_PROJECT) and m not in seen]
    return sorted(seen)


def _module_names(module: types.ModuleType) -> list[str]:
    """The modules ``module``'s module-level names come from (imported modules, and the modules of
    imported classes and functions)."""
    names = (
        v.__name__ if isinstance(v, types.ModuleType) else getattr(v, "__module__", None) for v in vars(module).values()
    )
    return [m for m in names if isinstance(m, str)]


@functools.cache
def env_code() -> str:
    """A fingerprint (16 hex digits) of the code every episode runs whatever the policy: the source
    files of `filters` and `semreloc_env`, this module (the episode runner) and `agents.metrics` (which scores
    an episode: success, wrong, unconverged), and the versions of the
    libraries they compute with (`semreloc_env.maps.mapping_libraries` and SciPy). Read once per process."""
    import scipy

    from semreloc_env.maps import mapping_libraries

    h = hashlib.sha256()
    roots = [Path(importlib.import_module(p).__file__).parent for p in ("filters", "semreloc_env")]
    files = [(f.relative_to(roots[0].parent).as_posix(), f) for f in sorted(f for r in roots for f in r.rglob("*.py"))]
    files += [("agents/experiments/evaluate_active.py", Path(__file__))]
    files += [("agents/metrics.py", Path(importlib.import_module("agents.metrics").__file__))]  # scores an episode
    for name, f in files:
        h.update(name.encode() + b"\0" + f.read_bytes())
    h.update(repr((*mapping_libraries(), f"scipy=={scipy.__version__}")).encode())
    return h.hexdigest()[:16]


def _map_is_file(map_source: str) -> bool:
    """Whether ``map_source`` is a layout file (whose bytes a row's settings record; a built-in
    layout is part of the code, `env_code`)."""
    from semreloc_env.layouts import LAYOUT_NAMES

    return map_source not in ("mapping", "perfect", *LAYOUT_NAMES)


def file_digest(path: str) -> str:
    """A fingerprint (16 hex digits) of a layout file's bytes (found as `get_layout` finds it), or of
    a ROS map as read (its occupancy and class grids, resolution, origin and class names: the image
    and sidecar files count, not only the .yaml's bytes)."""
    from semreloc_env.layouts import find_layout_file
    from semreloc_env.maps import is_ros_map_file, load_env_map

    if is_ros_map_file(path):
        grid = load_env_map(path)  # as the env reads it
        h = hashlib.sha256(np.ascontiguousarray(grid.occupancy).tobytes())
        h.update(b"" if grid.semantic is None else np.ascontiguousarray(grid.semantic).tobytes())
        h.update(repr((grid.resolution_m, tuple(grid.origin_xy_m), tuple(grid.class_names))).encode())
        return h.hexdigest()[:16]
    found = Path(path) if Path(path).is_file() else find_layout_file(path)
    return hashlib.sha256(Path(found).read_bytes()).hexdigest()[:16]


@functools.cache
def policy_code(spec: str) -> str:
    """A fingerprint (16 hex digits) of the code behind ``spec``: the source files of
    `policy_modules` and, for ``NAME=PATH``, the policy file's bytes and the versions of torch and
    stable-baselines3. A row kept by ``--reuse`` must
    carry the same fingerprint, so changing a policy's code (or code it calls) reruns it. Read once
    per process."""
    h = hashlib.sha256()
    for mod in policy_modules(spec):
        h.update(mod.encode() + b"\0" + Path(importlib.import_module(mod).__file__).read_bytes())
    user = _user_target(spec)
    if user is not None:  # the user's module and the modules it imports from its own folder
        for key, f in _keyed(_local_files(_user_module(user["source"]))):
            h.update(key.encode() + b"\0" + f.read_bytes())
    elif "=" in spec:  # a learned policy: its file, and the libraries that run its network
        import stable_baselines3
        import torch

        h.update(Path(spec.partition("=")[2]).read_bytes())
        h.update(f"torch=={torch.__version__};stable_baselines3=={stable_baselines3.__version__}".encode())
    return h.hexdigest()[:16]


def make_policy(spec: str, seed: int, sample: bool = False):
    """The policy named by ``spec``: a baseline name of agents.policies.POLICIES, NAME=PATH (a learned
    policy, sampling its actions from a generator seeded with ``seed`` if ``sample``) or NAME=MODULE:CLASS
    (``CLASS(seed)``, your own)."""
    from agents.policies import POLICIES

    name, _, path = spec.partition("=")
    if _user_target(spec) is not None:
        return user_factory(spec)(seed)
    if path:
        from agents.learned import LearnedPolicy

        loaded = _loaded_policy(path)
        return LearnedPolicy(
            loaded.model, loaded.observation, loaded.repeat, deterministic=not sample, seed=seed, options=loaded.options
        )
    return POLICIES[name](seed)


_LOADED: dict[tuple, object] = {}


def _loaded_policy(path: str):
    """`agents.learned.load_policy` of ``path``, once per process and file version (loading the model
    costs ~0.2 s, a sizeable share of an episode): every case gets a fresh `LearnedPolicy` around it."""
    from agents.learned import load_policy

    st = Path(path).stat()
    key = (str(Path(path).resolve()), st.st_mtime_ns, st.st_size)
    if key not in _LOADED:
        _LOADED[key] = load_policy(path)
    return _LOADED[key]


def case_env(case: dict, args: Args, render_mode: str | None = None):
    """The env of one (layout, start) pair: its layout, scenario, map, particle count and step limit."""
    import gymnasium as gym

    import semreloc_env  # noqa: F401

    return gym.make(
        args.env_id,
        layout=case["layout"],
        layout_seed=case["layout_seed"],
        scenario=case["scenario"],
        map_source=args.map_source,
        relocalizer=args.relocalizer_overrides(),
        max_episode_steps=args.max_steps,
        action_type=args.action_type,
        render_mode=render_mode,
    )


def record_gif(case: dict, spec: str, args: Args, path: Path, every: int = 2) -> None:
    """One episode of ``spec`` on ``case`` as a GIF (every ``every``-th frame, 10 fps)."""
    from PIL import Image

    env = case_env(case, args, render_mode="rgb_array")
    policy = make_policy(spec, case["episode_seed"], args.sample_learned)
    env = policy.wrap(env)
    policy.reset()
    obs, info = env.reset(seed=case["episode_seed"], options={"pose": case["start"]})
    frames, t = [env.render()], 0
    while True:
        obs, _, term, trunc, info = env.step(policy.act(obs))
        t += 1
        if t % every == 0 or term or trunc:
            frames.append(env.render())
        if term or trunc:
            break
    env.close()
    images = [Image.fromarray(f).convert("P", palette=Image.Palette.ADAPTIVE) for f in frames]
    images += [images[-1]] * 10  # hold the end
    images[0].save(path, save_all=True, append_images=images[1:], duration=100, loop=0)


# ---------------------------------------------------------------------- summary
wilson = wilson_interval  # Wilson 95 % interval (filters.experiments.stats)


def layout_of(row: dict) -> tuple:
    """The layout a row's episode ran on: the cluster its outcome shares with the other starts of that layout."""
    return (row["layout"], row["layout_seed"], row["scenario"], row.get("layout_digest"))


def _layout_clusters(rows: list[dict]) -> list[tuple] | None:
    """Each row's layout (`layout_of`), or None with fewer than two layouts (no clusters to count)."""
    clusters = [layout_of(r) for r in rows]
    return clusters if len(set(clusters)) >= 2 else None


def layouts_interval(values, rows: list[dict]) -> list[float] | None:
    """95 % bootstrap interval of the mean of ``values`` (one per row, e.g. paired differences) with each layout's
    rows resampled together (`filters.experiments.stats.cluster_bootstrap_interval`, seeded), or None with fewer
    than two layouts."""
    from filters.experiments.stats import cluster_bootstrap_interval

    clusters = _layout_clusters(rows)
    if clusters is None:
        return None
    _, lo, hi = cluster_bootstrap_interval(values, clusters, np.random.default_rng(0))
    return [lo, hi]


def layouts_rate_interval(hits: list[bool], rows: list[dict]) -> tuple[list[float] | None, float | None]:
    """``(interval, design effect)`` of the rate of ``hits`` (one per row) with the rows of a layout counted as one
    cluster: Wilson's 95 % interval at the effective sample size
    (`filters.experiments.stats.clustered_wilson_interval`); ``(None, None)`` with fewer than two layouts."""
    from filters.experiments.stats import clustered_wilson_interval

    clusters = _layout_clusters(rows)
    if clusters is None:
        return None, None
    effect, lo, hi = clustered_wilson_interval(np.asarray(hits, dtype=np.float64), clusters)
    return [lo, hi], effect


def summarise(rows: list[dict]) -> dict:
    """One policy's rows: ``episodes``, ``layouts``; per outcome (``success``, ``wrong``, ``unconverged``) and for
    ``first_wrong`` (episodes whose belief first reported "converged" at a wrong pose, whatever came after)
    ``{"rate", "ci95" (Wilson: the episodes taken as independent), "ci95_layouts" (Wilson at the effective sample
    size of the layouts' clusters, `layouts_rate_interval`; None with one layout), "design_effect", "count"}``;
    ``median_steps`` of the successes (None if none), ``collisions_per_episode``, ``seconds_per_step``."""
    n = len(rows)
    out = {"episodes": n, "layouts": len({layout_of(r) for r in rows})}
    hits = {outcome: [r["outcome"] == outcome for r in rows] for outcome in ("success", "wrong", "unconverged")}
    hits["first_wrong"] = [bool(r["first_convergence_wrong"]) for r in rows]
    for name, h in hits.items():
        k = sum(h)
        by_layout, effect = layouts_rate_interval(h, rows)
        out[name] = {
            "rate": k / n,
            "ci95": wilson(k, n),
            "ci95_layouts": by_layout,
            "design_effect": effect,
            "count": k,
        }
    steps = [r["steps_to_success"] for r in rows if r["steps_to_success"] is not None]
    out["median_steps"] = float(np.median(steps)) if steps else None
    out["collisions_per_episode"] = float(np.mean([r["collisions"] for r in rows]))
    out["seconds_per_step"] = float(sum(r["seconds"] for r in rows) / max(sum(r["length"] for r in rows), 1))
    return out


def groups(rows: list[dict]) -> dict[str, list[dict]]:
    g: dict[str, list[dict]] = {"all": rows}
    for r in rows:
        g.setdefault(r["kind"], []).append(r)
    unin = [r for r in rows if r["uninformative"]]
    if unin:
        g["uninformative starts"] = unin
    return g


def _pct(x: dict) -> str:
    lo, hi = x["ci95"]
    return f"{100 * x['rate']:.0f} % [{100 * lo:.0f}, {100 * hi:.0f}]"


def _layouts_ci(x: dict) -> str:
    ci = x.get("ci95_layouts")
    if ci is None:
        return "n/a: one layout"
    return "[{:.0f}, {:.0f}] (design effect {:.1f})".format(*(100 * v for v in ci), x["design_effect"])


TABLE_NOTE = (
    "Intervals: the first, in each column, is Wilson's 95 % interval, which takes the episodes as independent; "
    "the starts of one layout succeed or fail together, so it is too narrow for what a result says of other "
    "layouts. `success, over layouts` is Wilson's interval at the effective sample size the layouts leave "
    "(the design effect: how much the starts of one layout agree; where all or none succeeded, the worst case, each "
    "layout one outcome), the one to read for layouts."
)


def table(summary: dict, policies: list[str]) -> str:
    lines = [TABLE_NOTE, ""]
    for group, per_policy in summary.items():
        first = per_policy[policies[0]]
        n = first["episodes"]
        n_layouts = first.get("layouts")
        of = "" if n_layouts is None else f" on {n_layouts} layout{'' if n_layouts == 1 else 's'}"
        lines += [
            f"### {group} ({n} episode{'' if n == 1 else 's'} per policy{of})",
            "",
            "| policy | success | success, over layouts | wrong | unconverged | first convergence wrong "
            "| median steps | steps in collision / episode |",
            "|---|---|---|---|---|---|---|---|",
        ]
        for p in policies:
            s = per_policy[p]
            med = "-" if s["median_steps"] is None else f"{s['median_steps']:.0f}"
            lines.append(
                f"| {p} | {_pct(s['success'])} | {_layouts_ci(s['success'])} | {_pct(s['wrong'])} | "
                f"{_pct(s['unconverged'])} | {_pct(s['first_wrong'])} | {med} | {s['collisions_per_episode']:.1f} |"
            )
        lines.append("")
    return "\n".join(lines)


def _mean_difference(base: np.ndarray, new: np.ndarray, axis: int = -1) -> np.ndarray:
    return np.mean(new - base, axis=axis)


def paired(rows: list[dict], learned: list[str], policies: list[str]) -> list[dict]:
    """Success of each learned policy against each other policy on the same cases: the difference
    of the success rates with a paired bootstrap 95 % interval (``filters.experiments.stats``,
    seeded; None with a single case, which has no spread to resample), the same with each layout's cases resampled
    together (``ci95_layouts``, `layouts_interval`; None with one layout), and McNemar's exact p-value (a
    binomial test on the discordant pairs, which takes the cases as independent)."""
    from filters.experiments.stats import mcnemar_exact_p, paired_bootstrap_interval

    by = {(r["case"], r["policy"]): r["outcome"] == "success" for r in rows}
    cases = sorted({r["case"] for r in rows})
    case_rows = list({r["case"]: r for r in rows}.values())
    case_rows.sort(key=lambda r: r["case"])
    out = []
    for a in learned:
        for b in policies:
            if b == a:
                continue
            x = np.array([by[(c, a)] for c in cases], dtype=np.float64)
            y = np.array([by[(c, b)] for c in cases], dtype=np.float64)
            if len(cases) > 1:
                point, lo, hi = paired_bootstrap_interval(y, x, np.random.default_rng(0), statistic=_mean_difference)
                ci95 = [lo, hi]
            else:
                point, ci95 = float(np.mean(x - y)), None
            ci95_layouts = layouts_interval(x - y, case_rows)
            wins, losses = int(np.sum((x == 1) & (y == 0))), int(np.sum((x == 0) & (y == 1)))
            p = mcnemar_exact_p(wins, losses)
            out.append(
                {
                    "policy": a,
                    "against": b,
                    "difference": point,
                    "ci95": ci95,
                    "ci95_layouts": ci95_layouts,
                    "wins": wins,
                    "losses": losses,
                    "mcnemar_p": p,
                }
            )
    return out


def paired_table(comparisons: list[dict]) -> str:
    lines = [
        "### paired: success of the learned (or your own) policy minus the other's, same cases",
        "",
        "The first interval and McNemar's p take the cases as independent; the layouts-resampled interval resamples "
        "each layout's cases together, the one to read for what the difference says of other layouts.",
        "",
        "| policy | against | difference [paired bootstrap 95 %] | [layouts resampled] | only it solved "
        "| only other solved | McNemar p |",
        "|---|---|---|---|---|---|---|",
    ]
    for c in comparisons:
        ci = "n/a: one case" if c["ci95"] is None else "{:+.1f}, {:+.1f}".format(*(100 * v for v in c["ci95"]))
        by_layout = c.get("ci95_layouts")
        lay = "n/a: one layout" if by_layout is None else "[{:+.1f}, {:+.1f}]".format(*(100 * v for v in by_layout))
        lines.append(
            f"| {c['policy']} | {c['against']} | {100 * c['difference']:+.1f} pp [{ci}] | {lay} | "
            f"{c['wins']} | {c['losses']} | {c['mcnemar_p']:.3g} |"
        )
    return "\n".join([*lines, ""])


def plot(summary: dict, policies: list[str], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = list(summary)
    fig, ax = plt.subplots(figsize=(max(6, 1.2 * len(names) * len(policies) / 3), 4))
    width = 0.8 / len(policies)
    x = np.arange(len(names))
    for i, p in enumerate(policies):
        rate = np.array([summary[g][p]["success"]["rate"] for g in names])
        lo = np.array([summary[g][p]["success"]["ci95"][0] for g in names])
        hi = np.array([summary[g][p]["success"]["ci95"][1] for g in names])
        ax.bar(x + (i - (len(policies) - 1) / 2) * width, rate, width, yerr=[rate - lo, hi - rate], capsize=2, label=p)
    ax.set_xticks(x, names, rotation=20, ha="right")
    ax.set_ylim(0, 1)
    ax.set_ylabel("success within the step limit (Wilson 95 %)")
    ax.legend(fontsize=8, ncol=min(len(policies), 5))
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


@command
def main(argv: list[str] | None = None) -> int:
    """The command: parse ``argv`` (default ``sys.argv[1:]``), run the episodes, write the outputs."""
    args = parse(Args, argv, __doc__)
    specs = list(args.policies)
    policies = [s.partition("=")[0] for s in specs]
    t0 = time.time()
    try:
        cases = build_cases(args)
    except ValueError as e:  # e.g. a layout file with no room for the robot: its message names the layout
        return usage_error("evaluate_active", f"--layout-files: {e}" if args.layout_files else e)
    if args.gif_case >= len(cases):  # known only once the cases are built: an argument error all the same
        return usage_error(
            "evaluate_active", f"--gif-case {args.gif_case} is not a case (there are {len(cases)}, 0-{len(cases) - 1})"
        )
    for spec in specs:  # a saved model or a class of your own that cannot even start is an argument error
        if "=" in spec:
            try:
                check_policy_runs(spec, cases[0], args)
            except ValueError as e:
                return usage_error("evaluate_active", e)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    n_unin = sum(c["uninformative"] for c in cases)
    print(f"{len(cases)} (layout, start) pairs ({n_unin} uninformative starts) x {len(policies)} policies", flush=True)
    rows: list[dict] = []
    if args.reuse:
        old = [r for d in args.reuse for r in json.loads((Path(d) / "episodes.json").read_text())]
        keep = {c["case"]: c for c in cases}
        wanted = {p: settings(args, s) for p, s in zip(policies, specs)}
        seen: set[tuple[int, str]] = set()
        for r in old:
            c = keep.get(r["case"])
            if (
                r["policy"] in wanted
                and c is not None
                and all(r.get(k) == v for k, v in c.items())
                and (r["case"], r["policy"]) not in seen
                and r.get("settings") == wanted[r["policy"]]  # rows without settings cannot be checked: run again
                and "first_convergence_wrong" in r  # rows of runs before it was recorded are run again
            ):
                seen.add((r["case"], r["policy"]))
                rows.append(r)
        done = {(r["case"], r["policy"]) for r in rows}
        print(f"reused {len(rows)} episodes from {', '.join(args.reuse)}", flush=True)
    else:
        done = set()
    todo = [s for s in specs if any((c["case"], s.partition("=")[0]) not in done for c in cases)]
    todo_names = {s.partition("=")[0] for s in todo}
    rows = [r for r in rows if r["policy"] not in todo_names]  # a policy is reused whole or run whole
    jobs = [(c, tuple(todo), args) for c in cases] if todo else []

    def report(done_jobs: int, total: int) -> None:
        print(f"  {done_jobs}/{total} pairs, {time.time() - t0:.0f} s", file=sys.stderr, flush=True)

    on_result = report if args.runner.progress else None  # --no-progress: nothing per pair
    for r in run_jobs(run_case, jobs, args.runner, desc="pairs", on_result=on_result):  # results in job order
        rows += r
    failed: dict[str, str] = {}  # policy -> its first error; its episodes are left out, the others' written
    for r in rows:
        if "error" in r:
            failed.setdefault(r["policy"], r["error"])
    if failed:
        rows = [r for r in rows if r["policy"] not in failed]
        specs = [s for s in specs if s.partition("=")[0] not in failed]
        policies = [p for p in policies if p not in failed]
        for name, message in failed.items():
            print(f"evaluate_active: policy {name!r} failed, its episodes are left out: {message}", file=sys.stderr)
        if not policies:
            print("evaluate_active: no policy finished; nothing written", file=sys.stderr)
            return 1
    rows.sort(key=lambda r: (r["case"], policies.index(r["policy"])))
    summary = {
        g: {p: summarise([r for r in rs if r["policy"] == p]) for p in policies} for g, rs in groups(rows).items()
    }
    (out / "episodes.json").write_text(json.dumps(rows, indent=1))
    learned = [s.partition("=")[0] for s in specs if "=" in s]
    comparisons = paired(rows, learned, policies) if learned and len(policies) > 1 else []
    summary_out = {**summary, "paired": comparisons} if comparisons else summary
    (out / "summary.json").write_text(json.dumps(summary_out, indent=1))
    cli = command_line("scripts/evaluate_active.py", sys.argv[1:] if argv is None else argv)
    header = (
        f"Command: `{cli}`"
        f"\n\n{len(cases)} (layout, start) pairs, {n_unin} uninformative; {args.particles} particles, map "
        f"{args.map_source}{', continuous actions' if args.action_type == 'continuous' else ''}, success within "
        f"{args.max_steps} steps; wall time {time.time() - t0:.0f} s.\n\n"
    )
    (out / "table.md").write_text(
        header + table(summary, policies) + ("\n" + paired_table(comparisons) if comparisons else "")
    )
    plot(summary, policies, out / "success.png")
    if 0 <= args.gif_case < len(cases):
        for spec in specs:
            record_gif(cases[args.gif_case], spec, args, out / f"gif_{spec.partition('=')[0]}.gif")
    print(table({"all": summary["all"]}, policies))
    if comparisons:
        print(paired_table(comparisons))
    gifs = "".join(f", gif_{p}.gif" for p in policies) if 0 <= args.gif_case < len(cases) else ""
    print(f"wrote {out}/table.md, success.png, summary.json, episodes.json{gifs} ({time.time() - t0:.0f} s)")
    if failed:
        print(
            f"evaluate_active: {', '.join(map(repr, failed))} left out; after fixing, `--reuse {out}` keeps the "
            "other policies' episodes",
            file=sys.stderr,
        )
        return 1
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
