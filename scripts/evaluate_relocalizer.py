"""Evaluate the relocalizer (before/after, global relocalization, kidnapping, tracking, the ACES log).

The command lives in `agents.experiments.evaluate_relocalizer` (also installed as
``semreloc-evaluate-relocalizer``); ``python scripts/evaluate_relocalizer.py --help`` lists every option.
"""

from agents.experiments.evaluate_relocalizer import main

if __name__ == "__main__":
    raise SystemExit(main())
