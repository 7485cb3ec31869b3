"""Train a PPO policy for active relocalization (out/active/policy.zip).

The command lives in `agents.tools.train_active` (also installed as ``semreloc-train-active``);
``python scripts/train_active.py --help`` lists every option.
"""

from agents.tools.train_active import main

if __name__ == "__main__":
    raise SystemExit(main())
