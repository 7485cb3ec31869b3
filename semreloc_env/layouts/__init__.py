"""Layouts: world geometry as validated plain data (built-in, procedural, or from files)."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np

from .builtin import BUILTIN_LAYOUTS
from .layout import CLASS_NAMES, Layout, LayoutError, SemanticObject, layout_from_dict, load_layout, point_in_polygon
from .procedural import ProceduralParams, lookalike_layout, procedural_layout

__all__ = [
    "CLASS_NAMES",
    "Layout",
    "LayoutError",
    "ProceduralParams",
    "SemanticObject",
    "get_layout",
    "layout_from_dict",
    "load_layout",
    "lookalike_layout",
    "point_in_polygon",
    "procedural_layout",
]

BUILTIN_LAYOUTS_NAMES = tuple(BUILTIN_LAYOUTS)
PROCEDURAL_LAYOUTS = ("procedural", "procedural_sym", "procedural_lookalike")
LAYOUT_NAMES = (*BUILTIN_LAYOUTS, *PROCEDURAL_LAYOUTS)


def get_layout(spec: str | Path | Mapping | Layout, seed: int = 0) -> Layout:
    """Resolve a layout spec to a validated :class:`Layout`.

    Args:
        spec: a built-in name (``"lab"``, ``"twin_rooms"``), ``"procedural"``,
            ``"procedural_sym"`` or ``"procedural_lookalike"`` (generated from ``seed``), a path to a ``.json`` /
            ``.yaml`` file, a dict in the layout format, or a Layout (returned as is).
        seed: seed of the procedural generator (ignored otherwise).
    """
    if isinstance(spec, Layout):
        return spec
    if isinstance(spec, Mapping):
        return layout_from_dict(spec)
    if isinstance(spec, str) and spec in BUILTIN_LAYOUTS:
        return layout_from_dict(BUILTIN_LAYOUTS[spec]())
    if isinstance(spec, str) and spec in PROCEDURAL_LAYOUTS:
        params = ProceduralParams(symmetric=spec == "procedural_sym", lookalike=spec == "procedural_lookalike")
        return layout_from_dict(procedural_layout(np.random.default_rng(seed), params))
    if isinstance(spec, (str, Path)):
        path = Path(spec)
        if path.suffix.lower() in (".json", ".yaml", ".yml") or path.exists():
            return load_layout(path)
        raise LayoutError(f"unknown layout {str(spec)!r}: not one of {list(LAYOUT_NAMES)} and not a layout file path")
    raise LayoutError(f"a layout must be a name, a file path, a dict or a Layout, got {type(spec).__name__}")
