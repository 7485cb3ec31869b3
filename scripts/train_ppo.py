"""Train PPO for active relocalization and compare it with the hand-written explorers (out/ppo/).

The command lives in `agents.tools.train_ppo` (also installed as ``semreloc-train-ppo``);
``python scripts/train_ppo.py --help`` lists every option.
"""

from agents.tools.train_ppo import main

if __name__ == "__main__":
    raise SystemExit(main())
