"""Evaluation of the relocalizer inside ``SemReloc``: seeded episodes, outcomes, calibration.

An *episode* runs a fixed policy for ``n_steps`` steps in one layout from one seed, without
stopping at success, so the belief is watched after it claims convergence. Per episode
(from the env's ``info`` only; the true pose is used for scoring, never by the policy):

* **success**: at some step the belief was converged with its estimate within 0.5 m and
  15 deg of the truth (what ``SemReloc`` terminates on); ``steps`` is the first such step.
  In a kidnap episode only steps from the kidnap on count, and ``steps`` counts from it.
* **wrong**: no success, and the last step's belief is converged elsewhere.
* **unconverged**: neither. (The three partition the episodes, as in `agents.metrics`.)
* **ever_wrong**: some step before the first success had a converged, wrong belief.
* **calibration counts**: ``converged_steps`` and ``converged_correct_steps`` over all steps
  (post-kidnap steps only, in a kidnap episode): calibration = correct / converged.
* **cpu_s_per_step**: process CPU time per env step (the machine may be shared).
* **median_error_m**: median position error of the estimate over the scored steps.

Kidnap episodes (tracking, or a global start, then a teleport at step ``kidnap_at_step``) also
give (None in the others):

* **reconverged_wrong**: after the kidnap the belief was unconverged at some step (or already at
  the kidnap), and at a later step, before the first success, converged at a wrong place. Right
  after a teleport the belief is still converged at the old place: that stale state makes
  ``ever_wrong``, and says nothing about the recovery; ``reconverged_wrong`` does.
* **pre_kidnap_success** / **converged_at_kidnap**: some step before the kidnap was a success /
  the belief the teleport found (after step ``kidnap_at_step - 1``) was converged.
* **kidnapped_at**: the first step whose ``info["kidnapped"]`` was True (the env's own record).
* post-kidnap diagnostics of the relocalizer (``info["mcl"]``): ``w_slow_at_kidnap`` /
  ``w_fast_at_kidnap`` (the augmented-MCL averages the teleport found), ``recovery_steps`` (steps
  whose ``p_inject`` exceeded the routine ``proposal_frac``: augmented-MCL recovery injection),
  ``max_p_inject``, ``reinit_steps`` (all weights underflowed: global re-init), ``audits`` /
  ``audit_adds`` (convergence audits run / that added a hypothesis), ``surprises`` (updates the
  relocalizer took for a jump, `MCLConfig.surprise_ratio`; its audit window restarts there) and
  ``stale_audits`` / ``stale_audit_adds`` (those run fewer than ``audit_window`` updates after the
  kidnap and before any surprise after it, with
  pre-kidnap scans in the audit's window).

`score_steps` is the scoring of one episode's beliefs (a pure function of them).

Each episode's result depends only on its `EpisodeSpec`, so many of them run with
`filters.experiments.runner.run_jobs` (``run_jobs(run_episode, specs, runner)``) give the
same results sequentially, in a process pool or on Ray. `log_trial` and `log_tracking`
are the jobs of the ACES-log rows. The command is `agents.experiments.evaluate_relocalizer`.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from filters.experiments.stats import wilson_interval
from filters.numbers import is_int

LAYOUT_FILE_SUFFIXES = (".json", ".yaml", ".yml")
"""An episode's ``layout`` ending so is a layout file; its row is named by the file name's stem."""

POLICIES = ("random", "spin", "wall_follow")

TWIN_CENTRES = {"twin_rooms": (6.0, 3.0)}
"""Layouts whose half turn about this centre (x m, y m) maps the walls and the furniture's shapes onto themselves
and gives the furniture other classes: a kidnap to the image of the pose (`twin_image`) only the classes reveal."""


def twin_image(layout: str, pose) -> list[float]:
    """The half-turned image ``[x, y, theta]`` (m, rad in ``(-pi, pi]``) of ``pose`` in a layout of `TWIN_CENTRES`."""
    cx, cy = TWIN_CENTRES[layout]
    x, y, th = (float(v) for v in pose)
    return [2.0 * cx - x, 2.0 * cy - y, math.atan2(math.sin(th + math.pi), math.cos(th + math.pi))]


def lookalike_kidnap_pose(env, pose, seed: int):
    """The `semreloc_env.lookalike.Lookalike` a ``*_lookalike_kidnap`` episode teleports to:
    `semreloc_env.lookalike.lookalike_kidnap` of ``pose`` within the env's lidar and camera ranges, searched with a
    generator seeded by ``seed`` + 7919 (apart from the episode's own)."""
    from semreloc_env.lookalike import lookalike_kidnap

    u = env.unwrapped
    return lookalike_kidnap(
        u.world, pose, np.random.default_rng(seed + 7919),
        max_range_m=u.lidar.params.range_max_m, camera_range_m=u.camera.params.range_max_m,
    )  # fmt: skip


KIDNAP_STEP = 30
"""The step of the evaluation's tracking-then-kidnap rows' teleport, and the kidnap step whose look-alike place a
``global_at_lookalike`` episode starts at: a ``*_lookalike_global`` row starts where the ``*_lookalike_kidnap`` row
teleports to, seed for seed."""


@dataclass(frozen=True)
class EpisodeSpec:
    """One evaluation episode. ``mcl`` holds ``MCLConfig`` overrides (applied to the env's
    default relocalizer); ``kidnap_at_step`` > 0 makes it a tracking-then-kidnap episode (row
    ``*_kidnap``), with ``kidnap_after_global`` a global-start-then-kidnap episode (row
    ``*_global_kidnap``: no ``tracking`` reset option, a teleport at step ``kidnap_at_step``), and
    ``tracking`` a tracking episode (the belief starts at the true pose; only the error and the
    step time are of interest). ``kidnap_to_twin``: a tracking-then-kidnap episode whose teleport goes to the
    half-turned image of the pose after step ``kidnap_at_step - 1`` (`twin_image`; row ``*_twin_kidnap``): the
    same scans for the lidar, other classes for the camera. ``kidnap_to_lookalike``: the same with the teleport going to
    `lookalike_kidnap_pose` of that pose (row ``*_lookalike_kidnap``). ``global_at_lookalike``: no kidnap, a global
    start at the place a ``kidnap_to_lookalike`` episode of the same seed and policy kidnapped at step
    `KIDNAP_STEP` would go to (row ``*_lookalike_global``): what a belief that knows nothing does from
    there, beside what the belief after that kidnapping does. Inconsistent values raise ``ValueError``."""

    layout: str
    seed: int
    policy: str
    layout_seed: int = 0
    scenario: str = "nominal"
    n_steps: int = 400
    kidnap_at_step: int = 0
    tracking: bool = False
    mcl: dict = field(default_factory=dict)
    env_kwargs: dict = field(default_factory=dict)
    env_id: str = ""
    label: str = ""
    kidnap_after_global: bool = False
    kidnap_to_twin: bool = False
    kidnap_to_lookalike: bool = False
    global_at_lookalike: bool = False

    def __post_init__(self) -> None:
        name, eq, target = self.policy.partition("=")
        if self.policy not in policy_names() and not (eq and name and target):
            raise ValueError(
                f"EpisodeSpec.policy: unknown policy {self.policy!r:.60}; choose one of {list(policy_names())}, "
                "NAME=PATH (a saved policy) or NAME=MODULE:CLASS (your own)"
            )
        for name in ("tracking", "kidnap_after_global", "kidnap_to_twin", "kidnap_to_lookalike", "global_at_lookalike"):
            if not isinstance(getattr(self, name), (bool, np.bool_)):
                raise ValueError(f"EpisodeSpec.{name} must be True or False, got {getattr(self, name)!r:.60}")
        if not is_int(self.n_steps) or self.n_steps < 1:
            raise ValueError(f"EpisodeSpec.n_steps must be an integer >= 1, got {self.n_steps!r:.60}")
        if not is_int(self.kidnap_at_step) or self.kidnap_at_step < 0:
            raise ValueError(
                f"EpisodeSpec.kidnap_at_step must be an integer >= 0 (0: no kidnap), got {self.kidnap_at_step!r:.60}"
            )
        if self.kidnap_after_global:
            if self.kidnap_at_step < 1:
                raise ValueError(
                    "EpisodeSpec.kidnap_after_global needs kidnap_at_step >= 1 (the step of the teleport), "
                    f"got {self.kidnap_at_step}"
                )
            if self.tracking:
                raise ValueError("EpisodeSpec.kidnap_after_global starts from a global belief: tracking must be False")
        if self.kidnap_to_twin:
            if self.kidnap_at_step < 2 or self.kidnap_after_global:
                raise ValueError(
                    "EpisodeSpec.kidnap_to_twin needs a tracking start and kidnap_at_step >= 2 (the pose after step "
                    f"kidnap_at_step - 1 is mirrored), got kidnap_at_step={self.kidnap_at_step}, "
                    f"kidnap_after_global={self.kidnap_after_global}"
                )
            if self.layout not in TWIN_CENTRES:
                raise ValueError(
                    f"EpisodeSpec.kidnap_to_twin needs a layout of {sorted(TWIN_CENTRES)}, got {self.layout!r:.60}"
                )
        if self.kidnap_to_lookalike and (self.kidnap_at_step < 2 or self.kidnap_after_global or self.kidnap_to_twin):
            raise ValueError(
                "EpisodeSpec.kidnap_to_lookalike needs a tracking start and kidnap_at_step >= 2 (the pose after step "
                f"kidnap_at_step - 1 is matched), and not kidnap_to_twin, got kidnap_at_step={self.kidnap_at_step}, "
                f"kidnap_after_global={self.kidnap_after_global}, kidnap_to_twin={self.kidnap_to_twin}"
            )
        if self.global_at_lookalike and (self.kidnap_at_step or self.tracking):
            raise ValueError(
                "EpisodeSpec.global_at_lookalike is a global start without a kidnap: kidnap_at_step must be 0 and "
                f"tracking False, got kidnap_at_step={self.kidnap_at_step}, tracking={self.tracking}"
            )
        if self.kidnap_at_step > self.n_steps:
            raise ValueError(
                f"EpisodeSpec.kidnap_at_step {self.kidnap_at_step} is after the last step (n_steps {self.n_steps}): "
                "no step after the kidnap would be scored"
            )

    @property
    def row(self) -> str:
        """The table row this episode belongs to (a layout file's row is named by its file name's stem)."""
        name = Path(self.layout).stem if self.layout.endswith(LAYOUT_FILE_SUFFIXES) else self.layout
        if self.scenario != "nominal":
            name += f"_{self.scenario}"
        if self.kidnap_after_global:
            return name + "_global_kidnap"
        if self.kidnap_to_twin:
            return name + "_twin_kidnap"
        if self.kidnap_to_lookalike:
            return name + "_lookalike_kidnap"
        if self.global_at_lookalike:
            return name + "_lookalike_global"
        return name + ("_kidnap" if self.kidnap_at_step else "_tracking" if self.tracking else "")

    @property
    def reset_options(self) -> dict | None:
        """The ``options`` of the episode's ``env.reset``. `run_episode` finds the target of a ``kidnap_to_twin`` or
        ``kidnap_to_lookalike`` episode by running the steps before the kidnap and adds it as ``kidnap_pose``; a
        ``global_at_lookalike`` episode's options are ``{"pose": target}`` (None here)."""
        if self.kidnap_after_global:
            return {"kidnap_at_step": self.kidnap_at_step}  # global start, teleport at kidnap_at_step
        if self.kidnap_at_step:
            return {"tracking": True, "kidnap_at_step": self.kidnap_at_step}
        return {"tracking": True} if self.tracking else None


def policy_names() -> tuple[str, ...]:
    """Every policy an episode can run: `POLICIES` (the rows' own, the same episodes as ever) and the other
    policies of `agents.policies.POLICIES` (the viewpoint planner ``"viewpoint"``, ...)."""
    from agents.policies import POLICIES as AGENT_POLICIES

    return (*POLICIES, *sorted(set(AGENT_POLICIES) - set(POLICIES)))


def make_policy(name: str, seed: int):
    """A fresh policy callable ``obs -> action`` (discrete actions) of `POLICIES`."""
    from agents.baselines import TURN_LEFT, RandomWalk, WallFollowExplorer

    if name == "random":
        return RandomWalk(np.random.default_rng(10_000 + seed))
    if name == "wall_follow":
        return WallFollowExplorer()
    if name == "spin":
        return lambda obs: TURN_LEFT
    raise ValueError(f"unknown policy {name!r}; choose one of {POLICIES}")


def driver(name: str, seed: int, env):
    """``(env, act)``: the env to step and a fresh ``act(obs) -> action`` for policy ``name``: `make_policy`'s for
    `POLICIES`; else the policy built with ``seed`` (an `agents.policies` name, ``NAME=PATH`` of a saved policy or
    ``NAME=MODULE:CLASS`` of your own, as ``evaluate_active`` takes them), its ``wrap(env)`` (which the planners read
    the filter through, and a learned policy its observation) and its ``act``, reset for a new episode."""
    if name in POLICIES:
        return env, make_policy(name, seed)
    if name not in policy_names() and "=" not in name:
        raise ValueError(f"unknown policy {name!r}; choose one of {list(policy_names())}")
    from agents.experiments.evaluate_active import make_policy as make_named_policy

    policy = make_named_policy(name, seed)
    wrapped = policy.wrap(env)
    policy.reset()
    return wrapped, policy.act


def score_steps(converged: Sequence[bool], near: Sequence[bool], kidnap_at_step: int = 0) -> dict:
    """Score one episode from its beliefs: ``converged[t]`` / ``near[t]`` say whether the belief
    after step ``t`` was converged / had its estimate within 0.5 m and 15 deg of the truth; index 0
    is the belief after the reset (never scored; after a kidnap at step 1 it is the belief the
    teleport finds). ``kidnap_at_step`` 0: no kidnap, every step is scored; ``K`` >= 1: steps ``K``
    on are scored and ``steps`` counts from ``K`` (step ``K`` is 1).

    Returns ``outcome``, ``steps``, ``ever_wrong``, ``converged_steps``,
    ``converged_correct_steps`` (see the module docstring) and, for a kidnap (else None),
    ``reconverged_wrong``, ``pre_kidnap_success`` and ``converged_at_kidnap``.
    """
    conv = [bool(c) for c in converged]
    ok = [bool(x) for x in near]
    n = len(conv) - 1
    if len(ok) != len(conv) or n < 1:
        raise ValueError(
            f"converged and near need the same length >= 2 (the reset and the steps), got {len(conv)} and {len(ok)}"
        )
    k = kidnap_at_step
    if not is_int(k) or not 0 <= k <= n:
        raise ValueError(f"kidnap_at_step must be an integer in [0, {n}] (the steps scored), got {k!r:.60}")
    first = max(k, 1)
    first_success = None
    ever_wrong = False
    n_conv = n_ok = 0
    for t in range(first, n + 1):
        n_conv += conv[t]
        n_ok += conv[t] and ok[t]
        if first_success is None:
            if conv[t] and ok[t]:
                first_success = t - first + 1
            elif conv[t]:
                ever_wrong = True
    if first_success is not None:
        outcome = "success"
    elif conv[n]:
        outcome = "wrong"
    else:
        outcome = "unconverged"
    out = {
        "outcome": outcome,
        "steps": first_success,
        "ever_wrong": ever_wrong,
        "converged_steps": int(n_conv),
        "converged_correct_steps": int(n_ok),
        "reconverged_wrong": None,
        "pre_kidnap_success": None,
        "converged_at_kidnap": None,
    }
    if k:
        left = not conv[k - 1]  # the belief has left the place the teleport found it converged at
        again_wrong = False
        for t in range(k, n + 1):
            if conv[t] and ok[t]:
                break  # the first success: what follows is not a recovery
            if not conv[t]:
                left = True
            elif left:
                again_wrong = True
                break
        out.update(
            reconverged_wrong=again_wrong,
            pre_kidnap_success=any(conv[t] and ok[t] for t in range(1, k)),
            converged_at_kidnap=conv[k - 1],
        )
    return out


ENV_ID_KEY = "env_id"
"""The key of a variant dict (`agents.experiments.evaluate_relocalizer`) that names the registered ``SemReloc-vN``
id its episodes run in (the newest without it); its other keys are overrides of that id's relocalizer."""


def variant_parts(variant: dict) -> tuple[str, dict]:
    """``(env id or "" for the newest, relocalizer overrides)`` of a variant dict (`ENV_ID_KEY`)."""
    overrides = {k: v for k, v in variant.items() if k != ENV_ID_KEY}
    env_id = variant.get(ENV_ID_KEY, "")
    if ENV_ID_KEY in variant and not (isinstance(env_id, str) and env_id):
        raise ValueError(f"{ENV_ID_KEY} must name a SemReloc id (a non-empty string), got {env_id!r:.60}")
    return env_id, overrides


def env_class(env_id: str = ""):
    """The env class of a registered ``SemReloc-vN`` id (``""``: the newest, `SemRelocEnv`); ValueError for
    another id (`semreloc_env.semreloc_class`)."""
    from semreloc_env import semreloc_class
    from semreloc_env.envs.semreloc import SemRelocEnv

    return semreloc_class(env_id) if env_id else SemRelocEnv


def run_episode(spec: EpisodeSpec) -> dict:
    """Run one episode; returns a plain dict (the spec's fields plus the outcome fields).

    Every one of the ``n_steps`` steps is run, also after the env said ``terminated`` (a success,
    which in a global-start kidnap episode may come before the kidnap).
    """
    base = env_class(spec.env_id)(
        layout=spec.layout,
        layout_seed=spec.layout_seed,
        scenario=spec.scenario,
        relocalizer=dict(spec.mcl) or None,
        **spec.env_kwargs,
    )
    k = spec.kidnap_at_step
    options = spec.reset_options
    if spec.kidnap_to_twin or spec.kidnap_to_lookalike or spec.global_at_lookalike:
        # the episode is deterministic: its steps before the kidnap (KIDNAP_STEP's for a global row) say where it goes
        env, policy = driver(spec.policy, spec.seed, base)
        obs, info = env.reset(seed=spec.seed, options={"tracking": True})
        for _ in range((KIDNAP_STEP if spec.global_at_lookalike else k) - 1):
            obs, _, _, _, info = env.step(policy(obs))
        if spec.kidnap_to_twin:
            target = twin_image(spec.layout, info["pose"])
        else:
            target = lookalike_kidnap_pose(base, info["pose"], spec.seed).pose.tolist()
        options = {"pose": target} if spec.global_at_lookalike else {**options, "kidnap_pose": target}
    env, policy = driver(spec.policy, spec.seed, base)
    obs, info = env.reset(seed=spec.seed, options=options)
    cfg = base.mcl_config

    def near(err: dict) -> bool:
        return err["position"] < 0.5 and err["heading"] < math.radians(15.0)

    converged, close = [bool(info["belief"]["converged"])], [near(info["pose_error"])]
    collisions = 0
    cpu = 0.0
    n_particles, errors = [], []
    diag = dict.fromkeys(
        ("recovery_steps", "reinit_steps", "audits", "audit_adds", "stale_audits", "stale_audit_adds", "surprises"), 0
    )
    kidnapped_at = None
    w_at_kidnap = (info["mcl"]["w_slow"], info["mcl"]["w_fast"])
    max_p_inject = 0.0
    updates_since_kidnap = 0
    for t in range(1, spec.n_steps + 1):
        c0 = time.process_time()
        obs, _, _, _, info = env.step(policy(obs))  # terminated is ignored: the belief is watched on
        cpu += time.process_time() - c0
        collisions += bool(info["collided"])
        n_particles.append(info["belief"]["n_particles"])
        converged.append(bool(info["belief"]["converged"]))
        close.append(near(info["pose_error"]))
        if info["kidnapped"] and kidnapped_at is None:
            kidnapped_at = t
        m = info["mcl"]
        if k and t == k - 1:
            w_at_kidnap = (m["w_slow"], m["w_fast"])
        if k and t < k:
            continue
        errors.append(info["pose_error"]["position"])
        if not k:
            continue
        updates_since_kidnap += bool(m["updated"])
        if m.get("surprise"):  # the relocalizer restarted its audit window at this update
            updates_since_kidnap = cfg.audit_window
            diag["surprises"] += 1
        max_p_inject = max(max_p_inject, float(m["p_inject"]))
        diag["recovery_steps"] += bool(m["p_inject"] > cfg.proposal_frac)
        diag["reinit_steps"] += bool(m["recovered"])
        ratio = m.get("audit_log_ratio")
        if ratio is not None and math.isfinite(ratio):
            added = m["n_audit_injected"] > 0
            stale = updates_since_kidnap < cfg.audit_window  # some of the window's scans predate the teleport
            diag["audits"] += 1
            diag["audit_adds"] += added
            diag["stale_audits"] += stale
            diag["stale_audit_adds"] += stale and added
    base.close()
    out = asdict(spec)
    out.update(row=spec.row, **score_steps(converged, close, k))
    out.update(
        collisions=int(collisions),
        cpu_s_per_step=cpu / spec.n_steps,
        mean_particles=float(np.mean(n_particles)),
        final_particles=int(n_particles[-1]),
        median_error_m=float(np.median(errors)) if errors else math.nan,
        kidnapped_at=kidnapped_at,
        kidnap_pose=options.get("kidnap_pose") if options else None,
        start_pose=options.get("pose") if options else None,
    )
    if k:
        out.update(
            w_slow_at_kidnap=float(w_at_kidnap[0]),
            w_fast_at_kidnap=float(w_at_kidnap[1]),
            max_p_inject=max_p_inject,
            **{name: int(v) for name, v in diag.items()},
        )
    return out


wilson = wilson_interval  # Wilson 95 % interval of ``k / n`` (filters.experiments.stats)


def summarize(results: list[dict]) -> dict:
    """Rates with Wilson intervals, median steps, calibration and CPU time over episodes.

    ``reconverged_wrong`` and ``pre_kidnap_success`` are ``(count, episodes, rate, low, high)`` over
    the kidnap episodes among ``results`` (``(0, 0, nan, nan, nan)`` if none)."""
    n = len(results)
    out = {"episodes": n}
    for o in ("success", "wrong", "unconverged"):
        k = sum(r["outcome"] == o for r in results)
        out[o] = (k / n if n else math.nan, *wilson(k, n))
    k = sum(r["ever_wrong"] for r in results)
    out["ever_wrong"] = (k / n if n else math.nan, *wilson(k, n))
    for name in ("reconverged_wrong", "pre_kidnap_success"):  # kidnap episodes only (older results lack them)
        scored = [r[name] for r in results if r.get(name) is not None]
        k, m = sum(scored), len(scored)
        out[name] = (k, m, k / m if m else math.nan, *wilson(k, m))
    steps = [r["steps"] for r in results if r["steps"] is not None]
    out["median_steps"] = float(np.median(steps)) if steps else math.nan
    conv = sum(r["converged_steps"] for r in results)
    ok = sum(r["converged_correct_steps"] for r in results)
    out["calibration"] = (ok / conv if conv else math.nan, *wilson(ok, conv))
    out["converged_steps"] = conv
    out["cpu_ms_per_step"] = 1e3 * float(np.mean([r["cpu_s_per_step"] for r in results])) if n else math.nan
    out["mean_particles"] = float(np.mean([r["mean_particles"] for r in results])) if n else math.nan
    out["median_error_m"] = float(np.median([r["median_error_m"] for r in results])) if n else math.nan
    return out


def pct(t: tuple[float, float, float]) -> str:
    """``"12 % [8–17]"`` from ``(rate, low, high)`` (one decimal below 10 %)."""
    r, lo, hi = t
    if math.isnan(r):
        return "—"
    mid = f"{100 * r:.1f}" if 0 < r < 0.1 else f"{100 * r:.0f}"
    d = 1 if hi < 0.1 else 0
    return f"{mid} % [{100 * lo:.{d}f}–{100 * hi:.{d}f}]"


def count_pct(t: tuple[int, int, float, float, float]) -> str:
    """``"3 · 5.0 % [1.7–14]"`` from ``(count, n, rate, low, high)``; ``"—"`` when ``n`` is 0."""
    k, n, *rest = t
    return "—" if not n else f"{k} · {pct(tuple(rest))}"


def save_jsonl(results: list[dict], path) -> None:
    with open(path, "w") as f:
        for r in results:
            f.write(json.dumps(r) + "\n")


def load_jsonl(path) -> list[dict]:
    with open(path) as f:
        return [json.loads(line) for line in f if line.strip()]


# ----------------------------------------------------------------------------- real robot log
_LOG_CACHE: dict = {}


def _log_and_map(path: str):
    """The CARMEN log and the map built from its corrected poses (cached per process)."""
    if path not in _LOG_CACHE:
        from filters.mapping.from_scans import map_from_scans
        from filters.robot_data.carmen import read_carmen

        log = read_carmen(path)
        _LOG_CACHE[path] = (log, map_from_scans(log.poses, log.scans(), resolution_m=0.05))
    return _LOG_CACHE[path]


def _log_config(variant: dict):
    """The relocalizer of a variant (`variant_parts`: its env id's default with its overrides), lidar only."""
    from semreloc_env.config import coerce_config
    from semreloc_env.envs.semreloc import MCLConfig

    env_id, overrides = variant_parts(variant)
    default = env_class(env_id).default_relocalizer
    return coerce_config(MCLConfig, {**overrides, "use_semantic": False}, "relocalizer", default)


def log_trial(job: tuple) -> dict:
    """One global-localization trial on a log: ``(path, label, mcl_overrides, start, n_steps)``.

    The relocalizer is the env's default with ``mcl_overrides`` and ``use_semantic=False`` (a log
    has no semantic scans); the trial is seeded by its start scan.
    """
    from filters.robot_data.replay import global_localization_trials

    path, label, variant, start, n_steps = job
    cfg = _log_config(variant)
    log, grid = _log_and_map(path)
    c0 = time.process_time()
    (r,) = global_localization_trials(log, grid, cfg, [start], n_steps, rng_seed=start)
    return {
        "label": label,
        "start": start,
        "outcome": r.outcome,
        "steps": r.steps,
        "pos_error_m": r.pos_error_m,
        "cpu_s": time.process_time() - c0,
    }


def log_tracking(job: tuple) -> dict:
    """Tracking over a whole log: ``(path, label, mcl_overrides, seed)`` -> error statistics."""
    from filters.robot_data.replay import track

    path, label, variant, seed = job
    cfg = _log_config(variant)
    log, grid = _log_and_map(path)
    c0 = time.process_time()
    tr = track(log, grid, cfg, rng_seed=seed)
    return {"label": label, "seed": seed, **tr.stats(), "cpu_s_per_scan": (time.process_time() - c0) / len(log)}
