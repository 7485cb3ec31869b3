"""Main demo: a global relocalization on the lab, drawn and plotted (out/demo/).

The command lives in `agents.tools.demo` (also installed as ``semreloc-demo``);
``python scripts/demo.py --help`` lists every option.
"""

from agents.tools.demo import main

if __name__ == "__main__":
    raise SystemExit(main())
