"""Train a PPO policy for active relocalization (agents.train_active) and save it for agents.load_policy.

Every option is a field of `agents.train_active.ActiveTrainConfig` (`--config.<field>`); everything the
run writes goes under `--out`: config.json, progress.csv, TensorBoard events
(`tensorboard --logdir <out>`), checkpoints/, policy.zip, timing.json. Evaluate the result with
`python scripts/evaluate_active.py --policies info_gain,wall_follow,learned=<out>/policy.zip`.

Example (the documented run, docs/active.md):
    python scripts/train_active.py --out out/active --config.time-budget-s 3300
"""

from __future__ import annotations

from dataclasses import dataclass, field

import tyro

from agents.train_active import ActiveTrainConfig, train_active


@dataclass(frozen=True)
class Args:
    config: ActiveTrainConfig = field(default_factory=ActiveTrainConfig)
    """the training run"""
    out: str = "out/active"
    """output folder (created; nothing is written elsewhere)"""
    resume: str | None = None
    """a checkpoint .zip to continue from"""


def main(argv: list[str] | None = None) -> None:
    args = tyro.cli(Args, args=argv, description=__doc__)
    path = train_active(args.config, args.out, resume=args.resume)
    print(f"saved {path}")


if __name__ == "__main__":
    main()
