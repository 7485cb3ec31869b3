"""Speed of semreloc, in one run: kernels, env steps, stages, resets, maps, scaling, PPO.

The command lives in `agents.tools.bench` (also installed as ``semreloc-bench``);
``python scripts/bench.py --help`` lists every option.
"""

from agents.tools.bench import main

if __name__ == "__main__":
    raise SystemExit(main())
