"""Evaluate active-relocalization policies on the same held-out (layout, start) pairs (out/evaluate_active/).

The command lives in `agents.experiments.evaluate_active` (also installed as ``semreloc-evaluate-active``);
``python scripts/evaluate_active.py --help`` lists every option.
"""

from agents.experiments.evaluate_active import main

if __name__ == "__main__":
    raise SystemExit(main())
