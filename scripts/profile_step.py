"""Where the time of a default ``SemReloc-v22`` step goes: CPU time per stage (cProfile).

The command lives in `agents.tools.profile_step` (also installed as ``semreloc-profile-step``);
``python scripts/profile_step.py --help`` lists every option.
"""

from agents.tools.profile_step import main

if __name__ == "__main__":
    raise SystemExit(main())
