"""Reproduce paper 004: global relocalization, lidar-only vs lidar + semantic -> docs/paper004.md.

The command lives in `agents.experiments.paper004` (also installed as ``semreloc-repro-paper004``);
``python scripts/repro_paper004.py --help`` lists every option.
"""

from agents.experiments.paper004 import main

if __name__ == "__main__":
    raise SystemExit(main())
