"""Reproduce paper 001 (IFA-PF): Tables 1 and 3 -> docs/paper001.md.

The command lives in `filters.experiments.paper001` (also installed as ``semreloc-repro-paper001``);
``python scripts/repro_paper001.py --help`` lists every option.
"""

from filters.experiments.paper001 import main

if __name__ == "__main__":
    raise SystemExit(main())
