"""Reproduce paper 000 (SLAM_WOCPF): Tables 1-2 and a K sweep -> docs/paper000.md.

The command lives in `filters.experiments.paper000` (also installed as ``semreloc-repro-paper000``);
``python scripts/repro_paper000.py --help`` lists every option.
"""

from filters.experiments.paper000 import main

if __name__ == "__main__":
    raise SystemExit(main())
