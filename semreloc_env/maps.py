"""Where an env's map comes from: a mapping run (default), the rasterised layout, a map file, or another layout.

Mapping-run maps are cached in memory (per process) and on disk, keyed by the layout's
content, the sensor parameters, the resolution and the mapping run's version (`MAPPING_RUN_VERSIONS`),
so a process that meets a layout again loads its map in milliseconds. The disk cache lives
in ``$SEMRELOC_CACHE_DIR/maps`` (default ``$XDG_CACHE_HOME/semreloc/maps``, else
``~/.cache/semreloc/maps``; off without a home folder); set ``SEMRELOC_CACHE_DIR`` to an empty string
to switch it off. Files are written atomically, with the permissions the umask gives, and hold their
key: an unreadable file, or one holding another key, is rebuilt and replaced. A folder that cannot be
written warns once per process; the maps are then rebuilt in every process. Files are compressed (15-130 kB
a map) and nothing is evicted: delete the folder to clear it.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import os
import re
import tempfile
import time
import warnings
from collections import OrderedDict
from pathlib import Path

import numpy as np

from filters.mapping.grid import GridMap
from filters.mapping.ros_map import load_map

from .config import CameraParams, LidarParams
from .layouts import CLASS_NAMES, LAYOUT_NAMES, Layout, find_layout_file, get_layout
from .rasterize import rasterize

MAP_SOURCES = ("mapping", "perfect")


MEMORY_CACHE_SIZE = 16
"""Mapped GridMaps kept in memory per process (least recently used dropped first)."""

_memory: OrderedDict[str, GridMap] = OrderedDict()
_unwritable: set[Path] = set()  # cache folders a save failed in (warned once per process)


def cache_dir() -> Path | None:
    """The on-disk map cache folder (absolute), or None if switched off (``SEMRELOC_CACHE_DIR=""``) or, with
    neither ``SEMRELOC_CACHE_DIR`` nor ``XDG_CACHE_HOME`` set, when there is no home folder (``HOME`` unset or
    empty and no user entry, as in containers run under an arbitrary uid)."""
    try:  # "~" with no home folder raises RuntimeError
        root = os.environ.get("SEMRELOC_CACHE_DIR")
        if root is not None:
            return Path(root).expanduser().absolute() / "maps" if root else None
        xdg = os.environ.get("XDG_CACHE_HOME")
        if xdg and Path(xdg).expanduser().is_absolute():  # the XDG spec ignores a relative value
            return Path(xdg).expanduser() / "semreloc" / "maps"
        home = Path(os.environ.get("HOME") or pwd_home())  # an empty HOME counts as unset
    except (KeyError, OSError, RuntimeError):
        return None
    return home / ".cache" / "semreloc" / "maps" if home.is_absolute() else None


def pwd_home() -> str:
    """The home folder of the process's user from the user database (KeyError without an entry)."""
    import pwd

    return pwd.getpwuid(os.getuid()).pw_dir


def map_key(
    layout: Layout, lidar: LidarParams, camera: CameraParams, resolution_m: float = 0.05, version: str | None = None
) -> str:
    """Hex key of a mapping-run map: layout content, sensor parameters, resolution, the mapping run's version
    (`semreloc_env.mapping_run.MAPPING_RUN_VERSIONS`; None: the newest) and the versions of the libraries its
    drive and sensors run on (`mapping_libraries`: an upgrade may move the drive, so it rebuilds the maps)."""
    from .mapping_run import MAPPING_RUN_VERSION

    text = repr(
        (
            MAPPING_RUN_VERSION if version is None else version,
            _layout_text(layout),
            lidar,
            camera,
            float(resolution_m),
            CLASS_NAMES,
            *mapping_libraries(),
        )
    )
    return hashlib.blake2b(text.encode(), digest_size=16).hexdigest()


def mapping_libraries() -> tuple[str, ...]:
    """``name==version`` of the libraries a mapping run's result depends on: pymunk (the drive's physics),
    NumPy (its draws and arithmetic) and numba (the compiled ray casts)."""
    import numba
    import pymunk

    return (f"pymunk=={pymunk.version}", f"numpy=={np.__version__}", f"numba=={numba.__version__}")


def _layout_text(layout: Layout) -> str:
    """Every field of ``layout`` exactly (``repr`` of floats round-trips; a GridMap field, as in
    worlds traced from maps, by its content hash: ``repr`` would abbreviate its arrays)."""
    from filters.localization.likelihood_field import grid_content_key

    parts = [type(layout).__name__]
    for f in dataclasses.fields(layout):
        v = getattr(layout, f.name)
        if f.name == "blocks" and not v:
            continue  # layouts without blocks keep the keys they had before blocks existed
        parts.append(f"{f.name}={grid_content_key(v) if isinstance(v, GridMap) else repr(v)}")
    return ";".join(parts)


STALE_TMP_S = 3600.0
"""Age (s) after which a save's temporary file in the cache folder is taken for a killed save's, and deleted."""


def _umask() -> int:
    """The process's umask, read without changing it where Linux tells it (``/proc/self/status``)."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("Umask:"):
                return int(line.split()[1], 8)
    except (OSError, ValueError):
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


_TMP_PREFIX = ".semreloc-map-"
"""Prefix of the temporary files a save writes before its rename (the only ``.tmp`` files deleted here)."""


def _remove_stale_tmp(folder: Path) -> None:
    """Delete this package's temporary files older than `STALE_TMP_S`: what saves killed before their rename
    left (a save takes well under a second)."""
    now = time.time()
    for f in folder.glob(f"{_TMP_PREFIX}*.tmp"):
        try:
            if now - f.stat().st_mtime > STALE_TMP_S:
                f.unlink()
        except OSError:
            pass


def _save(path: Path, grid: GridMap, key: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    _remove_stale_tmp(path.parent)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=_TMP_PREFIX, suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            if hasattr(os, "fchmod"):  # POSIX: mkstemp's 0600 would keep a shared cache to one user
                os.fchmod(f.fileno(), 0o666 & ~_umask())
            np.savez_compressed(  # 15-130 kB a map instead of 0.7-1.6 MB; 1-2 ms more to load
                f,
                key=np.asarray(key),
                occupancy=grid.occupancy,
                semantic=grid.semantic,
                resolution_m=grid.resolution_m,
                origin_xy_m=np.asarray(grid.origin_xy_m),
                class_names=np.asarray(grid.class_names),
                thresholds=np.array([grid.occupied_thresh, grid.free_thresh, grid.semantic_thresh]),
            )
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def _load(path: Path, key: str) -> GridMap | None:
    try:
        with np.load(path, allow_pickle=False) as z:
            if str(z["key"]) != key:  # another map under this name (or a file written before keys were kept)
                return None
            occ, sem, th = z["occupancy"], z["semantic"], z["thresholds"]
            return GridMap(
                occ,
                float(z["resolution_m"]),
                tuple(z["origin_xy_m"].tolist()),
                sem,
                tuple(z["class_names"].tolist()),
                float(th[0]),
                float(th[1]),
                float(th[2]),
            )
    except FileNotFoundError:
        return None
    except Exception:  # a truncated or foreign file: rebuild it
        return None


def mapped(layout: Layout, lidar: LidarParams, camera: CameraParams, version: str | None = None) -> GridMap:
    """The mapping-run map of ``layout`` with these sensors (seed 0): from memory, disk, or a new run.
    ``version``: the mapping run's (`semreloc_env.mapping_run.MAPPING_RUN_VERSIONS`; None: the newest)."""
    from .mapping_run import MAPPING_RUN_VERSION

    version = MAPPING_RUN_VERSION if version is None else version
    key = map_key(layout, lidar, camera, version=version)
    grid = _memory.get(key)
    if grid is not None:
        _memory.move_to_end(key)
        return grid
    folder = cache_dir()
    path = folder / f"{key}.npz" if folder is not None else None
    grid = _load(path, key) if path is not None else None
    if grid is None:
        from .mapping_run import build_maps

        grid = build_maps(layout, lidar, camera, version=version)
        if path is not None:
            try:
                _save(path, grid, key)
            except OSError as e:  # a read-only or full disk must not break env creation
                if folder not in _unwritable:
                    _unwritable.add(folder)
                    warnings.warn(
                        f"map cache {folder} could not be written ({e}); maps are rebuilt in every process: "
                        "set SEMRELOC_CACHE_DIR to a folder you can write, or to '' to switch the cache off",
                        UserWarning,
                        stacklevel=2,
                    )
    _memory[key] = grid
    while len(_memory) > MEMORY_CACHE_SIZE:
        _memory.popitem(last=False)
    return grid


@functools.lru_cache(maxsize=MEMORY_CACHE_SIZE)
def _perfect(layout: Layout) -> GridMap:
    return rasterize(layout)


_ROS_MAP_KEYS = {"image", "resolution", "origin", "occupied_thresh", "free_thresh", "negate", "mode"}
"""Keys of a ROS map YAML (map_server's); a layout has none of them."""


def load_env_map(path) -> GridMap:
    """The ROS map at ``path`` as the registered envs (``SemReloc-v22`` and older, ``SemSlam-v2`` and older) have
    always read maps, so that their episodes stay what they were: `filters.mapping.ros_map.load_map` with alpha left
    out of trinary maps and unknown cells at 0.5 whatever the thresholds (it warns where that reads them otherwise;
    docs/real_robot.md, section 6)."""
    return load_map(path, alpha_in_trinary=False, unknown_at_half=True)


def is_ros_map_file(path) -> bool:
    """True for a ``.yaml`` / ``.yml`` file that is a ROS map (one of map_server's keys, ``image``, ``resolution``,
    ``origin``, ..., and no ``outer``), not a layout."""
    p = Path(path).expanduser()
    if p.suffix.lower() not in (".yaml", ".yml") or not p.is_file():
        return False
    import yaml

    try:
        text = p.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        return False  # neither kind can be read: the layout loader's LayoutError says why (not UTF-8 text)
    try:
        doc = yaml.safe_load(text)
    except yaml.YAMLError:  # broken YAML: a ROS map if a top-level key is one of a map's and none is outer
        key = re.compile(r"^(\w+)\s*:", re.M)
        keys = {m.group(1) for m in key.finditer(text)}
        return "outer" not in keys and bool(_ROS_MAP_KEYS & keys)
    # a map file that lacks its image (or misspells it) is still a map: load_map says what is missing
    return isinstance(doc, dict) and "outer" not in doc and bool(_ROS_MAP_KEYS & set(doc))


def searched_ros_map(source) -> Path | None:
    """The ROS map file that a plain name (not a built-in layout nor one of `MAP_SOURCES`) finds on
    ``$SEMRELOC_LAYOUT_PATH`` (`find_layout_file`), or None: not such a name, nothing found, or a layout found."""
    if not isinstance(source, str) or source in MAP_SOURCES or source in LAYOUT_NAMES:
        return None
    found = find_layout_file(source)
    return found if found is not None and is_ros_map_file(found) else None


def names_a_layout(source) -> bool:
    """True if ``source`` names a layout: a built-in / procedural name, a name on ``$SEMRELOC_LAYOUT_PATH``
    (of a layout file, not a ROS map: `searched_ros_map`), a ``.json`` file, or an existing YAML file that is not a
    ROS map."""
    if isinstance(source, str) and (source in LAYOUT_NAMES or find_layout_file(source) is not None):
        return searched_ros_map(source) is None
    if isinstance(source, (str, Path)):
        p = Path(source).expanduser()
        if p.suffix.lower() == ".json":
            return True
        return p.suffix.lower() in (".yaml", ".yml") and p.is_file() and not is_ros_map_file(p)
    return False


def check_map_source_name(source: str) -> None:
    """ValueError unless ``source`` is a map source a command line can name: one of `MAP_SOURCES`, a layout
    (`names_a_layout`) or a ROS map file (`is_ros_map_file`), by path or by its name on the search path
    (`searched_ros_map`)."""
    if not (source in MAP_SOURCES or names_a_layout(source) or is_ros_map_file(source) or searched_ros_map(source)):
        raise ValueError(
            f"map_source must be mapping, perfect, a layout (a built-in name or a layout file) or a ROS map "
            f"(.yaml), got {source!r}"
        )


def maps_for(
    layout: Layout,
    source,
    lidar: LidarParams,
    camera: CameraParams,
    semantic: bool = True,
    mapping_version: str | None = None,
) -> GridMap:
    """The GridMap an env's filter uses.

    Args:
        source: ``"mapping"`` (a mapping run with these sensors, seed 0; cached in memory
            and on disk, see the module docstring), ``"perfect"`` (the
            rasterised layout), a ROS map ``.yaml`` / ``.yml`` path (`filters.mapping.ros_map.load_map`) or its name
            on ``$SEMRELOC_LAYOUT_PATH`` (`searched_ros_map`),
            a GridMap, or a *layout* (a name such as ``"lab"``, or a layout file): the mapping run
            of that layout, so the world can differ from the map ("the map is the lab, the world
            is the lab with furniture moved"). A map's classes are the env's, in any order
            (`env_classes`); a map without classes (a plain ROS map, no semantic sidecar) or with only
            some of them needs ``semantic=False``.
        semantic: whether the relocalizer uses the semantic factor.
        mapping_version: the mapping run's version for the sources that run one (`mapped`; None: the newest).

    Raises:
        ValueError: classes that do not fit, or a map (file, GridMap or other layout) whose extent
            or frame does not fit the world (`semreloc_env.map_world.check_map_matches_world`).
    """
    from .map_world import MapLayout, check_map_matches_world

    derived = False
    if isinstance(source, GridMap):
        grid = source
    elif isinstance(source, str) and source == "perfect":
        grid, derived = _perfect(layout), True
    elif isinstance(source, str) and source == "mapping":
        grid, derived = mapped(layout, lidar, camera, mapping_version), True
    elif names_a_layout(source):
        grid = mapped(get_layout(source), lidar, camera, mapping_version)
    else:  # a ROS map: its path, or its name on the search path
        path = searched_ros_map(source) or Path(source)
        grid = load_env_map(path)
    grid = env_classes(grid, source, semantic)  # the env's classes, in its order (empty layers if lidar-only)
    if not derived and not (isinstance(layout, MapLayout) and _same_map(layout.grid, grid)):
        check_map_matches_world(grid, layout)
    return grid


def env_classes(grid: GridMap, source, semantic: bool = True) -> GridMap:
    """``grid`` with its class layers in the env's order (`CLASS_NAMES`), those it lacks empty.

    A map's sidecar may list some of the env's classes, in any order (docs/maps.md). The semantic
    factor needs a layer for every class (a missing one would read as "no such object anywhere"),
    so a map that lacks one is refused when ``semantic`` is True; lidar-only relocalization takes it.

    Raises:
        ValueError: a class that is not the env's, or (``semantic``) a class of the env's missing;
            the message names the map (``source``) and what to do.
    """
    names = grid.class_names
    if names == CLASS_NAMES:
        return grid
    where = f"map {source if not isinstance(source, GridMap) else '(GridMap)'}"
    if not names and semantic:
        raise ValueError(
            f"{where} has no semantic classes (a plain ROS map without a <name>.semantic.yaml sidecar): pass "
            f"semantic=False for lidar-only relocalization, or give the map a sidecar with the classes "
            f"{CLASS_NAMES} (docs/maps.md)"
        )
    unknown = [c for c in names if c not in CLASS_NAMES]
    if unknown:
        raise ValueError(f"{where}: classes {unknown} are not among the env's {CLASS_NAMES} (docs/maps.md)")
    missing = [c for c in CLASS_NAMES if c not in names]
    if missing and semantic:
        raise ValueError(
            f"{where} has no layer for the classes {missing}: the semantic factor needs every class of the "
            f"env {CLASS_NAMES}. Add them to its sidecar (an image with no cell of the class where the building "
            "has none; docs/maps.md), or pass semantic=False for lidar-only relocalization"
        )
    layers = np.zeros((len(CLASS_NAMES), *grid.shape), dtype=np.float32)
    for k, name in enumerate(names):
        layers[CLASS_NAMES.index(name)] = grid.semantic[k]
    return dataclasses.replace(grid, semantic=layers, class_names=CLASS_NAMES)


def _same_map(a: GridMap, b: GridMap) -> bool:
    return a is b or (
        a.shape == b.shape
        and a.resolution_m == b.resolution_m
        and a.origin_xy_m == b.origin_xy_m
        and bool(np.array_equal(a.occupied_mask(), b.occupied_mask()))
    )
