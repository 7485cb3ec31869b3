"""Train a network to act as the viewpoint planner by DAgger (out/dagger/policy.zip).

The command lives in `agents.tools.imitate_active` (also installed as ``semreloc-imitate-active``);
``python scripts/imitate_active.py --help`` lists every option.
"""

from agents.tools.imitate_active import main

if __name__ == "__main__":
    raise SystemExit(main())
