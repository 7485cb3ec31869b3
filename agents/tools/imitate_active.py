"""Train a network to act as the viewpoint planner (DAgger, `agents.imitation`) and save it for `agents.load_policy`.

Every option is a field of `agents.imitation.ImitationConfig` (`--config.<field>`; the envs and the
network under `--config.train.<field>`, as in `scripts/train_active.py`); everything the run writes
goes under `--out`: config.json, imitation.csv, learning_curve.png, timing.json, policy.zip. Evaluate
the result with `python scripts/evaluate_active.py --policies viewpoint dagger=<out>/policy.zip`.

The documented run (docs/active.md):
    python scripts/imitate_active.py --out out/dagger
"""

from __future__ import annotations

from dataclasses import dataclass, field

from filters.experiments.cli import command, parse, usage_error

from ..imitation import ImitationConfig, imitate
from ..train_active import RunFolderError


@dataclass(frozen=True)
class Args:
    config: ImitationConfig = field(default_factory=ImitationConfig)
    """the imitation run"""
    out: str = "out/dagger"
    """output folder (created; nothing is written elsewhere)"""


@command
def main(argv: list[str] | None = None) -> int:
    """The command: parse ``argv`` (default ``sys.argv[1:]``), imitate, save; prints the policy's path."""
    args = parse(Args, argv, __doc__)
    try:
        path = imitate(args.config, args.out)
    except RunFolderError as e:  # raised before any env is built
        return usage_error("imitate_active", e)
    print(f"saved {path}")
    return 0
