"""Train a PPO policy for active relocalization (`agents.train_active`) and save it for `agents.load_policy`.

Every option is a field of `agents.train_active.ActiveTrainConfig` (`--config.<field>`); everything the
run writes goes under `--out`: config.json, progress.csv, TensorBoard events
(`tensorboard --logdir <out>`), checkpoints/, policy.zip, timing.json, learning_curve.png. Evaluate the
result with `python scripts/evaluate_active.py --policies info_gain wall_follow ppo=<out>/policy.zip`.

The documented run (docs/active.md):
    python scripts/train_active.py --out out/active --config.time-budget-s 3000 --config.total-timesteps 400000
"""

from __future__ import annotations

from dataclasses import dataclass, field

from filters.experiments.cli import command, parse, usage_error

from ..train_active import ActiveTrainConfig, RunFolderError, train_active


@dataclass(frozen=True)
class Args:
    config: ActiveTrainConfig = field(default_factory=ActiveTrainConfig)
    """the training run"""
    out: str = "out/active"
    """output folder (created; nothing is written elsewhere)"""
    resume: str | None = None
    """a checkpoint .zip (or policy.zip) to continue from; its run's options, repeat and observation must
    be given again (they shape the policy's spaces); other changed settings are printed"""


@command
def main(argv: list[str] | None = None) -> int:
    """The command: parse ``argv`` (default ``sys.argv[1:]``), train, save; prints the policy's path."""
    args = parse(Args, argv, __doc__)
    try:
        path = train_active(args.config, args.out, resume=args.resume)
    except RunFolderError as e:  # raised before any env is built
        return usage_error("train_active", e)
    print(f"saved {path}")
    return 0
