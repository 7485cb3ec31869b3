"""Evaluation of the relocalizer inside ``SemReloc``: seeded episodes, outcomes, calibration.

An *episode* runs a fixed policy for ``n_steps`` steps in one layout from one seed, without
stopping at success, so the belief is watched after it claims convergence. Per episode
(from the env's ``info`` only; the true pose is used for scoring, never by the policy):

* **success**: at some step the belief was converged with its estimate within 0.5 m and
  15 deg of the truth (what ``SemReloc`` terminates on); ``steps`` is the first such step.
  In a kidnap episode only steps after the kidnap count, and ``steps`` counts from it.
* **wrong**: no success, and the last step's belief is converged elsewhere.
* **unconverged**: neither. (The three partition the episodes, as in `agents.metrics`.)
* **ever_wrong**: some step before the first success had a converged, wrong belief.
* **calibration counts**: ``converged_steps`` and ``converged_correct_steps`` over all steps
  (post-kidnap steps only, in a kidnap episode): calibration = correct / converged.
* **cpu_s_per_step**: process CPU time per env step (the machine may be shared).
* **median_error_m**: median position error of the estimate over the scored steps.

Each episode's result depends only on its `EpisodeSpec`, so many of them run with
`filters.experiments.runner.run_jobs` (``run_jobs(run_episode, specs, runner)``) give the
same results sequentially, in a process pool or on Ray. `log_trial` and `log_tracking`
are the jobs of the ACES-log rows. The command is `agents.experiments.evaluate_relocalizer`.
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import asdict, dataclass, field

import numpy as np

from filters.experiments.stats import wilson_interval

POLICIES = ("random", "spin", "wall_follow")


@dataclass(frozen=True)
class EpisodeSpec:
    """One evaluation episode. ``mcl`` holds ``MCLConfig`` overrides (applied to the env's
    default relocalizer); ``kidnap_at_step`` > 0 makes it a tracking-then-kidnap episode, and
    ``tracking`` a tracking episode (the belief starts at the true pose; only the error and the
    step time are of interest)."""

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
    label: str = ""

    @property
    def row(self) -> str:
        """The table row this episode belongs to."""
        name = self.layout if self.layout not in ("procedural", "procedural_sym") else f"{self.layout}"
        if self.scenario != "nominal":
            name += f"_{self.scenario}"
        return name + ("_kidnap" if self.kidnap_at_step else "_tracking" if self.tracking else "")


def make_policy(name: str, seed: int):
    """A fresh policy callable ``obs -> action`` (discrete actions)."""
    from agents.baselines import TURN_LEFT, RandomWalk, WallFollowExplorer

    if name == "random":
        return RandomWalk(np.random.default_rng(10_000 + seed))
    if name == "wall_follow":
        return WallFollowExplorer()
    if name == "spin":
        return lambda obs: TURN_LEFT
    raise ValueError(f"unknown policy {name!r}; choose one of {POLICIES}")


def run_episode(spec: EpisodeSpec) -> dict:
    """Run one episode; returns a plain dict (the spec's fields plus the outcome fields)."""
    from semreloc_env.envs.semreloc import SemRelocEnv

    env = SemRelocEnv(
        layout=spec.layout,
        layout_seed=spec.layout_seed,
        scenario=spec.scenario,
        relocalizer=dict(spec.mcl) or None,
        **spec.env_kwargs,
    )
    if spec.kidnap_at_step:
        options = {"tracking": True, "kidnap_at_step": spec.kidnap_at_step}
    else:
        options = {"tracking": True} if spec.tracking else None
    obs, info = env.reset(seed=spec.seed, options=options)
    policy = make_policy(spec.policy, spec.seed)
    first_success = None
    ever_wrong = False
    conv = conv_ok = 0
    collisions = 0
    cpu = 0.0
    n_particles, errors = [], []
    for t in range(1, spec.n_steps + 1):
        c0 = time.process_time()
        obs, _, _, _, info = env.step(policy(obs))
        cpu += time.process_time() - c0
        collisions += bool(info["collided"])
        n_particles.append(info["belief"]["n_particles"])
        if spec.kidnap_at_step and t < spec.kidnap_at_step:
            continue
        err = info["pose_error"]
        errors.append(err["position"])
        near = err["position"] < 0.5 and err["heading"] < math.radians(15.0)
        converged = info["belief"]["converged"]
        conv += converged
        conv_ok += converged and near
        if converged and near and first_success is None:
            first_success = t - (spec.kidnap_at_step - 1 if spec.kidnap_at_step else 0)
        if converged and not near and first_success is None:
            ever_wrong = True
    env.close()
    final_converged = info["belief"]["converged"]
    if first_success is not None:
        outcome = "success"
    elif final_converged:
        outcome = "wrong"
    else:
        outcome = "unconverged"
    out = asdict(spec)
    out.update(
        row=spec.row,
        outcome=outcome,
        steps=first_success,
        ever_wrong=ever_wrong,
        converged_steps=int(conv),
        converged_correct_steps=int(conv_ok),
        collisions=int(collisions),
        cpu_s_per_step=cpu / spec.n_steps,
        mean_particles=float(np.mean(n_particles)),
        final_particles=int(n_particles[-1]),
        median_error_m=float(np.median(errors)) if errors else math.nan,
    )
    return out


wilson = wilson_interval  # Wilson 95 % interval of ``k / n`` (filters.experiments.stats)


def summarize(results: list[dict]) -> dict:
    """Rates with Wilson intervals, median steps, calibration and CPU time over episodes."""
    n = len(results)
    out = {"episodes": n}
    for o in ("success", "wrong", "unconverged"):
        k = sum(r["outcome"] == o for r in results)
        out[o] = (k / n if n else math.nan, *wilson(k, n))
    k = sum(r["ever_wrong"] for r in results)
    out["ever_wrong"] = (k / n if n else math.nan, *wilson(k, n))
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


def log_trial(job: tuple) -> dict:
    """One global-localization trial on a log: ``(path, label, mcl_overrides, start, n_steps)``.

    The relocalizer is the env's default with ``mcl_overrides`` and ``use_semantic=False`` (a log
    has no semantic scans); the trial is seeded by its start scan.
    """
    from filters.robot_data.replay import global_localization_trials
    from semreloc_env.config import coerce_config
    from semreloc_env.envs.semreloc import DEFAULT_RELOCALIZER, MCLConfig

    path, label, overrides, start, n_steps = job
    cfg = coerce_config(MCLConfig, {**overrides, "use_semantic": False}, "relocalizer", DEFAULT_RELOCALIZER)
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
    from semreloc_env.config import coerce_config
    from semreloc_env.envs.semreloc import DEFAULT_RELOCALIZER, MCLConfig

    path, label, overrides, seed = job
    cfg = coerce_config(MCLConfig, {**overrides, "use_semantic": False}, "relocalizer", DEFAULT_RELOCALIZER)
    log, grid = _log_and_map(path)
    c0 = time.process_time()
    tr = track(log, grid, cfg, rng_seed=seed)
    return {"label": label, "seed": seed, **tr.stats(), "cpu_s_per_scan": (time.process_time() - c0) / len(log)}
