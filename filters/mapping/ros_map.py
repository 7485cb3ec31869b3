"""Read and write maps in the ROS ``map_server`` format, plus semreloc's semantic layers.

A map on disk is

* ``<name>.yaml`` + ``<name>.pgm``: the occupancy grid exactly as ROS
  ``map_server`` / ``map_saver`` (ROS 1) and ``nav2_map_server`` (ROS 2) read and
  write it, so maps built on a real robot load unchanged;
* optionally ``<name>.semantic.yaml`` + one 8-bit PGM per class: the semantic
  grids of `filters.mapping.grid.GridMap` on the same raster.

The full specification, with a worked example, is ``docs/maps.md``. In short:

Occupancy YAML (``.yaml`` or ``.yml``) keys: ``image`` (path, relative to the YAML's folder
unless absolute), ``resolution`` (metres per cell, > 0), ``origin`` (``[x, y, yaw]``: world pose
of the lower-left pixel's lower-left corner; a non-zero ``yaw`` is refused with an error, since
a `GridMap` is axis-aligned), ``occupied_thresh``, ``free_thresh`` (in ``[0, 1]``), all
required; ``negate`` (0/1, default 0) and ``mode`` (``trinary`` (default), ``scale`` or ``raw``)
optional, as in map_server.

Pixel to probability, as map_server does (``v`` = grey level scaled to 0..255; colour images:
mean of the colour channels, with alpha for a ``trinary`` map (`read_map_image`); ``negate: 1`` first
replaces ``v`` by ``255 - v``):
``p = (255 - v) / 255``. ``trinary``: ``p > occupied_thresh`` -> occupied (1.0),
``p < free_thresh`` -> free (0.0), otherwise unknown (`unknown_occupancy`: 0.5, or the thresholds' midpoint
where 0.5 is not between them). ``scale``: the cell keeps ``p`` itself (its class under the same thresholds is
what map_server reports); a fully transparent pixel between the thresholds is unknown. ``raw``: ``round(v)`` is
the occupancy in percent, ``p = round(v) / 100``; values above 100 are unknown, as in nav2.

The image's first row is the *top* of the map (largest y); `GridMap` row 0
is the bottom, so rows are flipped on read and write.

Images: binary ``P5`` and ASCII ``P2`` greymaps with ``#`` comments, 8 or 16 bit
(``maxval`` up to 65535, rescaled to 0..255), read here; any other format (PNG, BMP, TIFF, ...)
through Pillow (`read_map_image`). Maps are written as 8-bit ``P5`` (``trinary``) or grey-and-alpha PNG
(``scale``: unknown cells transparent, as nav2's map_saver writes them). Anything wrong with the files raises
`MapFormatError`, naming the file and the problem.
"""

from __future__ import annotations

import math
import os
import re
import warnings
from pathlib import Path

import numpy as np
import yaml

from filters.mapping.grid import GridMap
from filters.numbers import is_exponent_form, yaml_number_hint
from filters.unique_keys import FileTextError, load_yaml

__all__ = [
    "MapFormatWarning",
    "unknown_occupancy",
    "MapFormatError",
    "save_map",
    "load_map",
    "read_pgm",
    "read_map_image",
    "write_pgm",
    "semantic_yaml_path",
]

MAX_MAP_COORDINATE_M = 1e12
"""How far from the origin a map's corners may lie (m): beyond any robot's map (float64 still resolves 0.12 mm there),
and short of where the world's and the filter's arithmetic overflow."""

SEMANTIC_FORMAT = "semreloc-semantic/1"
"""Value of the ``format`` key of a semantic YAML written by this version."""

_OCC_PIXEL = 0  # map_saver's colours (trinary): occupied black, free near-white, unknown grey
_FREE_PIXEL = 254
_UNKNOWN_PIXEL = 205


class MapFormatError(ValueError):
    """A map file is malformed. ``path`` is the offending file, ``problem`` what is wrong with it."""

    def __init__(self, path: str | os.PathLike, problem: str) -> None:
        self.path = str(path)
        self.problem = problem
        super().__init__(f"{self.path}: {problem}")


class MapFormatWarning(UserWarning):
    """A map file is read as asked, but not as its values mean (`load_map`'s ``unknown_at_half``)."""


# ---------------------------------------------------------------------------------------------- PGM
def write_pgm(path: str | os.PathLike, image: np.ndarray) -> None:
    """Write an ``(H, W)`` uint8 image as a binary (``P5``) PGM, first array row = top row of the picture."""
    img = np.asarray(image)
    if img.ndim != 2 or img.size == 0:
        raise ValueError(f"write_pgm: need a non-empty 2D image, got shape {img.shape}")
    if img.dtype != np.uint8:
        raise ValueError(f"write_pgm: need uint8 pixels, got {img.dtype}")
    h, w = img.shape
    with open(path, "wb") as f:
        f.write(f"P5\n{w} {h}\n255\n".encode("ascii"))
        f.write(np.ascontiguousarray(img).tobytes())


def _pgm_tokens(data: bytes, count: int, start: int, path: Path) -> tuple[list[bytes], int]:
    """Read ``count`` whitespace-separated header tokens from ``data[start:]``, skipping ``#`` comments.

    Returns the tokens and the index just after the last token (which points at the single
    whitespace byte that ends a P5 header).
    """
    tokens: list[bytes] = []
    i, n = start, len(data)
    while len(tokens) < count:
        while i < n and data[i : i + 1].isspace():
            i += 1
        if i < n and data[i : i + 1] == b"#":
            while i < n and data[i : i + 1] not in (b"\n", b"\r"):
                i += 1
            continue
        if i >= n:
            raise MapFormatError(path, "bad PGM header: file ends inside the header")
        j = i
        while j < n and not data[j : j + 1].isspace() and data[j : j + 1] != b"#":
            j += 1
        tokens.append(data[i:j])
        i = j
    return tokens, i


def _read_bytes(path: Path) -> bytes:
    try:
        return path.read_bytes()
    except FileNotFoundError:
        raise MapFormatError(path, "image file not found") from None
    except OSError as e:
        raise MapFormatError(path, f"cannot read image file ({e.strerror})") from None


def _parse_pgm(data: bytes, path: Path) -> tuple[np.ndarray, int]:
    """``(values (H, W) int64, maxval)`` of a ``P5`` / ``P2`` greymap, ``maxval`` in ``1..65535``.

    16-bit ``P5`` samples are big-endian (the Netpbm definition).
    """
    magic = data[:2]
    if magic not in (b"P5", b"P2"):
        raise MapFormatError(path, f"bad PGM header: magic number {magic!r}, expected b'P5' or b'P2'")
    tokens, end = _pgm_tokens(data, 3, 2, path)
    try:
        w, h, maxval = (int(t) for t in tokens)
    except ValueError:
        raise MapFormatError(path, f"bad PGM header: width/height/maxval {tokens!r} are not integers") from None
    if w <= 0 or h <= 0:
        raise MapFormatError(path, f"bad PGM header: image size {w} x {h}")
    if not 0 < maxval <= 65535:
        raise MapFormatError(path, f"bad PGM header: maxval {maxval}; must be in 1..65535")
    if magic == b"P5":
        body = data[end + 1 :]  # exactly one whitespace byte separates header and raster
        nbytes = 1 if maxval <= 255 else 2
        if len(body) != w * h * nbytes:
            raise MapFormatError(
                path,
                f"wrong size: header says {w} x {h} = {w * h} pixels of {nbytes} byte(s), file holds {len(body)} bytes",
            )
        vals = np.frombuffer(body, dtype=np.uint8 if nbytes == 1 else ">u2").reshape(h, w).astype(np.int64)
        if vals.max() > maxval:
            raise MapFormatError(path, f"bad P5 raster: pixel values outside 0..{maxval}")
    else:
        words = data[end:].split()
        if len(words) != w * h:
            raise MapFormatError(path, f"wrong size: header says {w} x {h} = {w * h} pixels, file holds {len(words)}")
        try:
            vals = np.array([int(t) for t in words], dtype=np.int64)
        except ValueError:
            raise MapFormatError(path, "bad P2 raster: non-integer pixel value") from None
        if vals.min() < 0 or vals.max() > maxval:
            raise MapFormatError(path, f"bad P2 raster: pixel values outside 0..{maxval}")
        vals = vals.reshape(h, w)
    return vals, maxval


def read_pgm(path: str | os.PathLike) -> np.ndarray:
    """Read an 8-bit greymap (``P5`` binary or ``P2`` ASCII) as ``(H, W)`` uint8, first row = top of the picture.

    ``maxval`` must be in ``1..255``; values are rescaled to ``0..255`` (``round(v * 255 / maxval)``).
    (16-bit greymaps: `read_map_image`.)

    Raises:
        MapFormatError: the file is missing, is not a P5/P2 PGM, has a bad header, a 16-bit
            ``maxval``, or holds more or fewer pixels than ``width * height``.
    """
    path = Path(path)
    data = _read_bytes(path)
    if data[:2] in (b"P5", b"P2"):
        tokens, _ = _pgm_tokens(data, 3, 2, path)
        if len(tokens) == 3 and tokens[2].isdigit() and int(tokens[2]) > 255:
            raise MapFormatError(
                path,
                f"bad PGM header: maxval {int(tokens[2])}: an 8-bit greymap (maxval <= 255) is needed here, as a "
                "semantic class image must be (a 16-bit occupancy image is read through its map YAML: load_map, "
                "or read_map_image)",
            )
    vals, maxval = _parse_pgm(data, path)
    img = vals.astype(np.uint8)
    if maxval != 255:
        img = np.round(vals.astype(np.float64) * (255.0 / maxval)).astype(np.uint8)
    return np.array(img, dtype=np.uint8)


def read_map_image(path: str | os.PathLike, trinary: bool = False) -> tuple[np.ndarray, np.ndarray | None]:
    """Read a map image as map_server does: ``(grey (H, W) float64 in [0, 255], alpha (H, W) bool or None)``.

    * PGM (``P5`` / ``P2``, 8 or 16 bit, ``#`` comments): ``grey = v * 255 / maxval``.
    * Any other image Pillow reads (PNG, BMP, TIFF, ...): grey images as they are (16-bit
      scaled by ``255 / 65535``); colour images give the mean of their colour channels, alpha left
      out, except for an ``RGBA`` or grey-and-alpha (``LA``, loaded as RGBA with ``r = g = b``) image read
      for a ``trinary`` map, whose alpha is averaged in: ``(r + g + b + a) / 4`` (map_server's
      ``image_loader`` and nav2's ``map_io``; so an opaque 205 grey reads as free there, and a transparent
      white as unknown). ``alpha`` is ``True`` where an alpha channel is fully transparent (``None`` without
      alpha channel).

    First row = top of the picture. Raises `MapFormatError` naming the file.
    """
    path = Path(path)
    data = _read_bytes(path)
    if data[:2] in (b"P5", b"P2"):
        vals, maxval = _parse_pgm(data, path)
        return vals.astype(np.float64) * (255.0 / maxval), None
    import io

    from PIL import Image, UnidentifiedImageError

    try:
        im = Image.open(io.BytesIO(data))
        im.load()
    except UnidentifiedImageError:
        raise MapFormatError(
            path, f"bad PGM header: magic number {data[:2]!r}, and not an image Pillow can read either"
        ) from None
    except Image.DecompressionBombError as e:
        raise MapFormatError(path, f"image too large to be a map ({e})") from None
    except (OSError, ValueError) as e:
        raise MapFormatError(path, f"cannot decode image ({e})") from None
    transparent = None
    if im.mode in ("I;16", "I;16B", "I;16L", "I"):
        grey = np.asarray(im, dtype=np.float64) * (255.0 / 65535.0)
    elif im.mode in ("L", "1"):
        grey = np.asarray(im.convert("L"), dtype=np.float64)
    else:
        has_alpha = im.mode in ("LA", "RGBA", "PA") or (im.mode == "P" and "transparency" in im.info)
        rgba = np.asarray(im.convert("RGBA"), dtype=np.float64)
        if trinary and im.mode in ("LA", "RGBA"):  # alpha averaged in, as map_server does for trinary maps
            grey = rgba.mean(axis=2)
        elif im.mode in ("LA", "La"):
            grey = rgba[..., 0]
        else:
            grey = rgba[..., :3].mean(axis=2)
        if has_alpha:
            transparent = rgba[..., 3] == 0
    if grey.ndim != 2 or grey.size == 0:
        raise MapFormatError(path, f"image has shape {grey.shape}, expected a non-empty 2D raster")
    return grey, transparent


# --------------------------------------------------------------------------------------------- YAML
def _read_yaml(path: Path) -> dict:
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise MapFormatError(path, "not a UTF-8 text file") from None
    try:
        doc = load_yaml(text, numbers="yaml1.2")  # as ROS's own reader: 010 is 10, 12:30 a string
    except FileTextError as e:
        raise MapFormatError(path, str(e)) from None
    except yaml.YAMLError as e:
        raise MapFormatError(path, f"not valid YAML ({e})") from None
    if not isinstance(doc, dict):
        raise MapFormatError(path, f"expected a YAML mapping of keys, got {type(doc).__name__}")
    return doc


def _require(doc: dict, key: str, path: Path):
    if key not in doc:
        raise MapFormatError(path, f"missing key {key!r}")
    return doc[key]


def _number(value, key: str, path: Path) -> float:
    if isinstance(value, str) and is_exponent_form(value):
        value = float(value)  # ROS reads map YAMLs with yaml-cpp, which takes 5e-2 for a number; PyYAML does not
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise MapFormatError(path, f"{key} must be a number, got {value!r}{yaml_number_hint(value)}")
    v = float(value)
    if not math.isfinite(v):
        raise MapFormatError(path, f"{key} must be finite, got {value!r}")
    return v


def _resolution(doc: dict, path: Path) -> float:
    res = _number(_require(doc, "resolution", path), "resolution", path)
    if res <= 0:
        raise MapFormatError(path, f"resolution must be positive, got {res}")
    return res


def _origin(doc: dict, path: Path) -> tuple[float, float]:
    origin = _require(doc, "origin", path)
    if not isinstance(origin, (list, tuple)) or len(origin) != 3:
        raise MapFormatError(path, f"origin must be a list [x, y, yaw], got {origin!r}")
    x, y, yaw = (_number(v, f"origin[{i}]", path) for i, v in enumerate(origin))
    if yaw != 0.0:
        raise MapFormatError(
            path,
            f"origin yaw is {yaw} rad; rotated maps are not supported (a GridMap is axis-aligned): "
            "set yaw to 0 and express poses in the map's own frame, or re-save the map unrotated",
        )
    return x, y


def _image_path(doc: dict, yaml_path: Path, key: str = "image") -> Path:
    image = _require(doc, key, yaml_path)
    if not isinstance(image, str) or not image:
        raise MapFormatError(yaml_path, f"{key} must be a file name, got {image!r}")
    p = Path(image)
    return p if p.is_absolute() else yaml_path.parent / p


def semantic_yaml_path(path_yaml: str | os.PathLike) -> Path:
    """The semantic sidecar of a map YAML: ``dir/name.yaml`` -> ``dir/name.semantic.yaml`` (``.yml``:
    ``.semantic.yml``); if only the other spelling exists (``name.semantic.yml`` beside ``name.yaml``),
    that file."""
    p = Path(path_yaml)
    own = p.with_name(p.stem + ".semantic" + (".yml" if p.suffix.lower() == ".yml" else ".yaml"))
    other = own.with_suffix(".yaml" if own.suffix == ".yml" else ".yml")
    return other if not own.exists() and other.exists() else own


def _safe_name(name: str) -> str:
    s = re.sub(r"[^A-Za-z0-9_-]+", "_", name).strip("_")
    return s or "class"


def _fmt(v: float) -> float:
    """Shortest float that round-trips (keeps YAML readable: 0.05, not 0.05000000074505806)."""
    return float(repr(float(v)))


# --------------------------------------------------------------------------------------------- save
def _semantic_pixels(prob: np.ndarray, thresh: float) -> np.ndarray:
    """``round(255 * p)``, moved one grey level back where rounding would carry ``p`` across ``thresh``.

    So ``p > thresh`` (the class mask) survives the round trip exactly; e.g. an unobserved cell
    at ``p = 0.5`` with threshold 0.5 is written 127, not 128 (which would read back as 0.502).
    """
    prob = np.asarray(prob, dtype=np.float32)
    v = np.round(255.0 * prob.astype(np.float64))
    back = v.astype(np.float32) / np.float32(255.0)  # exactly what load_map computes
    is_class = prob > thresh  # exactly what GridMap.class_mask computes
    v[is_class & (back <= thresh)] += 1
    v[~is_class & (back > thresh)] -= 1
    return np.clip(v, 0, 255).astype(np.uint8)


SAVE_MODES = ("trinary", "scale")
"""The ``mode`` values `save_map` writes."""


def save_map(grid: GridMap, path_yaml: str | os.PathLike, mode: str = "trinary") -> Path:
    """Write ``grid`` as a map_server map (+ semantic sidecar when the grid has classes).

    Files written next to ``path_yaml`` (``dir/name.yaml``):

    * ``name.yaml`` and ``name.pgm`` (binary P5, ``negate: 0``). ``mode="trinary"`` (default,
      what ``map_saver`` writes): occupied cells -> 0, free -> 254, unknown -> 205 (or the pixel
      of the mid-probability when the grid's thresholds would misread 205), which reloads to
      the same occupied/free/unknown masks. ``mode="scale"``: ``name.png`` (grey and alpha) instead,
      pixel ``round(255 * (1 - p))``, which reloads ``p`` to within ``1/255`` (cells that rounding would
      carry across a threshold are moved one grey level back, so the masks are kept exactly here too);
      cells of exactly ``p = 0.5`` (unknown) are transparent, which ROS reads as unknown, where an
      opaque grey would be a graded cost. ValueError, before anything is written, if the masks cannot
      survive (thresholds with no grey level between them for the unknown cells, e.g. equal ones).
    * only if ``grid.class_names`` is non-empty: ``name.semantic.yaml`` and one
      ``name.semantic.<class>.pgm`` per class, pixel ``round(255 * p)`` (one grey level less or more
      where rounding would move ``p`` across ``semantic_thresh``, so class masks survive; see
      ``docs/maps.md``).
      A stale sidecar from an earlier save is removed when the grid has no classes.

    Returns:
        The path of the occupancy YAML.
    """
    if mode not in SAVE_MODES:
        raise ValueError(f"save_map: mode must be 'trinary' or 'scale', got {mode!r}")
    path_yaml = Path(path_yaml)
    if path_yaml.suffix not in (".yaml", ".yml"):
        raise ValueError(f"save_map: the map path must end in .yaml or .yml, got {path_yaml}")
    stem = path_yaml.stem
    folder = path_yaml.parent
    occ = grid.occupancy.astype(np.float64)

    if mode == "trinary":
        img = np.full(grid.shape, _UNKNOWN_PIXEL, dtype=np.uint8)
        unknown_p = (255 - _UNKNOWN_PIXEL) / 255.0
        if not grid.free_thresh <= unknown_p <= grid.occupied_thresh:
            mid = 0.5 * (grid.free_thresh + grid.occupied_thresh)
            img[:] = np.uint8(round(255 * (1.0 - mid)))
        # 254 reads back as p = 1/255; a (silly) free_thresh at or below that needs pure white
        img[grid.free_mask()] = _FREE_PIXEL if grid.free_thresh > 1.0 / 255.0 else 255
        img[grid.occupied_mask()] = _OCC_PIXEL
    else:
        v = np.round(255.0 * (1.0 - occ))
        # nudge the few cells that quantisation would carry across a threshold by one grey level,
        # so the occupied / free / unknown masks survive the round trip exactly
        p = ((255.0 - v) / 255.0).astype(np.float32)  # what load_map hands to GridMap
        occupied, free = grid.occupied_mask(), grid.free_mask()
        unknown = ~occupied & ~free
        v[occupied & (p <= grid.occupied_thresh)] -= 1
        v[free & (p >= grid.free_thresh)] += 1
        v[unknown & (p > grid.occupied_thresh)] += 1
        v[unknown & (p < grid.free_thresh)] -= 1
        img = np.clip(v, 0, 255).astype(np.uint8)
    back = _occupancy_from_pixels(img.astype(np.float64), False, "trinary", grid.occupied_thresh, grid.free_thresh)
    if not (np.array_equal(back == 1.0, grid.occupied_mask()) and np.array_equal(back == 0.0, grid.free_mask())):
        raise ValueError(
            f"save_map: no grey level reads back as the grid's cells under free_thresh {grid.free_thresh} and "
            f"occupied_thresh {grid.occupied_thresh} (unknown cells need a level between them): widen the band"
        )
    folder.mkdir(parents=True, exist_ok=True)
    if mode == "trinary":
        image_name = stem + ".pgm"
        write_pgm(folder / image_name, np.flipud(img))
    else:
        from PIL import Image

        image_name = stem + ".png"
        # unknown (`unknown_occupancy`, between the thresholds): transparent, as nav2's map_saver writes it
        alpha = np.where(unknown & (occ == unknown_occupancy(grid.free_thresh, grid.occupied_thresh)), 0, 255)
        alpha = alpha.astype(np.uint8)
        Image.fromarray(np.flipud(np.stack([img, alpha], axis=-1)), "LA").save(folder / image_name)
    doc = {
        "image": image_name,
        "mode": mode,
        "resolution": _fmt(grid.resolution_m),
        "origin": [_fmt(grid.origin_xy_m[0]), _fmt(grid.origin_xy_m[1]), 0.0],
        "negate": 0,
        "occupied_thresh": _fmt(grid.occupied_thresh),
        "free_thresh": _fmt(grid.free_thresh),
    }
    path_yaml.write_text(yaml.safe_dump(doc, sort_keys=False, default_flow_style=None), encoding="utf-8")

    sem_path = semantic_yaml_path(path_yaml)
    if not grid.class_names:
        if sem_path.exists():
            sem_path.unlink()
        return path_yaml
    h, w = grid.shape
    classes = []
    used: set[str] = set()
    for k, name in enumerate(grid.class_names):
        fname = f"{stem}.semantic.{_safe_name(name)}.pgm"
        if fname in used:
            fname = f"{stem}.semantic.{k}_{_safe_name(name)}.pgm"
        used.add(fname)
        layer = _semantic_pixels(grid.semantic[k], grid.semantic_thresh)
        write_pgm(folder / fname, np.flipud(layer))
        classes.append({"name": name, "label": k + 1, "image": fname})
    sem_doc = {
        "format": SEMANTIC_FORMAT,
        "map": path_yaml.name,
        "resolution": _fmt(grid.resolution_m),
        "origin": [_fmt(grid.origin_xy_m[0]), _fmt(grid.origin_xy_m[1]), 0.0],
        "width": w,
        "height": h,
        "semantic_thresh": _fmt(grid.semantic_thresh),
        "classes": classes,
    }
    sem_path.write_text(yaml.safe_dump(sem_doc, sort_keys=False, default_flow_style=None), encoding="utf-8")
    return path_yaml


# --------------------------------------------------------------------------------------------- load
def unknown_occupancy(free_thresh: float, occupied_thresh: float) -> float:
    """The occupancy an unknown cell is stored with, which a `GridMap` with these thresholds reads as neither
    occupied (``> occupied_thresh``) nor free (``< free_thresh``): 0.5 where it lies between them (the map_server
    defaults, 0.196 and 0.65), else their midpoint (an outside audit: thresholds 0.1 and 0.4 read a stored 0.5 as
    occupied, and unknown cells became walls in a world built from the map)."""
    return 0.5 if free_thresh <= 0.5 <= occupied_thresh else 0.5 * (free_thresh + occupied_thresh)


def _occupancy_from_pixels(
    img: np.ndarray,
    negate: bool,
    mode: str,
    occ_t: float,
    free_t: float,
    transparent: np.ndarray | None = None,
    unknown: float | None = None,
) -> np.ndarray:
    """The occupancy of the pixels ``img`` (module docstring); unknown cells hold ``unknown`` (None:
    `unknown_occupancy`)."""
    v = img.astype(np.float64)
    unknown = unknown_occupancy(free_t, occ_t) if unknown is None else unknown
    if negate:
        v = 255.0 - v
    if mode == "raw":  # the pixel is the occupancy in percent; anything above 100 is unknown (nav2)
        v = np.round(v)
        return np.where(v <= 100.0, v / 100.0, unknown)
    p = (255.0 - v) / 255.0
    if mode == "scale":
        out = p.copy()
        if transparent is not None:  # map_server: a transparent pixel between the thresholds is unknown
            out[transparent & (p <= occ_t) & (p >= free_t)] = unknown
        return out
    out = np.full(p.shape, unknown)
    out[p > occ_t] = 1.0
    out[p < free_t] = 0.0
    return out


def _load_semantic(sem_path: Path, shape: tuple[int, int], res: float, origin: tuple[float, float]):
    doc = _read_yaml(sem_path)
    fmt = _require(doc, "format", sem_path)
    if fmt != SEMANTIC_FORMAT:
        raise MapFormatError(sem_path, f"format is {fmt!r}, expected {SEMANTIC_FORMAT!r}")
    s_res = _resolution(doc, sem_path)
    s_origin = _origin(doc, sem_path)
    if not math.isclose(s_res, res, rel_tol=1e-9):
        raise MapFormatError(sem_path, f"resolution {s_res} differs from the occupancy map's {res}")
    if not all(math.isclose(a, b, rel_tol=1e-9, abs_tol=1e-9) for a, b in zip(s_origin, origin, strict=True)):
        raise MapFormatError(sem_path, f"origin {list(s_origin)} differs from the occupancy map's {list(origin)}")
    h, w = shape
    for key, want in (("width", w), ("height", h)):
        got = _require(doc, key, sem_path)
        if isinstance(got, bool) or not isinstance(got, int) or got != want:
            raise MapFormatError(sem_path, f"{key} is {got!r}, the occupancy image has {want}")
    thresh = _number(doc.get("semantic_thresh", 0.5), "semantic_thresh", sem_path)
    if not 0.0 <= thresh <= 1.0:
        raise MapFormatError(sem_path, f"semantic_thresh must be in [0, 1], got {thresh}")
    classes = _require(doc, "classes", sem_path)
    if not isinstance(classes, list):
        raise MapFormatError(sem_path, f"classes must be a list, got {classes!r}")
    names: list[str] = []
    layers: list[np.ndarray] = []
    for k, entry in enumerate(classes):
        if not isinstance(entry, dict):
            raise MapFormatError(sem_path, f"classes[{k}] must be a mapping with name and image, got {entry!r}")
        name = _require(entry, "name", sem_path)
        if not isinstance(name, str) or not name:
            raise MapFormatError(sem_path, f"classes[{k}].name must be a non-empty string, got {name!r}")
        if name in names:
            raise MapFormatError(sem_path, f"class {name!r} is listed twice")
        if "label" in entry and entry["label"] != k + 1:
            raise MapFormatError(sem_path, f"classes[{k}] ({name}) has label {entry['label']!r}, expected {k + 1}")
        img_path = _image_path(entry, sem_path)
        img = read_pgm(img_path)
        if img.shape != shape:
            raise MapFormatError(
                img_path, f"semantic raster for class {name!r} is {img.shape[1]} x {img.shape[0]}, expected {w} x {h}"
            )
        names.append(name)
        layers.append(np.flipud(img).astype(np.float32) / np.float32(255.0))
    sem = np.stack(layers) if layers else np.zeros((0,) + shape, np.float32)
    return tuple(names), sem, thresh


def load_map(
    path_yaml: str | os.PathLike,
    semantic_yaml: str | os.PathLike | None = None,
    alpha_in_trinary: bool = True,
    unknown_at_half: bool = False,
) -> GridMap:
    """Load a map_server map (and its semantic sidecar, if any) as a `GridMap`.

    Args:
        path_yaml: the occupancy YAML.
        semantic_yaml: the semantic YAML; default ``<name>.semantic.yaml`` next to ``path_yaml``
            (absent -> a map without classes; given explicitly but absent -> error).
        alpha_in_trinary: average an RGBA or grey-and-alpha image's alpha into a ``trinary`` map's grey
            levels, as map_server and nav2 do (`read_map_image`); False leaves it out, as this package did
            before, and as the registered envs (``SemReloc-v22`` and older, ``SemSlam-v2`` and older) read
            their maps, so that their episodes stay what they were.
        unknown_at_half: store unknown cells as 0.5 whatever the thresholds, as this package did before and as the
            registered envs read their maps (their episodes stay what they were); then a map whose thresholds do not
            straddle 0.5 reads its unknown cells as occupied (above both) or free (below both), and a
            `MapFormatWarning` says so. False (default): `unknown_occupancy`, which the grid reads as unknown.

    Returns:
        A ``GridMap`` with ``occupancy`` in ``{0, 0.5, 1}`` (``trinary``), the pixel
        probability (``scale``) or the percentage / 100 (``raw``), thresholds from the YAML,
        row 0 = bottom of the map.

    Raises:
        FileNotFoundError: ``path_yaml`` (or an explicitly given ``semantic_yaml``) does not exist.
        MapFormatError: any file is malformed (missing key, bad value, bad or missing image,
            size mismatch, rotated origin...). The message names the file.
    """
    path_yaml = Path(path_yaml).expanduser()
    if not path_yaml.is_file():
        raise FileNotFoundError(f"map YAML not found: {path_yaml}")
    doc = _read_yaml(path_yaml)
    img_path = _image_path(doc, path_yaml)
    res = _resolution(doc, path_yaml)
    origin = _origin(doc, path_yaml)
    negate = doc.get("negate", 0)  # optional, default 0, as in map_server
    if negate not in (0, 1) or isinstance(negate, float):  # True/False count as 1/0, as YAML users expect
        raise MapFormatError(path_yaml, f"negate must be 0 or 1, got {negate!r}")
    occ_t = _number(_require(doc, "occupied_thresh", path_yaml), "occupied_thresh", path_yaml)
    free_t = _number(_require(doc, "free_thresh", path_yaml), "free_thresh", path_yaml)
    if not 0.0 <= free_t <= occ_t <= 1.0:
        raise MapFormatError(path_yaml, f"need 0 <= free_thresh ({free_t}) <= occupied_thresh ({occ_t}) <= 1")
    mode = doc.get("mode", "trinary")
    if mode not in ("trinary", "scale", "raw"):
        raise MapFormatError(path_yaml, f"mode {mode!r} is not supported (use 'trinary', 'scale' or 'raw')")
    img, transparent = read_map_image(img_path, trinary=alpha_in_trinary and mode == "trinary")
    far = max(abs(origin[0]), abs(origin[1]), abs(origin[0] + img.shape[1] * res), abs(origin[1] + img.shape[0] * res))
    if not far <= MAX_MAP_COORDINATE_M:  # an outside audit's: 1e300 gave an OverflowError at the env's reset
        raise MapFormatError(
            path_yaml,
            f"origin {list(origin)} and resolution {res} put the map's corners {far:.12g} m from the origin, "
            f"beyond the {MAX_MAP_COORDINATE_M:g} m maps may reach (not metres?)",
        )
    right = unknown_occupancy(free_t, occ_t)
    unknown = 0.5 if unknown_at_half else right
    pixels = (img, bool(negate), mode, occ_t, free_t, transparent)
    occ = _occupancy_from_pixels(*pixels, unknown)
    if unknown != right and not np.array_equal(occ, _occupancy_from_pixels(*pixels, right)):
        warnings.warn(
            f"{path_yaml}: free_thresh {free_t} and occupied_thresh {occ_t} do not straddle 0.5, so the unknown cells, "
            f"stored as 0.5 as the registered envs read maps, read as {'occupied' if unknown > occ_t else 'free'} "
            "(load_map's default stores them between the thresholds: docs/maps.md)",
            MapFormatWarning,
            stacklevel=2,
        )
    occ = np.flipud(occ)

    names: tuple[str, ...] = ()
    sem = np.zeros((0,) + img.shape, np.float32)
    sem_thresh = 0.5
    if semantic_yaml is not None:
        sem_path = Path(semantic_yaml)
        if not sem_path.is_file():
            raise FileNotFoundError(f"semantic YAML not found: {sem_path}")
    else:
        sem_path = semantic_yaml_path(path_yaml)
    if sem_path.is_file():
        names, sem, sem_thresh = _load_semantic(sem_path, img.shape, res, origin)
    return GridMap(
        occupancy=np.ascontiguousarray(occ, dtype=np.float32),
        resolution_m=res,
        origin_xy_m=origin,
        semantic=np.ascontiguousarray(sem),
        class_names=names,
        occupied_thresh=occ_t,
        free_thresh=free_t,
        semantic_thresh=sem_thresh,
    )
