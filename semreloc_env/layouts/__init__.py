"""Layouts: world geometry as validated plain data (built-in, procedural, or from files)."""

from __future__ import annotations

import os
import warnings
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from filters.numbers import is_int

from .builtin import BUILTIN_LAYOUTS
from .layout import CLASS_NAMES, Layout, LayoutError, SemanticObject, layout_from_dict, load_layout, point_in_polygon
from .procedural import (
    PROCEDURAL_VERSION,
    CorridorParams,
    ProceduralParams,
    RingParams,
    corridor_layout,
    half_turn_asymmetry,
    lookalike_layout,
    period_shift_distance,
    procedural_layout,
    quarter_turn_asymmetry,
    ring_layout,
)

__all__ = [
    "CLASS_NAMES",
    "CorridorParams",
    "LAYOUT_NAMES",
    "LAYOUT_PATH_ENV",
    "PROCEDURAL_VERSION",
    "find_layout_file",
    "Layout",
    "LayoutError",
    "ProceduralParams",
    "RingParams",
    "SemanticObject",
    "check_layout_option",
    "check_layout_seed",
    "corridor_layout",
    "get_layout",
    "half_turn_asymmetry",
    "layout_from_dict",
    "load_layout",
    "lookalike_layout",
    "period_shift_distance",
    "point_in_polygon",
    "procedural_layout",
    "quarter_turn_asymmetry",
    "ring_layout",
]

BUILTIN_LAYOUTS_NAMES = tuple(BUILTIN_LAYOUTS)
PROCEDURAL_LAYOUTS = ("procedural", "procedural_sym", "procedural_lookalike", "procedural_ring", "procedural_corridor")
LAYOUT_NAMES = (*BUILTIN_LAYOUTS, *PROCEDURAL_LAYOUTS)


LAYOUT_PATH_ENV = "SEMRELOC_LAYOUT_PATH"
"""Environment variable: folders (``os.pathsep``-separated) searched for layouts given by name."""


def find_layout_file(name: str) -> Path | None:
    """The first ``<folder>/<name>.yaml``, ``.yml`` or ``.json`` over the folders of ``$SEMRELOC_LAYOUT_PATH``
    (``os.pathsep``-separated, searched in order), or None. Names with a path separator are not searched."""
    if not name or "/" in name or os.sep in name:
        return None
    for folder in filter(None, os.environ.get(LAYOUT_PATH_ENV, "").split(os.pathsep)):
        for ext in (".yaml", ".yml", ".json"):
            p = Path(folder) / f"{name}{ext}"
            if p.is_file():
                return p
    return None


def _warn_if_shadowed(name: str) -> None:
    """Warn when a file on the search path has the name of a built-in or procedural layout: the name means
    the built-in one, never the file (which its path still reaches)."""
    if not os.environ.get(LAYOUT_PATH_ENV):
        return
    found = find_layout_file(name)
    if found is not None:
        warnings.warn(
            f"layout {name!r} is the built-in one: {found} on ${LAYOUT_PATH_ENV} has its name and is not used "
            "(built-in and procedural names come first); give the file's path to use it, or rename it",
            UserWarning,
            stacklevel=3,
        )


def _is_ros_map(spec) -> bool:
    if not isinstance(spec, (str, Path)) or Path(spec).suffix.lower() not in (".yaml", ".yml"):
        return False
    from ..maps import is_ros_map_file  # lazy: maps imports this package

    return is_ros_map_file(spec)


def check_layout_option(spec, option: str = "layout", seed: int = 0) -> Layout:
    """`get_layout` of ``spec``; ValueError ``"<option>: <the LayoutError>"`` if it does not resolve: a command's
    argument check, which its parser turns into a usage error before any work."""
    try:
        return get_layout(spec, seed=seed)
    except LayoutError as e:
        raise ValueError(f"{option}: {e}") from None


def check_layout_seed(value) -> int:
    """``layout_seed`` as an int; ValueError unless it is an integer >= 0 (not a bool, float or string)."""
    if is_int(value) and value >= 0:
        return int(value)
    raise ValueError(f"layout_seed must be an integer >= 0, got {type(value).__name__} {value!r:.60}")


def get_layout(
    spec: str | Path | Mapping | Layout, seed: int = 0, procedural_version: int = PROCEDURAL_VERSION
) -> Layout:
    """Resolve a layout spec to a validated `Layout`.

    Args:
        spec: a built-in name (``"lab"``, ``"twin_rooms"``, ``"three_rooms"``, ``"open_hall"``), ``"procedural"``,
            ``"procedural_sym"``, ``"procedural_lookalike"``, ``"procedural_ring"`` (`ring_layout`) or
            ``"procedural_corridor"`` (`corridor_layout`; all generated from ``seed``), the name of a
            layout file on the search path ``$SEMRELOC_LAYOUT_PATH`` (`find_layout_file`; the built-in and
            procedural names come first: a file of such a name warns and is not used), a path
            to a ``.json`` / ``.yaml`` file, a dict in the layout format, a Layout (returned as is), or a
            map: a ROS map ``.yaml`` / ``.yml`` (a YAML with an ``image`` key) or a
            `GridMap`, whose world is traced from its occupied
            cells (`semreloc_env.map_world.layout_from_map`).
        seed: seed of the procedural generator, an integer >= 0 (`check_layout_seed`; ignored otherwise).
        procedural_version: the procedural generator's version (`PROCEDURAL_VERSION`, the newest,
            or 1: lookalike layouts as ``SemReloc-v2`` and older draw them, without the check
            that their corridor objects break the half turn; ignored for other specs).
    """
    if procedural_version not in (1, 2) or isinstance(procedural_version, bool):
        raise ValueError(f"procedural_version must be 1 or 2, got {procedural_version!r:.60}")
    if isinstance(spec, str) and spec in PROCEDURAL_LAYOUTS:
        seed = check_layout_seed(seed)
    if isinstance(spec, str) and not spec.strip():
        raise LayoutError(f"the layout name is empty: give one of {list(LAYOUT_NAMES)}, a file path or a dict")
    if isinstance(spec, (str, Path)) and str(spec).startswith("~"):
        spec = Path(spec).expanduser()
    if isinstance(spec, Layout):
        return spec
    from filters.mapping.grid import GridMap

    if isinstance(spec, GridMap) or _is_ros_map(spec):
        from ..map_world import layout_from_map  # lazy: map_world and maps import this package
        from ..maps import load_env_map

        # a class region with no simple outline left out of the world, as the registered envs have always built it
        if isinstance(spec, GridMap):
            return layout_from_map(spec, untraced_as_walls=False)
        return layout_from_map(load_env_map(spec), name=Path(spec).stem, untraced_as_walls=False)
    if isinstance(spec, Mapping):
        return layout_from_dict(spec)
    if isinstance(spec, str) and spec in LAYOUT_NAMES:
        _warn_if_shadowed(spec)
    if isinstance(spec, str) and spec in BUILTIN_LAYOUTS:
        return layout_from_dict(BUILTIN_LAYOUTS[spec]())
    if isinstance(spec, str) and spec == "procedural_ring":
        return layout_from_dict(ring_layout(np.random.default_rng(seed)))
    if isinstance(spec, str) and spec == "procedural_corridor":
        return layout_from_dict(corridor_layout(np.random.default_rng(seed)))
    if isinstance(spec, str) and spec in PROCEDURAL_LAYOUTS:
        params = ProceduralParams(
            symmetric=spec == "procedural_sym",
            lookalike=spec == "procedural_lookalike",
            min_asymmetry_m=ProceduralParams.min_asymmetry_m if procedural_version >= 2 else 0.0,
        )
        return layout_from_dict(procedural_layout(np.random.default_rng(seed), params))
    if isinstance(spec, (str, Path)):
        path = Path(spec).expanduser()
        if path.suffix.lower() in (".json", ".yaml", ".yml") and not path.exists() and find_layout_file(path.stem):
            raise LayoutError(
                f"layout file not found: {path} (a name with an extension is a path; the layouts on "
                f"${LAYOUT_PATH_ENV} are named without one: {path.stem!r} is {find_layout_file(path.stem)})"
            )
        if path.suffix.lower() in (".json", ".yaml", ".yml") or path.is_file():
            return load_layout(path)
        found = find_layout_file(str(spec))
        if found is not None:  # also when a folder of that name lies in the working folder; a ROS map is one too
            return get_layout(found, seed, procedural_version)
        if path.exists():
            return load_layout(path)  # a folder, say: its error names it
        raise LayoutError(
            f"unknown layout {str(spec)!r}: not one of {list(LAYOUT_NAMES)}, not a layout file path, and no "
            f"<name>.yaml/.yml/.json in ${LAYOUT_PATH_ENV} ({os.environ.get(LAYOUT_PATH_ENV, 'unset')})"
        )
    raise LayoutError(f"a layout must be a name, a file path, a dict or a Layout, got {type(spec).__name__}")
