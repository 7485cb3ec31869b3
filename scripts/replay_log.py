"""Replay a robot log (CARMEN) through the Monte Carlo localizer against its corrected poses.

The command lives in `filters.tools.replay_log` (also installed as ``semreloc-replay-log``);
``python scripts/replay_log.py --help`` lists every option.
"""

from filters.tools.replay_log import main

if __name__ == "__main__":
    raise SystemExit(main())
