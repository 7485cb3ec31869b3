"""Build the maps of a layout from a simulated mapping run and save them as ROS map_server files.

The command lives in `semreloc_env.tools.build_maps` (also installed as ``semreloc-build-maps``);
``python scripts/build_maps.py --help`` lists every option.
"""

from semreloc_env.tools.build_maps import main

if __name__ == "__main__":
    raise SystemExit(main())
