"""Train PPO for active relocalization on ``SemReloc-v1`` and compare it with the hand-written explorers.

Trains a ``MultiInputPolicy`` PPO (:func:`agents.train.train`; observation = lidar, semantic
pseudo-laser, odometry and the filter's belief summary, never the true pose), saves it, then
evaluates PPO, :class:`agents.baselines.WallFollowExplorer` and :class:`agents.baselines.RandomWalk`
on the *same* episode seeds (same start poses, noise and filter draws) and prints a table of
success rate, wrong-convergence rate, median steps to converge and median final error.

Everything is written under ``--out`` (default ``out/ppo``): ``model.zip``, ``progress.csv``,
TensorBoard events (``tensorboard --logdir out/ppo``), ``checkpoints/``, ``eval/`` (periodic
``EvalCallback`` evaluations, ``best_model.zip``), ``results.json`` and ``results.md`` (the command
and the table; ``--load`` appends a re-evaluation). ``--doc PATH`` also writes the report to
``PATH``, but never over an existing file (it appends re-evaluations): hand-written notes in
``docs/rl.md`` are safe.

The defaults train for about 10-20 min on two CPU cores. Example::

    python scripts/train_ppo.py --total-timesteps 100000 --n-envs 4 --layout lab

Run ``python scripts/train_ppo.py --help`` for every option.
"""

from __future__ import annotations

import argparse
import json
import math
import shlex
import sys
import time
from dataclasses import asdict, dataclass, fields
from pathlib import Path

import numpy as np


@dataclass(frozen=True)
class Args:
    layout: str = "lab"
    """layout: lab, twin_rooms, procedural, procedural_sym or a .json/.yaml file"""
    lidar_only: bool = False
    """run the relocalizer without the semantic factor (semantic=False)"""
    map_source: str = "mapping"
    """map the filter uses: mapping (simulated mapping run) or perfect (rasterised layout)"""
    n_particles: int = 1000
    """particles of the relocalizer"""
    max_episode_steps: int = 200
    """time limit per episode (steps of 0.1 s), for training and evaluation alike"""
    n_envs: int = 4
    """parallel training envs"""
    subproc: bool = False
    """one process per env (SubprocVecEnv) instead of one process (DummyVecEnv)"""
    batched: bool = False
    """the batched env (R robots in one process, SB3 adapter) instead of DummyVecEnv"""
    total_timesteps: int = 200_000
    """PPO training budget in env steps (summed over envs)"""
    n_steps: int = 256
    """PPO rollout length per env"""
    batch_size: int = 256
    """PPO minibatch size"""
    n_epochs: int = 4
    """PPO epochs per rollout"""
    learning_rate: float = 3e-4
    """Adam learning rate"""
    ent_coef: float = 0.01
    """PPO entropy bonus"""
    seed: int = 0
    """training seed (PPO and env k gets seed + k)"""
    eval_episodes: int = 50
    """evaluation episodes per policy"""
    eval_seed: int = 10_000
    """first evaluation episode seed (disjoint from the training seeds' first episodes)"""
    out: str = "out/ppo"
    """the run's folder: model.zip, progress.csv, TensorBoard events, checkpoints/, eval/, results.json/.md"""
    doc: str = ""
    """also write the report to this Markdown file, which must not exist yet ('' to skip; --load appends)"""
    verbose: bool = False
    """print SB3's log table after every rollout"""
    device: str = "cpu"
    """torch device of the policy: cpu, cuda or auto"""
    checkpoint_every: int = 50_000
    """env steps between checkpoints in OUT/checkpoints (0: none)"""
    eval_every: int = 20_000
    """env steps between EvalCallback evaluations in OUT/eval (0: none)"""
    eval_every_episodes: int = 10
    """episodes per EvalCallback evaluation"""
    no_progress_bar: bool = False
    """hide SB3's progress bar"""
    load: str = ""
    """skip training: evaluate this saved model.zip (trained with the same env options) and append the
    table to --doc under a 'Re-evaluation' heading instead of rewriting it"""


def parse_args(argv: list[str] | None = None) -> Args:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    docs = _field_docs()
    for f in fields(Args):
        flag = "--" + f.name.replace("_", "-")
        if f.type in ("bool", bool):
            p.add_argument(flag, action="store_true", help=docs.get(f.name, ""))
        else:
            p.add_argument(
                flag, type=type(f.default), default=f.default, help=f"{docs.get(f.name, '')} (default: {f.default})"
            )
    return Args(**vars(p.parse_args(argv)))


def _field_docs() -> dict[str, str]:
    """The attribute docstrings of :class:`Args` (the string under each field), by field name."""
    import ast
    import inspect

    tree = ast.parse(inspect.getsource(Args))
    body = tree.body[0].body
    out = {}
    for a, b in zip(body, body[1:]):
        if isinstance(a, ast.AnnAssign) and isinstance(b, ast.Expr) and isinstance(b.value, ast.Constant):
            out[a.target.id] = str(b.value.value)
    return out


def env_kwargs_of(args: Args) -> dict:
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


def results_table(rows: dict[str, dict]) -> str:
    """Markdown table of :func:`agents.train.evaluate` summaries, one row per policy."""
    head = (
        "| policy | success | wrong convergence | unconverged | median steps to converge "
        "| median final error (m) | mean return |\n|---|---|---|---|---|---|---|\n"
    )
    body = "".join(
        f"| {name} | {_fmt(r['success_rate'], True)} | {_fmt(r['wrong_convergence_rate'], True)} "
        f"| {_fmt(r['unconverged_rate'], True)} | {_fmt(r['median_steps_to_converge'], digits=0)} "
        f"| {_fmt(r['median_final_position_error_m'])} | {_fmt(r['mean_return'])} |\n"
        for name, r in rows.items()
    )
    return head + body


def main(argv: list[str] | None = None) -> dict:
    args = parse_args(argv)
    from agents.baselines import RandomWalk, WallFollowExplorer
    from agents.train import TrainConfig, evaluate, train

    out = Path(args.out)
    doc = Path(args.doc) if args.doc else None
    if doc is not None and doc.exists() and not args.load:
        raise SystemExit(f"--doc {doc} exists: refusing to overwrite it (pick a new file, or omit --doc)")
    out.mkdir(parents=True, exist_ok=True)
    env_kwargs = env_kwargs_of(args)
    config = TrainConfig(
        env_kwargs=env_kwargs,
        n_envs=args.n_envs,
        vec_env="subproc" if args.subproc else ("batched" if args.batched else "dummy"),
        total_timesteps=args.total_timesteps,
        seed=args.seed,
        n_steps=args.n_steps,
        batch_size=args.batch_size,
        n_epochs=args.n_epochs,
        learning_rate=args.learning_rate,
        ent_coef=args.ent_coef,
        log_dir=str(out),
        verbose=int(args.verbose),
        progress_bar=not args.no_progress_bar,
        device=args.device,
        checkpoint_every=args.checkpoint_every or None,
        eval_every=args.eval_every or None,
        eval_episodes=args.eval_every_episodes,
        eval_seed=args.eval_seed + args.eval_episodes,
    )
    if args.load:
        from stable_baselines3 import PPO

        model, train_s = PPO.load(args.load, device=args.device), 0.0
        print(f"[train_ppo] loaded {args.load}", file=sys.stderr, flush=True)
    else:
        print(f"[train_ppo] training PPO for {args.total_timesteps} steps on {env_kwargs}", file=sys.stderr, flush=True)
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
        rows[name] = evaluate(policy, env_kwargs, n_episodes=args.eval_episodes, seed=args.eval_seed)
        eval_s[name] = time.perf_counter() - t1
        print(f"[train_ppo] evaluated {name} in {eval_s[name]:.0f} s: {rows[name]}", file=sys.stderr, flush=True)

    table = results_table(rows)
    print(table)
    cli = sys.argv[1:] if argv is None else argv
    command = "python scripts/train_ppo.py " + " ".join(shlex.quote(a) for a in cli)
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
same env options.

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
PPO (`MultiInputPolicy` + `agents.features.SemRelocExtractor`, observation = lidar, semantic
pseudo-laser, odometry and the belief summary of `semreloc_env.wrappers.BeliefObservation`)
trained for {args.total_timesteps} steps on {args.n_envs} envs, seed {args.seed}, in {train_s / 60:.1f} min on CPU.

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
    main()
