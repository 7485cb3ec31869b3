"""Long random soak of both envs, every step checked; exit status 1 if anything failed.

The command lives in `semreloc_env.tools.soak` (also installed as ``semreloc-soak``);
``python scripts/soak.py --help`` lists every option.
"""

from semreloc_env.tools.soak import main

if __name__ == "__main__":
    raise SystemExit(main())
