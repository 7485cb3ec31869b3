"""Build the maps of a layout from a simulated mapping run and save them as ROS map_server files.

Writes ``<out>/<name>.yaml`` + ``.pgm`` (occupancy) and ``<name>.semantic.yaml`` +
one ``.pgm`` per class (see docs/maps.md), plus ``<name>.perfect.*`` (the rasterised
layout) with ``--perfect``. Prints how well the mapped grids match the layout.

    python scripts/build_maps.py --layout lab --out maps/        # or: semreloc-build-maps --layout lab
    python scripts/build_maps.py --layout my_floor.yaml --seed 3 --out maps/

Use the result with ``gym.make("SemReloc-v22", layout="lab", map_source="maps/lab.yaml")``
(procedural layouts come from the newest generator, as ``SemReloc-v22``'s do).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np

from filters.experiments.cli import command, parse
from filters.mapping.metrics import semantic_surface_quality
from filters.mapping.ros_map import save_map
from semreloc_env.envs.base import check_seed_use
from semreloc_env.layouts import PROCEDURAL_LAYOUTS, check_layout_option, get_layout
from semreloc_env.mapping_run import build_maps, mapping_path, narrow_drive
from semreloc_env.rasterize import rasterize


@dataclass(frozen=True)
class Args:
    layout: str = "lab"
    """built-in name or layout file"""
    layout_seed: int = 0
    """seed of procedural layouts"""
    seed: int = 0
    """seed of the sensor noise during the mapping run"""
    resolution: float = 0.05
    """cell size, metres"""
    perfect: bool = False
    """also save the rasterised layout"""
    out: str = "maps"
    """output folder"""
    mapping_version: Literal["2", "3", "4", "5", "6"] = "6"
    """the mapping run's version (semreloc_env.mapping_run.MAPPING_RUN_VERSIONS): 6 as SemReloc-v22 to v12, 5 as v11 (a
    drive that skips passages between its lattice's rows and columns), 4 as v10 (also space beyond the lidar's range
    from every surface left unknown), 3 as v8 and v9 (stray class cells kept), 2 as v7 and older (its camera beams
    without a return cleared the classes along their range)"""

    def __post_init__(self) -> None:
        if not 0 < self.resolution < float("inf"):
            raise ValueError(f"resolution must be a finite number > 0 m, got {self.resolution}")
        # an unknown name or a bad file: refused here, not after the imports of a mapping run
        name = check_layout_option(self.layout, seed=self.layout_seed).name
        check_seed_use(self.layout, self.layout_seed, "nominal")  # as gym.make: a seed a file would ignore
        if name in ("", ".", "..") or Path(name).name != name or "\\" in name:
            raise ValueError(
                f"layout: its name {name!r} cannot name the map files in --out (it is empty or a path); "
                "give the layout a plain name"
            )


@command
def main(argv: list[str] | None = None) -> int:
    """The command: parse ``argv`` (default ``sys.argv[1:]``), map the layout, save and score the maps."""
    args = parse(Args, argv, __doc__)
    layout = get_layout(args.layout, seed=args.layout_seed)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    grid = build_maps(
        layout, rng=np.random.default_rng(args.seed), resolution_m=args.resolution, version=args.mapping_version
    )
    # the seed names a procedural layout's maps; a file's own name (even one starting "procedural") names its maps
    name = f"{layout.name}_{args.layout_seed}" if args.layout in PROCEDURAL_LAYOUTS else layout.name
    seconds = time.perf_counter() - t0
    path = save_map(grid, out / f"{name}.yaml")
    truth = rasterize(layout, args.resolution)
    n_poses = len(mapping_path(layout, narrow=narrow_drive(args.mapping_version)))
    print(f"{layout.name}: {n_poses} poses mapped in {seconds:.1f} s -> {path}")
    for cls, q in semantic_surface_quality(grid, truth).items():
        print(
            f"  {cls:10s} IoU vs visible surface {q['iou']:.2f}, precision {q['precision']:.2f}, "
            f"recall {q['recall']:.2f} (1-cell tolerance)"
        )
    if args.perfect:
        save_map(truth, out / f"{name}.perfect.yaml")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
