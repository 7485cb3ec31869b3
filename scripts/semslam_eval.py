"""SemSlam pose and landmark error over seeds, against dead reckoning (prints a Markdown table).

The command lives in `agents.experiments.semslam_eval` (also installed as ``semreloc-semslam-eval``);
``python scripts/semslam_eval.py --help`` lists every option.
"""

from agents.experiments.semslam_eval import main

if __name__ == "__main__":
    raise SystemExit(main())
