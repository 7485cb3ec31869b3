"""Train PPO for active relocalization and compare it with the hand-written explorers.

Trains a PPO (`agents.features.SemRelocPolicy`, SB3's ``MultiInputPolicy``; `agents.train.train`; observation =
lidar, semantic pseudo-laser, odometry and the filter's belief summary, never the true pose), saves it, then
evaluates PPO, `agents.baselines.WallFollowExplorer` and `agents.baselines.RandomWalk`
on the *same* episode seeds (same start poses, noise and filter draws) and prints a table of
success rate, wrong-convergence rate, median steps to converge and median final error.

The training options are the fields of `agents.train.TrainConfig` (``--config.<field>``);
the env options (``--layout``, ``--lidar-only``, ``--map-source``, ``--n-particles``,
``--max-episode-steps``) make its ``env_kwargs``. Everything is written under ``--config.log-dir``
(default ``out/ppo``): ``model.zip``, ``progress.csv``, TensorBoard events
(``tensorboard --logdir out/ppo``), ``checkpoints/``, ``eval/`` (periodic ``EvalCallback``
evaluations, ``best_model.zip``), ``results.json`` and ``results.md`` (the command and the table;
``--load`` appends a re-evaluation). ``--doc PATH`` also writes the report to ``PATH``, but never
over an existing file (it appends re-evaluations): hand-written notes in ``docs/rl.md`` are safe.

The defaults train for about 10-20 min on two CPU cores. Example::

    python scripts/train_ppo.py --config.total-timesteps 100000 --config.n-envs 4 --layout lab

(``semreloc-train-ppo`` is the same command; ``--help`` lists every option.)
"""

from __future__ import annotations

import json
import math
import sys
import time
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np

from agents.train import TrainConfig
from filters.experiments.cli import command, command_line, parse, usage_error
from filters.experiments.stats import wilson_interval

DEFAULT_CONFIG = TrainConfig(
    total_timesteps=200_000,
    log_dir="out/ppo",
    progress_bar=True,
    checkpoint_every=50_000,
    eval_every=20_000,
    eval_episodes=10,
    eval_seed=10_050,
)
"""The command's training defaults (``env_kwargs`` comes from the env options)."""


@dataclass(frozen=True)
class Args:
    """Train PPO for active relocalization and compare it with the hand-written explorers."""

    config: TrainConfig = field(default_factory=lambda: DEFAULT_CONFIG)
    """the training run; log_dir is the run's folder (model.zip, progress.csv, TensorBoard events,
    checkpoints/, eval/, results.json/.md); eval_* are the periodic EvalCallback evaluations"""
    layout: str = "lab"
    """layout: a name of semreloc_env.layouts.LAYOUT_NAMES (lab, twin_rooms, three_rooms, open_hall,
    procedural, procedural_sym, procedural_lookalike, procedural_ring, procedural_corridor), a name on
    $SEMRELOC_LAYOUT_PATH or a .json/.yaml file"""
    lidar_only: bool = False
    """run the relocalizer without the semantic factor (semantic=False)"""
    map_source: str = "mapping"
    """map the filter uses: mapping (the simulated mapping run's), perfect (the rasterised layout), another
    layout (a built-in name or a layout file: its mapping run's map, as for a changed world) or a ROS map
    (.yaml) that fits the layout"""
    n_particles: int = 1000
    """particles of the relocalizer"""
    max_episode_steps: int = 200
    """time limit per episode (steps of 0.1 s), for training and evaluation alike"""
    eval_episodes: int = 50
    """final evaluation episodes per policy"""
    eval_seed: int = 10_000
    """first final-evaluation episode seed (episode i: eval_seed + i)"""
    doc: str = ""
    """also write the report to this Markdown file, which must not exist yet ('' to skip; --load appends)"""
    load: str = ""
    """skip training: evaluate this saved model.zip with the env options given (the report says where they
    differ from those its run's results.json records) and append the
    table under a 'Re-evaluation' heading to results.md in --config.log-dir (the model's own run folder only
    if that is the one given) and to --doc, instead of rewriting them"""

    def __post_init__(self) -> None:
        if self.config.log_dir is None:
            raise ValueError("config.log_dir: the command needs a run folder")
        if self.config.env_kwargs:
            raise ValueError("config.env_kwargs: set the env through layout, lidar_only, map_source, ...")
        from semreloc_env.maps import check_map_source_name, names_a_layout

        for name in ("layout", "map_source"):  # a file name that names no file
            v = getattr(self, name)
            if v.lower().endswith((".json", ".yaml", ".yml")) and not Path(v).expanduser().is_file():
                raise ValueError(f"{name} {v!r}: no such file")
        if not names_a_layout(self.layout):
            from semreloc_env.layouts import LAYOUT_NAMES

            raise ValueError(f"layout must be one of {sorted(LAYOUT_NAMES)} or a layout file, got {self.layout!r}")
        check_map_source_name(self.map_source)
        if self.n_particles < 1 or self.max_episode_steps < 1 or self.eval_episodes < 1:
            raise ValueError(
                f"n_particles, max_episode_steps and eval_episodes must be >= 1, got "
                f"{self.n_particles}, {self.max_episode_steps}, {self.eval_episodes}"
            )
        if self.load and not (Path(self.load).is_file() or Path(self.load + ".zip").is_file()):
            raise ValueError(f"load: no model file {self.load!r} (a model.zip that train_ppo.py saved)")
        final = range(self.eval_seed, self.eval_seed + self.eval_episodes)
        if not self.load and self.config.eval_every is not None and self.config.eval_seed in final:
            raise ValueError(
                f"config.eval_seed {self.config.eval_seed} (the EvalCallback's env) lies among the final "
                f"evaluation's seeds {final.start}..{final.stop - 1}; pick one outside, e.g. {final.stop}"
            )

    @property
    def out(self) -> Path:
        """The run's folder (``config.log_dir``)."""
        return Path(str(self.config.log_dir))


ENV_OPTIONS = ("layout", "lidar_only", "map_source", "n_particles", "max_episode_steps")
"""The fields of `Args` that make the env (`env_kwargs_of`)."""


def trained_env_options(model: str | Path) -> dict | None:
    """The env options (`ENV_OPTIONS`, and ``env_id``) of the run that saved ``model``, from the ``results.json`` of
    its run folder (the model's folder, or the one above for ``checkpoints/`` and ``eval/``); None if none says."""
    model = Path(model)
    for folder in (model.parent, model.parent.parent):
        f = folder / "results.json"
        try:
            saved = json.loads(f.read_text())["args"]
        except (OSError, ValueError, KeyError, TypeError):
            continue
        if isinstance(saved, dict) and all(k in saved for k in ENV_OPTIONS):
            env_id = saved.get("config", {}).get("env_id") if isinstance(saved.get("config"), dict) else None
            return {"env_id": env_id, **{k: saved[k] for k in ENV_OPTIONS}}
    return None


def env_options_note(args: Args) -> str:
    """How ``--load``'s env options compare with those the model was trained with (`trained_env_options`)."""
    now = {"env_id": args.config.env_id, **{k: getattr(args, k) for k in ENV_OPTIONS}}
    listed = ", ".join(f"{k} {v!r}" for k, v in now.items())
    trained = trained_env_options(args.load)
    if trained is None:
        return f"env options {listed} (the model's training options are unknown: no results.json beside it)"
    differ = {k: trained[k] for k in now if trained[k] is not None and trained[k] != now[k]}
    if not differ:
        return f"the env options of its training run ({listed})"
    return f"env options {listed}; **other than its training run's**: " + ", ".join(
        f"{k} {v!r}" for k, v in differ.items()
    )


def env_kwargs_of(args: Args) -> dict:
    """The ``gym.make`` keyword arguments of the env options."""
    return {
        "layout": args.layout,
        "semantic": not args.lidar_only,
        "map_source": args.map_source,
        "relocalizer": {"n_particles": args.n_particles},
        "max_episode_steps": args.max_episode_steps,
    }


def _fmt(v, pct: bool = False, digits: int = 2) -> str:
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "-"
    return f"{100 * v:.0f} %" if pct else f"{v:.{digits}f}"


def _rate(r: dict, key: str) -> str:
    """A rate of an `agents.train.evaluate` summary in %, with its Wilson 95 % interval when the summary says over
    how many episodes (older results.json files do not)."""
    text = _fmt(r[key], True)
    n = r.get("episodes")
    if text == "-" or not n:
        return text
    lo, hi = wilson_interval(round(r[key] * n), n)
    return f"{text} [{100 * lo:.0f}, {100 * hi:.0f}]"


def results_table(rows: dict[str, dict]) -> str:
    """Markdown table of `agents.train.evaluate` summaries, one row per policy; the rates with their Wilson 95 %
    intervals over the episodes."""
    head = (
        "| policy | success [95 %] | wrong convergence | unconverged | median steps to converge "
        "| median final error (m) | mean return |\n|---|---|---|---|---|---|---|\n"
    )
    body = "".join(
        f"| {name} | {_rate(r, 'success_rate')} | {_rate(r, 'wrong_convergence_rate')} "
        f"| {_rate(r, 'unconverged_rate')} | {_fmt(r['median_steps_to_converge'], digits=0)} "
        f"| {_fmt(r['median_final_position_error_m'])} | {_fmt(r['mean_return'])} |\n"
        for name, r in rows.items()
    )
    return head + body


@command
def main(argv: list[str] | None = None) -> int:
    """The command: parse ``argv`` (default ``sys.argv[1:]``), train (or ``--load``), evaluate, write the report."""
    run(parse(Args, argv, __doc__), sys.argv[1:] if argv is None else argv)
    return 0


def run(args: Args, argv: list[str] | None = None) -> dict:
    """Train (or load), evaluate the three policies, write results.json/.md (and ``args.doc``); returns
    the record written to results.json. ``argv`` is the command line recorded in the report."""
    from agents.baselines import RandomWalk, WallFollowExplorer
    from agents.train import env_for, evaluate, train

    out = args.out
    doc = Path(args.doc) if args.doc else None
    if doc is not None and doc.exists() and not args.load:
        raise SystemExit(
            usage_error("train_ppo", f"--doc {doc} exists: refusing to overwrite it (pick a new file, or omit --doc)")
        )
    held = [n for n in ("model.zip", "results.json", "progress.csv") if (out / n).exists()]
    if held and not args.load:  # a new run would replace its model and mix TensorBoard events with it
        raise SystemExit(
            usage_error(
                "train_ppo",
                f"--config.log-dir {out} holds a training run already ({', '.join(held)}): choose a new folder, "
                f"or evaluate that run's model again with --load {out}/model.zip",
            )
        )
    env_kwargs = env_kwargs_of(args)
    config = replace(args.config, env_kwargs=env_kwargs)
    if args.load:  # checked before the folder is made: a model that cannot run here leaves nothing behind
        from agents.learned import load_model

        try:
            model, train_s = load_model(args.load, "PPO", device=config.device), 0.0
            env_for(model, env_kwargs, config.env_id).close()
        except (OSError, ValueError) as e:
            raise SystemExit(usage_error("train_ppo", f"--load {args.load}: {e}")) from None
    out.mkdir(parents=True, exist_ok=True)
    if args.load:
        print(f"[train_ppo] loaded {args.load}", file=sys.stderr, flush=True)
        note = env_options_note(args)
        if "other than" in note:
            print(f"[train_ppo] note: evaluating with {note.replace('**', '')}", file=sys.stderr, flush=True)
    else:
        print(
            f"[train_ppo] training PPO for {config.total_timesteps} steps on {env_kwargs}", file=sys.stderr, flush=True
        )
        t0 = time.perf_counter()
        model = train(config)
        train_s = time.perf_counter() - t0
        model.save(out / "model.zip")
        model.get_env().close()
        print(f"[train_ppo] trained in {train_s:.0f} s; saved {out / 'model.zip'}", file=sys.stderr, flush=True)

    policies = {
        "PPO": model,
        "WallFollowExplorer": WallFollowExplorer(),
        "RandomWalk": RandomWalk(np.random.default_rng(args.eval_seed)),
    }
    rows, eval_s = {}, {}
    for name, policy in policies.items():
        t1 = time.perf_counter()
        rows[name] = evaluate(
            policy, env_kwargs, n_episodes=args.eval_episodes, seed=args.eval_seed, env_id=config.env_id
        )
        eval_s[name] = time.perf_counter() - t1
        print(f"[train_ppo] evaluated {name} in {eval_s[name]:.0f} s: {rows[name]}", file=sys.stderr, flush=True)

    table = results_table(rows)
    print(table)
    command = command_line("scripts/train_ppo.py", [] if argv is None else argv)
    record = {
        "args": asdict(args),
        "command": command,
        "train_seconds": train_s,
        "eval_seconds": eval_s,
        "results": rows,
    }
    (out / ("results_reeval.json" if args.load else "results.json")).write_text(json.dumps(record, indent=2))
    for path in (out / "results.md", doc):
        if path is None:
            continue
        if args.load:
            _append_reevaluation(path, args, command, table)
        else:
            _write_doc(path, args, command, table, train_s)
    return record


def _append_reevaluation(path: Path, args: Args, command: str, table: str) -> None:
    text = f"""
## Re-evaluation of `{args.load}`

```bash
{command.strip()}
```

{args.eval_episodes} episodes per policy, seeds `{args.eval_seed}` to `{args.eval_seed + args.eval_episodes - 1}`,
{env_options_note(args)}.

{table}"""
    with path.open("a") as f:
        f.write(text)


def _write_doc(path: Path, args: Args, command: str, table: str, train_s: float) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    text = f"""# Active relocalization with PPO

Command, set-up and tables generated by `scripts/train_ppo.py` (rerun the command to regenerate;
`--load` appends a re-evaluation). Notes at the end, if any, are written by hand about the recorded run.

## Command

```bash
{command.strip()}
```

Layout `{args.layout}`, semantic factor {"off" if args.lidar_only else "on"}, map `{args.map_source}`,
{args.n_particles} particles, time limit {args.max_episode_steps} steps (0.1 s each).
PPO (`agents.features.SemRelocPolicy` + `agents.features.SemRelocExtractor`, observation = lidar, semantic
pseudo-laser, odometry and the belief summary of `semreloc_env.wrappers.BeliefObservation`)
trained for {args.config.total_timesteps} steps on {args.config.n_envs} envs, seed {args.config.seed}, \
in {train_s / 60:.1f} min on CPU.

## Results

{args.eval_episodes} evaluation episodes per policy, episode `i` reset with seed `{args.eval_seed} + i`, so
every policy starts from the same poses with the same noise and filter draws (PPO acts greedily).

{table}
* **success**: the episode ends with the belief converged within 0.5 m and 15 deg of the truth
  (the env's termination); **wrong convergence**: it ends converged somewhere else;
  **unconverged**: the belief is still spread at the time limit. The three sum to 100 %.
* **median steps to converge**: over successful episodes only. **final error**: belief mean vs truth.
* Definitions: `agents/metrics.py`; evaluation: `agents.train.evaluate`.
"""
    path.write_text(text)


if __name__ == "__main__":
    raise SystemExit(main())
