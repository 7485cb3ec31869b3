"""A new layout at every reset: a seeded sampler over layout kinds and seeds, and its wrapper.

* `HELD_OUT_LAYOUT_SEEDS` — the procedural seeds kept for evaluation. A
  `LayoutSampler` never draws them, whatever seed range it is given, so a policy trained
  through it has never seen the evaluation layouts of ``scripts/evaluate_active.py``.
* `LayoutSampler` — draws ``(kind, seed)`` from a seeded generator: a kind (a procedural
  generator, a built-in, or a layout file) by weight, then for procedural kinds a seed uniformly
  from the training range without the held-out ones. Layouts are built once per ``(kind, seed)``
  and cached.
* `RandomLayout` — a wrapper that gives a ``SemReloc`` env the next drawn layout before
  every reset (`set_layout`), the filter's maps
  from `semreloc_env.maps.maps_for` (built once per layout, cached).

The same reset seed gives the same layout, bit for bit; ``info["layout"]`` says which.
"""

from __future__ import annotations

import copy
import functools
from collections import OrderedDict
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import gymnasium as gym
import numpy as np

from filters.numbers import is_int

from .layouts import BUILTIN_LAYOUTS_NAMES, PROCEDURAL_LAYOUTS, PROCEDURAL_VERSION, Layout, find_layout_file, get_layout
from .maps import maps_for
from .wrappers import KidnapBeyondLimitError

HELD_OUT_LAYOUT_SEEDS: range = range(1_000_000, 1_000_500)
"""Procedural layout seeds for evaluation only (500 per procedural kind): never drawn for training."""

DEFAULT_TRAIN_SEEDS: range = range(0, 100_000)
"""Seed range a `LayoutSampler` draws procedural layouts from by default."""

DEFAULT_KINDS = ("procedural", "procedural_sym", "procedural_lookalike", "lab", "twin_rooms")

_SALT = 0x1A7


@dataclass(frozen=True)
class LayoutDraw:
    """One drawn layout: its kind (generator name, built-in name or file path), seed and Layout.

    ``seed`` is the procedural seed, 0 for built-ins and files (they have none).
    """

    kind: str
    seed: int
    layout: Layout

    def as_dict(self) -> dict:
        return {"kind": self.kind, "seed": self.seed, "name": self.layout.name}


@functools.lru_cache(maxsize=512)
def _layout(kind: str, seed: int, procedural_version: int = PROCEDURAL_VERSION) -> Layout:
    return get_layout(kind, seed=seed, procedural_version=procedural_version)


def is_held_out(seed: int) -> bool:
    """Whether a procedural seed is one of `HELD_OUT_LAYOUT_SEEDS`."""
    return int(seed) in HELD_OUT_LAYOUT_SEEDS


def portable_layout_file(entry) -> str:
    """A layout file entry as an absolute path that names the same file from any folder: a path (with a layout
    file's extension, or an existing file) resolved, a name found on ``$SEMRELOC_LAYOUT_PATH`` as the path of the
    file it finds (`get_layout`'s order); anything else as given (its own error comes when it is loaded)."""
    path = Path(entry).expanduser()
    if path.suffix.lower() in (".json", ".yaml", ".yml") or path.is_file():
        return str(path.resolve())
    found = find_layout_file(str(entry))
    return str(found.resolve()) if found is not None else str(entry)


class LayoutSampler:
    """Seeded draws of training layouts.

    Args:
        kinds: layout names: procedural generators (``"procedural"``, ``"procedural_sym"``,
            ``"procedural_lookalike"``, ``"procedural_ring"``, ``"procedural_corridor"``) and built-ins (``"lab"``,
            ``"twin_rooms"``, ``"three_rooms"``, ``"open_hall"``).
        files: layout files (``.json`` / ``.yaml``), each one more entry.
        seeds: the procedural seeds to draw from (a range or a sequence of ints); the held-out
            ones are left out.
        weights: one non-negative weight per entry (``kinds`` then ``files``), default equal.

    Raises:
        ValueError: an unknown kind, no entry, bad weights, or no seed left once the held-out
            ones are removed. Files are loaded here, so a bad file fails now.

    `config` gives these arguments as a JSON-able dict and `from_config` takes it back (a seed
    range is written ``{"start": a, "stop": b}``, layout files as absolute paths), so an env spec
    that holds a sampler can be saved with ``env.spec.to_json()`` and made again from any folder.
    It holds the files' paths, not their contents: an edited file gives other layouts.
    """

    def __init__(
        self,
        kinds: Sequence[str] = DEFAULT_KINDS,
        files: Sequence[str | Path] = (),
        seeds: range | Sequence[int] = DEFAULT_TRAIN_SEEDS,
        weights: Sequence[float] | None = None,
    ):
        kinds = tuple(str(k) for k in kinds)
        bad = [k for k in kinds if k not in PROCEDURAL_LAYOUTS and k not in BUILTIN_LAYOUTS_NAMES]
        if bad:
            raise ValueError(
                f"kinds: unknown {bad}; known: {[*PROCEDURAL_LAYOUTS, *BUILTIN_LAYOUTS_NAMES]}; files go in files="
            )
        self.kinds = kinds
        self.files = tuple(str(f) for f in files)
        self.entries = kinds + self.files
        if not self.entries:
            raise ValueError("kinds and files are both empty: nothing to draw")
        self._file_layouts = {f: get_layout(Path(f)) for f in self.files}
        w = np.ones(len(self.entries)) if weights is None else np.asarray(weights, dtype=np.float64)
        if w.shape != (len(self.entries),) or not np.all(np.isfinite(w)) or np.any(w < 0) or w.sum() <= 0:
            raise ValueError(f"weights must be {len(self.entries)} non-negative numbers, not all 0; got {weights!r}")
        self._weights_given = None if weights is None else w.tolist()
        self.weights = w / w.sum()
        if isinstance(seeds, range):
            if seeds.step != 1:
                raise ValueError("seeds: a range must have step 1")
            if seeds.stop <= seeds.start or seeds.start < 0 or seeds.stop > 2**63:
                raise ValueError(f"seeds: need a non-empty range within [0, 2**63), got {seeds!r}")
            self._seeds: range | np.ndarray = seeds
            overlap = len(
                range(max(seeds.start, HELD_OUT_LAYOUT_SEEDS.start), min(seeds.stop, HELD_OUT_LAYOUT_SEEDS.stop))
            )
            n_left = len(seeds) - overlap
        else:
            items = list(seeds)
            if not items or not all(is_int(v) and 0 <= v < 2**63 for v in items):
                raise ValueError(f"seeds must be a non-empty list of integers in [0, 2**63), got {items!r:.80}")
            arr = np.asarray(items, dtype=np.int64)
            self._seeds = np.array([s for s in arr if not is_held_out(s)], dtype=np.int64)
            n_left = self._seeds.size
        if any(k in PROCEDURAL_LAYOUTS for k in kinds) and n_left == 0:
            raise ValueError(f"seeds: none left after removing the held-out seeds {HELD_OUT_LAYOUT_SEEDS}")

    def config(self) -> dict:
        """The constructor's arguments as a JSON-able dict, for `from_config` (the same draws)."""
        seeds = self._seeds
        return {
            "kinds": list(self.kinds),
            "files": [portable_layout_file(f) for f in self.files],  # usable from any folder
            "seeds": {"start": seeds.start, "stop": seeds.stop} if isinstance(seeds, range) else seeds.tolist(),
            "weights": self._weights_given,
        }

    @classmethod
    def from_config(cls, config: Mapping) -> LayoutSampler:
        """A sampler from `config`'s dict (or any subset of the constructor's keyword arguments).

        Raises:
            ValueError: an unknown key, a malformed seed range, or what the constructor rejects.
        """
        if not isinstance(config, Mapping):
            raise ValueError(f"a sampler config must be a dict, got {type(config).__name__}")
        unknown = sorted(set(config) - {"kinds", "files", "seeds", "weights"})
        if unknown:
            raise ValueError(f"sampler config: unknown keys {unknown}; known: kinds, files, seeds, weights")
        kwargs = dict(config)
        seeds = kwargs.get("seeds")
        if isinstance(seeds, Mapping):
            if set(seeds) != {"start", "stop"} or not all(is_int(v) for v in seeds.values()):
                raise ValueError(f"sampler config: a seed range is {{'start': int, 'stop': int}}, got {seeds!r:.80}")
            kwargs["seeds"] = range(int(seeds["start"]), int(seeds["stop"]))
        return cls(**kwargs)

    def _seed(self, rng: np.random.Generator) -> int:
        if isinstance(self._seeds, np.ndarray):
            return int(self._seeds[rng.integers(0, self._seeds.size)])
        while True:  # rejection: the held-out block is small next to any useful range
            s = int(rng.integers(self._seeds.start, self._seeds.stop))
            if not is_held_out(s):
                return s

    def draw(self, rng: np.random.Generator, procedural_version: int = PROCEDURAL_VERSION) -> LayoutDraw:
        """The next layout (one entry draw, then one seed draw for procedural kinds), procedural ones
        from that version of the generator (`semreloc_env.layouts.get_layout`; `RandomLayout` passes
        its env's, so ``SemReloc-v2`` keeps its layouts)."""
        i = int(rng.choice(len(self.entries), p=self.weights))
        kind = self.entries[i]
        if kind in self._file_layouts:
            return LayoutDraw(kind, 0, self._file_layouts[kind])
        seed = self._seed(rng) if kind in PROCEDURAL_LAYOUTS else 0
        return LayoutDraw(kind, seed, _layout(kind, seed, procedural_version))


class RandomLayout(gym.Wrapper, gym.utils.RecordConstructorArgs):
    """Give a ``SemReloc`` env a new layout, drawn from ``sampler``, before every reset.

    ``reset(seed=s)`` reseeds the layout stream (``np.random.default_rng([s, salt])``), so the
    same seed gives the same layout and then the same episode; resets without a seed continue
    the stream (started from ``seed`` here). The env's ``map_source`` must be ``"mapping"``
    or ``"perfect"``; each layout's map is built once (`maps_for`, its
    cache) and kept here for the last ``cache_size`` layouts. ``info["layout"]`` is
    `LayoutDraw.as_dict` of the episode's layout.

    Args:
        env: a ``SemReloc`` env, v1 or newer.
        sampler: the layouts to draw: a `LayoutSampler`, or its `LayoutSampler.config` dict
            (default: `LayoutSampler` with its defaults). The env spec records the dict, so
            ``gym.make(env.spec)`` and ``env.spec.to_json()`` work.
        seed: seed of the layout stream until a reset passes one.
        cache_size: maps kept in memory (about 2 MB each with what they derive; each wrapper keeps its own,
            so a batched env of R robots keeps up to R times as many). Procedural layouts drawn from a
            wide seed range rarely come back, and the disk cache loads one in milliseconds: a small
            cache serves as well (an outside tester: 0 hits in 180 procedural draws with 64).
    """

    def __init__(
        self, env: gym.Env, sampler: LayoutSampler | Mapping | None = None, seed: int = 0, cache_size: int = 8
    ):
        if sampler is None:
            sampler = LayoutSampler()
        elif isinstance(sampler, Mapping):
            sampler = LayoutSampler.from_config(sampler)
        elif not isinstance(sampler, LayoutSampler):
            raise TypeError(
                f"RandomLayout: sampler must be a LayoutSampler or its config dict, got {type(sampler).__name__}"
            )
        if not (is_int(cache_size) and cache_size >= 1):
            raise ValueError(f"RandomLayout: cache_size must be an integer >= 1, got {cache_size!r:.60}")
        gym.utils.RecordConstructorArgs.__init__(self, sampler=sampler.config(), seed=seed, cache_size=cache_size)
        gym.Wrapper.__init__(self, env)
        base = env.unwrapped
        if not hasattr(base, "set_layout"):
            raise TypeError(f"RandomLayout needs an env with set_layout(); {type(base).__name__} has none")
        if not (isinstance(base.map_source, str) and base.map_source in ("mapping", "perfect")):
            raise ValueError(f"RandomLayout needs map_source 'mapping' or 'perfect', got {base.map_source!r}")
        self.sampler = sampler
        if not (is_int(seed) and seed >= 0):
            raise ValueError(f"RandomLayout: seed must be an integer >= 0, got {seed!r:.60}")
        self._rng = np.random.default_rng([int(seed), _SALT])
        self._maps: OrderedDict[tuple, object] = OrderedDict()
        self.cache_size = int(cache_size)
        self.current: LayoutDraw | None = None

    def _grid(self, draw: LayoutDraw):
        key = (draw.kind, draw.seed)  # one env, so one generator version
        grid = self._maps.get(key)
        if grid is None:
            base = self.env.unwrapped
            grid = maps_for(
                draw.layout, base.map_source, base.lidar.params, base.camera.params,
                mapping_version=getattr(base, "mapping_run_version", None),
            )  # fmt: skip
            self._maps[key] = grid
            if len(self._maps) > self.cache_size:
                self._maps.popitem(last=False)
        else:
            self._maps.move_to_end(key)
        return grid

    def _next_stream(self, seed: int | None) -> np.random.Generator:
        """The layout stream a reset with ``seed`` draws from (a copy: drawing advances a generator in place)."""
        return np.random.default_rng([int(seed), _SALT]) if seed is not None else copy.deepcopy(self._rng)

    def _on_drawn_layout(self, seed: int | None, options, run, keep: bool):
        """``run()`` with the env set to the layout a reset with ``seed`` draws; with ``keep``, the stream and the
        layout stay drawn if ``run`` returns, else (and whenever it raises) everything is put back as it was. A
        ValueError of ``run`` given ``options`` names the layout drawn, whose place an option may not fit."""
        base = self.env.unwrapped
        base.check_reset(seed=seed)  # the seed before it re-seeds the layout stream
        saved = (self._rng, self.current, base.layout, base.layout_seed, base.grid)
        draw = None
        done = False
        try:
            self._rng = self._next_stream(seed)
            draw = self.sampler.draw(self._rng, getattr(base, "procedural_version", PROCEDURAL_VERSION))
            base.set_layout(draw.layout, draw.seed, grid=self._grid(draw), check_map=False)  # maps_for's
            self.current = draw
            out = run()
            done = keep
        except ValueError as e:
            if draw is not None and options and not isinstance(e, KidnapBeyondLimitError):  # a place in this layout
                raise ValueError(f"{e} (in the layout drawn for this reset: {draw.kind}, seed {draw.seed})") from None
            raise
        finally:
            if not done:
                self._rng, self.current, layout, layout_seed, grid = saved
                base.set_layout(layout, layout_seed, grid=grid, check_map=False)  # the map it had
        return out, draw

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Draw the next layout, then reset on it. A rejected reset (bad seed or options, raised
        by the env) changes nothing: the layout stream, the env's layout and map stay as they were."""
        (obs, info), draw = self._on_drawn_layout(
            seed, options, lambda: self.env.reset(seed=seed, options=options), keep=True
        )
        info["layout"] = draw.as_dict()
        return obs, info

    def check_reset_through(self, seed, options, inner) -> None:
        """`semreloc_env.wrappers.check_reset`'s hook: the inner envs check ``options`` on the layout this reset would
        draw (a start pose must be free there, not in the layout of the episode before). No episode changes: the layout
        stream and the env's layout are put back; the drawn layout's map stays in this wrapper's map cache (where the
        reset would put it), and `set_layout` closes a renderer, which reopens at the next frame."""
        self._on_drawn_layout(seed, options, lambda: inner(seed, options), keep=False)

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        info["layout"] = self.current.as_dict()
        return obs, reward, terminated, truncated, info
