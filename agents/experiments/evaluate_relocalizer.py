"""Evaluate the relocalizer: global relocalization and kidnapping, before vs after, Wilson intervals.

Each *variant* is a dict of ``MCLConfig`` overrides applied to ``SemReloc``'s default relocalizer (``{}`` = the env's
defaults); a variant's ``"env_id"`` key runs its episodes in another registered id (``{"env_id": "SemReloc-v18"}``:
v18 as it was, to compare with the newest). Every variant runs the same episodes: per row, ``--episodes`` episodes
pooled over the baseline policies (random walk, spin in place, wall following; ``--policies`` names others, the
viewpoint planner among them), each episode ``i`` with seed ``--seed-base + i``. Rows: the built-in layouts, the
changed lab, ``procedural_sym`` over ``--sym-seeds``, kidnap rows (tracking, then a teleport at step 30, 200 steps
after it), global-kidnap rows (``*_global_kidnap``: a global start, a teleport at step 150, 200 steps after it), a
class-only kidnap row (``twin_rooms_twin_kidnap``: tracking, then a teleport at step 30 to the half-turned image of
the pose in the other room, whose walls and furniture shapes are the same and whose classes differ) and a tracking row
(300 steps from the true pose: error and step time). Not by default: a look-alike kidnap row of any layout
(``<layout>_lookalike_kidnap``: tracking, then a teleport at step 30 to the place at least 3 m away whose all-round
view is most like the pose's) and its pair, ``<layout>_lookalike_global`` (a global start at the place that row's
episode of the same seed teleports to, 200 steps: whether a look-alike kidnapping fails for the place or for the
belief it leaves). ``--layout-files`` adds a global, a kidnap, a look-alike kidnap and a global-kidnap row for each
layout file of yours.

Tuning and reporting use disjoint seeds: defaults were chosen with ``--seed-base 5000
--sym-seeds 100 101 102 103 104``; the report in docs/relocalizer_eval.md uses the defaults below.

    python scripts/evaluate_relocalizer.py --variants before after --episodes 200 --out out/reloc_eval

(``semreloc-evaluate-relocalizer`` is the same command; ``--address`` runs the episodes on a Ray cluster.)
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from agents.relocalizer_eval import (
    KIDNAP_STEP,
    LAYOUT_FILE_SUFFIXES,
    POLICIES,
    EpisodeSpec,
    count_pct,
    env_class,
    log_tracking,
    log_trial,
    pct,
    policy_names,
    run_episode,
    save_jsonl,
    summarize,
    variant_parts,
    wilson,
)
from filters.experiments.cli import Runner, command, parse
from filters.experiments.report import markdown_table
from filters.experiments.runner import RunnerConfig, run_jobs
from filters.experiments.stats import mcnemar_exact_p
from filters.robot_data import ACES_LOG
from semreloc_env.envs.semreloc import LEGACY_RELOCALIZER_OVERRIDES

VARIANTS = {"before": LEGACY_RELOCALIZER_OVERRIDES, "after": {}}
"""``before``: the relocalizer of SemReloc-v0 (the first release's defaults); ``after``: the env's defaults."""

GLOBAL_ROWS = ("twin_rooms", "lab", "lab_changed", "procedural_sym", "three_rooms", "open_hall")
"""Global starts, 400 steps (also the layouts the built-in rows name: a layout file's stem must differ)."""
KIDNAP_ROWS = ("lab_kidnap", "three_rooms_kidnap")
GLOBAL_KIDNAP_ROWS = ("lab_global_kidnap", "three_rooms_global_kidnap")
"""A global start, then a teleport at step ``GLOBAL_KIDNAP_STEP`` (global localization, then kidnapped)."""
GLOBAL_KIDNAP_STEP = 150
TWIN_KIDNAP_ROWS = ("twin_rooms_twin_kidnap",)
"""Tracking, then a teleport at step 30 to the half-turned image of the pose: a kidnap only the classes reveal."""
TRACKING_ROWS = ("lab_tracking",)
ROW_KIND_WORDS = ("_kidnap", "_tracking", "_lookalike", "_twin", "_global")
"""Endings a layout file's stem may not have: its rows' names (``<stem>_kidnap``, ...) would read as another kind's."""
LOOKALIKE_SUFFIX = "_lookalike_kidnap"
"""A row ``<layout>_lookalike_kidnap``: tracking, then a teleport at step 30 to the place at least 3 m away whose
all-round view is most like the pose's (`agents.relocalizer_eval.lookalike_kidnap_pose`); any layout, not a
default row."""
LOOKALIKE_GLOBAL_SUFFIX = "_lookalike_global"
"""A row ``<layout>_lookalike_global``: a global start, 200 steps, at the place the ``<layout>_lookalike_kidnap`` row's
episode of the same seed teleports to: whether a look-alike kidnapping fails for the place or for the belief the
kidnapping leaves (the two rows' episodes pair by seed); any layout, not a default row."""


ROW_KINDS = (
    ("_global_kidnap", "global_kidnap"),
    ("_twin_kidnap", "twin_kidnap"),
    (LOOKALIKE_SUFFIX, "lookalike_kidnap"),
    (LOOKALIKE_GLOBAL_SUFFIX, "lookalike_global"),
    ("_kidnap", "kidnap"),
    ("_tracking", "tracking"),
)
"""A row's name ending and its kind, longer endings first; a name with none is a global row."""


def row_kind(row: str) -> tuple[str, str]:
    """``(base, kind)`` of a row: its name without its kind's ending (one ending only: ``lab_kidnap_tracking``'s
    base is ``lab_kidnap``), and the kind (`ROW_KINDS`, or ``"global"``)."""
    for suffix, kind in ROW_KINDS:
        if row.endswith(suffix):
            return row[: -len(suffix)], kind
    return row, "global"


def row_layout(row: str, files: dict[str, str] | None = None) -> tuple[str, str]:
    """``(base, layout)`` of a row: its name without the kind's suffix, and the layout (name or file) it runs."""
    base = row_kind(row)[0]
    return base, "lab" if base == "lab_changed" else (files or {}).get(base, base)


def specs_for(
    row: str,
    n: int,
    seed_base: int,
    sym_seeds: list[int],
    mcl: dict,
    label: str,
    files: dict[str, str] | None = None,
    policies: tuple[str, ...] = POLICIES,
) -> list[EpisodeSpec]:
    """The ``n`` episodes of ``row`` for one variant, episode ``i`` run by ``policies[i % len(policies)]``;
    ``files``: ``{row name: layout file}`` of `file_rows`."""
    kind = row_kind(row)[1]
    env_id, overrides = variant_parts(mcl)
    kidnap = kind in ("kidnap", "twin_kidnap", "lookalike_kidnap")  # tracking, then a teleport at KIDNAP_STEP
    global_kidnap = kind == "global_kidnap"
    base, layout = row_layout(row, files)
    scenario = "changed" if base == "lab_changed" else "nominal"
    kidnap_at = GLOBAL_KIDNAP_STEP if global_kidnap else KIDNAP_STEP if kidnap else 0
    n_steps = (
        kidnap_at + 200 if kidnap_at else 300 if kind == "tracking" else 200 if kind == "lookalike_global" else 400
    )
    out = []
    for i in range(n):
        out.append(
            EpisodeSpec(
                layout=layout,
                seed=seed_base + i,
                policy=policies[i % len(policies)],
                layout_seed=sym_seeds[i % len(sym_seeds)] if layout.startswith("procedural") else 0,
                scenario=scenario,
                n_steps=n_steps,
                kidnap_at_step=kidnap_at,
                tracking=kind == "tracking",
                mcl=overrides,
                env_id=env_id,
                label=label,
                kidnap_after_global=global_kidnap,
                kidnap_to_twin=kind == "twin_kidnap",
                kidnap_to_lookalike=kind == "lookalike_kidnap",
                global_at_lookalike=kind == "lookalike_global",
            )
        )
    return out


def file_rows(paths) -> tuple[dict[str, str], list[str]]:
    """``({row name: path}, rows)`` of ``--layout-files``: per file, named by its file name's stem, a global row,
    a tracking-then-kidnap row (``*_kidnap``), a tracking-then-look-alike-kidnap row (``*_lookalike_kidnap``) and a
    global-then-kidnap row (``*_global_kidnap``).

    Raises:
        ValueError: a file that is not a valid layout (the message names it and the entry), two files with one
            stem, or a stem a built-in row uses.
    """
    from semreloc_env.layouts import LayoutError, get_layout

    files: dict[str, str] = {}
    for path in paths:
        path = str(path)
        stem = Path(path).stem
        if not path.endswith(LAYOUT_FILE_SUFFIXES):
            raise ValueError(f"layout file {path!r}: must end in one of {LAYOUT_FILE_SUFFIXES}")
        if stem.endswith(ROW_KIND_WORDS):
            raise ValueError(
                f"layout file {path!r}: a name ending in {' or '.join(ROW_KIND_WORDS)} names a row kind (its rows "
                "would be read as another kind's); rename it"
            )
        if stem in files or stem in GLOBAL_ROWS:
            raise ValueError(
                f"layout file {path!r}: its row name {stem!r} is taken "
                f"({'by ' + repr(files[stem]) if stem in files else 'by a built-in row'}); rename the file"
            )
        try:
            get_layout(path)
        except (LayoutError, ValueError, OSError) as e:
            raise ValueError(f"layout file {path!r}: {e}") from None
        files[stem] = path
    rows = [r for stem in files for r in (stem, f"{stem}_kidnap", f"{stem}{LOOKALIKE_SUFFIX}", f"{stem}_global_kidnap")]
    return files, rows


def table(results: list[dict], variants: list[str], rows: list[str]) -> str:
    """The Markdown table of the episode rows: one line per (row, variant) with episodes.

    *reconverged wrong* and *pre-kidnap success* (count · rate [Wilson 95 %]) are for kidnap rows
    (``—`` in the others)."""
    header = ["row", "variant", "episodes", "success", "wrong", "unconverged", "ever wrong", "median steps",
              "calibration", "median error m", "CPU ms/step", "mean particles", "reconverged wrong",
              "pre-kidnap success"]  # fmt: skip
    lines = []
    for row in rows:
        for v in variants:
            rs = [r for r in results if r["row"] == row and r["label"] == v]
            if not rs:
                continue
            s = summarize(rs)
            lines.append(
                [row, v, s["episodes"], pct(s["success"]), pct(s["wrong"]), pct(s["unconverged"]),
                 pct(s["ever_wrong"]), f"{s['median_steps']:.0f}", pct(s["calibration"]),
                 f"{s['median_error_m']:.3f}", f"{s['cpu_ms_per_step']:.2f}", f"{s['mean_particles']:.0f}",
                 count_pct(s["reconverged_wrong"]), count_pct(s["pre_kidnap_success"])]
            )  # fmt: skip
    return markdown_table(header, lines) + "\n"


def kidnap_table(results: list[dict], variants: list[str], rows: list[str]) -> str:
    """The Markdown table of what the relocalizer did after the kidnap, per kidnap row and variant
    (episodes with it; "" when no row has kidnap episodes): augmented-MCL recovery injection
    (``p_inject`` above the routine ``proposal_frac``) and global re-inits, the averages the
    teleport found, surprises (`MCLConfig.surprise_ratio`), convergence audits (those with pre-kidnap
    scans in their window: stale)."""
    header = ["row", "variant", "episodes", "converged at kidnap", "recovery injection", "median max p_inject",
              "median w_slow / w_fast at kidnap", "global re-init", "surprise", "audits (added)",
              "stale-window audits (added)"]  # fmt: skip
    lines = []
    for row in rows:
        for v in variants:
            rs = [r for r in results if r["row"] == row and r["label"] == v and r.get("kidnapped_at") is not None]
            if not rs or "recovery_steps" not in rs[0]:
                continue

            def eps(name: str, rs: list[dict] = rs) -> str:  # episodes where it happened (0 in older results)
                return str(sum(r.get(name, 0) > 0 for r in rs))

            def med(name: str, rs: list[dict] = rs) -> float:
                return float(np.median([r[name] for r in rs]))

            lines.append(
                [row, v, len(rs), sum(bool(r["converged_at_kidnap"]) for r in rs), eps("recovery_steps"),
                 f"{med('max_p_inject'):.2f}", f"{med('w_slow_at_kidnap'):.3f} / {med('w_fast_at_kidnap'):.3f}",
                 eps("reinit_steps"), eps("surprises"), f"{eps('audits')} ({eps('audit_adds')})",
                 f"{eps('stale_audits')} ({eps('stale_audit_adds')})"]
            )  # fmt: skip
    return markdown_table(header, lines) + "\n" if lines else ""


def lookalike_pair_table(results: list[dict], variants: list[str], rows: list[str]) -> str:
    """The Markdown table pairing each ``<layout>_lookalike_kidnap`` row with its ``<layout>_lookalike_global`` row
    where both ran, episode by episode (the same seed and policy, and the global start at the place the kidnapping
    went to: an episode whose ``start_pose`` is not its pair's ``kidnap_pose`` is left out), one line per layout,
    variant and policy, with an ``all`` line per variant and policy over the layouts when there are several:
    successes after the kidnapping and from the global start, the places only one of them succeeded from, McNemar's
    exact p ("" when no layout has both rows)."""
    header = ["layout", "variant", "policy", "places", "success after the kidnap", "success from a global start there",
              "only after the kidnap", "only from the global start", "McNemar p"]  # fmt: skip
    stems = [r.removesuffix(LOOKALIKE_SUFFIX) for r in rows if r.endswith(LOOKALIKE_SUFFIX)]
    stems = [b for b in stems if b + LOOKALIKE_GLOBAL_SUFFIX in rows]
    lines = []
    for v in variants:
        policies = sorted({r["policy"] for r in results if r["label"] == v})
        for policy in policies:
            total = np.zeros(4, dtype=np.int64)  # places, only after the kidnap, only from the global start, both
            done = 0
            mine = [r for r in results if r["label"] == v and r["policy"] == policy]
            for stem in stems:
                kid = {r["seed"]: r for r in mine if r["row"] == stem + LOOKALIKE_SUFFIX}
                glob = {r["seed"]: r for r in mine if r["row"] == stem + LOOKALIKE_GLOBAL_SUFFIX}
                same = [
                    k for k in sorted(kid.keys() & glob.keys()) if glob[k].get("start_pose") == kid[k]["kidnap_pose"]
                ]
                pairs = [(kid[k]["outcome"] == "success", glob[k]["outcome"] == "success") for k in same]
                if not pairs:
                    continue
                a, b = np.array(pairs, dtype=bool).T
                counts = np.array([a.size, np.sum(a & ~b), np.sum(~a & b), np.sum(a & b)])
                total += counts
                done += 1
                lines.append(_pair_line(stem, v, policy.partition("=")[0], counts))
            if done > 1:
                lines.append(_pair_line("all", v, policy.partition("=")[0], total))
    return markdown_table(header, lines) + "\n" if lines else ""


def _pair_line(name: str, variant: str, policy: str, counts: np.ndarray) -> list:
    n, only_kidnap, only_global, both = (int(c) for c in counts)
    return [name, variant, policy, n, both + only_kidnap, both + only_global, only_kidnap, only_global,
            f"{mcnemar_exact_p(only_kidnap, only_global):.2g}"]  # fmt: skip


def log_table(trials: list[dict], tracks: list[dict], names: list[str]) -> str:
    """The Markdown table of the log rows: global-localization trials and tracking per variant."""
    header = ["variant", "starts", "correct", "wrong", "unconverged", "median scans to correct",
              "CPU s per trial", "tracking median error m (seeds)"]  # fmt: skip
    lines = []
    for v in names:
        ts = [t for t in trials if t["label"] == v]
        if not ts:
            continue
        n = len(ts)
        cell = {o: (sum(t["outcome"] == o for t in ts) / n, *wilson(sum(t["outcome"] == o for t in ts), n)) for o in
                ("correct", "wrong", "unconverged")}  # fmt: skip
        ok = [t["steps"] for t in ts if t["outcome"] == "correct"]
        med = f"{sorted(ok)[len(ok) // 2]}" if ok else "—"
        tr = [t for t in tracks if t["label"] == v]
        trk = ", ".join(f"{t['pos_median_m']:.3f}" for t in tr) or "—"
        lines.append(
            [v, n, pct(cell["correct"]), pct(cell["wrong"]), pct(cell["unconverged"]), med,
             f"{sum(t['cpu_s'] for t in ts) / n:.1f}", trk]
        )  # fmt: skip
    return markdown_table(header, lines) + "\n"


@dataclass(frozen=True)
class Args:
    """Evaluate the relocalizer: global relocalization and kidnapping, before vs after, Wilson intervals."""

    variants: tuple[str, ...] = ("before", "after")
    """names of VARIANTS (or of --extra) to run"""
    extra: str = "{}"
    """JSON {"name": {MCLConfig overrides}} of more variants; an "env_id" key names the SemReloc id they run in
    (default: the newest)"""
    rows: tuple[str, ...] = GLOBAL_ROWS + KIDNAP_ROWS + GLOBAL_KIDNAP_ROWS + TWIN_KIDNAP_ROWS + TRACKING_ROWS
    """rows to run ('none' = only the log rows)"""
    layout_files: tuple[str, ...] = ()
    """layout files of your own (.json / .yaml): each adds four rows named by the file name's stem: a global
    start, a tracking start kidnapped at step 30 to a random place (_kidnap) and to the place that looks most
    like the pose (_lookalike_kidnap), a global start kidnapped at step 150"""
    episodes: int = 200
    """episodes per row and variant"""
    policies: tuple[str, ...] = POLICIES
    """the policies each row's episodes take in turn (episode i: policies[i % n]); the default three make the
    documented rows; any of random, spin, wall_follow, spin_backup, info_gain, viewpoint (the viewpoint planner,
    agents.policies), NAME=PATH (a policy saved by train_active, discrete actions) or NAME=MODULE:CLASS /
    NAME=path/to/file.py:CLASS (your own, CLASS(seed) with wrap, reset and act), as evaluate_active takes them"""
    before_episodes: int = 0
    """episodes per row of 'before' (0 = --episodes)"""
    seed_base: int = 0
    """seed of episode 0"""
    sym_seeds: tuple[int, ...] = tuple(range(10))
    """procedural_sym layout seeds"""
    out: str = "out/reloc_eval"
    """output folder (results.jsonl, log_results.jsonl, table.md; all written at the end, from this run only)"""
    log_starts: int = 44
    """ACES log: evenly spaced start scans (0 = skip the log)"""
    log_steps: int = 60
    """ACES log: scans per global-localization trial"""
    log_tracking_seeds: int = 3
    """ACES log: tracking runs over the whole log"""
    runner: Runner = RunnerConfig(workers=2)

    def __post_init__(self) -> None:
        unknown = [v for v in self.variants if v not in self.all_variants()]
        if unknown:
            raise ValueError(f"unknown variants {unknown}; known: {sorted(self.all_variants())}")
        if self.episodes < 0 or self.before_episodes < 0 or self.log_starts < 0 or not self.sym_seeds:
            raise ValueError("episodes, before_episodes and log_starts must be >= 0 and sym_seeds not empty")
        from agents.experiments.evaluate_active import check_policy_specs

        check_policy_specs(self.policies, policy_names())
        if self.log_starts and not 1 <= self.log_steps <= 440:
            raise ValueError(f"log_steps must be in 1..440 (the log has 440 scans), got {self.log_steps}")
        files, rows = self.row_list()  # raises on a bad file, before any episode runs
        for name, values in (("rows", rows), ("variants", self.variants), ("sym_seeds", self.sym_seeds)):
            twice = sorted({v for v in values if values.count(v) > 1}, key=str)
            if twice:  # the same seeded episodes would count twice (a row may also come from a --layout-files stem)
                raise ValueError(f"{name}: {twice} given more than once")
        from semreloc_env.layouts import check_layout_option

        for row in self.rows:
            base, layout = row_layout(row, files)
            if row != "none" and base not in files:  # a built-in name, a name on $SEMRELOC_LAYOUT_PATH, a path
                check_layout_option(layout, f"rows: unknown row {row!r}")
        episodes = [self.episodes_of(v) for v in self.variants]
        if not self.variants or ((not rows or max(episodes) == 0) and self.log_starts == 0):
            raise ValueError("nothing to run: no variant, or no rows (or no episodes) and --log-starts 0")
        from filters.localization.mcl import check_overrides

        variants = self.all_variants()
        for name in self.variants:  # on top of the env's relocalizer, as the episodes apply them
            env_id, overrides = variant_parts(variants[name])
            try:
                default = env_class(env_id).default_relocalizer
            except ValueError as e:
                raise ValueError(f"variant {name!r}: {e}") from None
            check_overrides(overrides, f"variant {name!r}", default)

    def row_list(self) -> tuple[dict[str, str], list[str]]:
        """``({row name: layout file}, the rows to run)``: ``--rows`` (without ``none``), then four rows per
        ``--layout-files`` file (`file_rows`)."""
        files, extra_rows = file_rows(self.layout_files)
        return files, [r for r in self.rows if r and r != "none"] + extra_rows

    def episodes_of(self, variant: str) -> int:
        """Episodes per row of ``variant``: ``--before-episodes`` for 'before' if set, else ``--episodes``."""
        return self.before_episodes if variant == "before" and self.before_episodes > 0 else self.episodes

    def all_variants(self) -> dict[str, dict]:
        """VARIANTS plus ``--extra``."""
        extra = json.loads(self.extra)
        if not isinstance(extra, dict) or not all(isinstance(v, dict) for v in extra.values()):
            raise ValueError(f'extra must be a JSON object {{"name": {{overrides}}}}, got {self.extra!r}')
        return {**VARIANTS, **extra}


@command
def main(argv: list[str] | None = None) -> int:
    """The command: parse ``argv`` (default ``sys.argv[1:]``), run the episodes and log trials, write the tables."""
    args = parse(Args, argv, __doc__)
    variants = args.all_variants()
    names = list(args.variants)
    files, rows = args.row_list()
    specs = []
    for row in rows:  # grouped by row, so a worker meets few layouts (maps are cached per process)
        for v in names:
            n = args.episodes_of(v)
            if row.endswith("_tracking"):
                n = min(n, 30)  # tracking rows measure error and step time only
            specs += specs_for(row, n, args.seed_base, list(args.sym_seeds), variants[v], v, files, args.policies)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.time()
    results = run_jobs(run_episode, specs, args.runner, desc="episodes")
    md = table(results, names, rows) if results else ""
    kt = kidnap_table(results, names, rows)
    if kt:
        md += "\n### After the kidnap (episodes)\n\n" + kt
    pt = lookalike_pair_table(results, names, rows)
    if pt:
        md += "\n### Look-alike kidnappings beside global starts at the same places (paired by seed)\n\n" + pt
    if args.log_starts > 0:
        log_path = str(ACES_LOG)
        n_scans = 440
        starts = [round(i * (n_scans - args.log_steps) / args.log_starts) for i in range(args.log_starts)]
        trial_jobs = [(log_path, v, variants[v], s, args.log_steps) for v in names for s in starts]
        trials = run_jobs(log_trial, trial_jobs, args.runner, desc="log trials")
        track_jobs = [(log_path, v, variants[v], k) for v in names for k in range(args.log_tracking_seeds)]
        tracks = run_jobs(log_tracking, track_jobs, args.runner, desc="log tracking")
        md += "\n### ACES log (lidar only, map from the corrected poses)\n\n" + log_table(trials, tracks, names)
    # every file at the end, from this run only: an interrupted run leaves the folder as it was
    save_jsonl(results, out / "results.jsonl")
    log_file = out / "log_results.jsonl"
    if args.log_starts > 0:
        save_jsonl(trials + tracks, log_file)
    elif log_file.exists():
        log_file.unlink()  # an earlier run's, which this run's table does not show
    (out / "table.md").write_text(md)
    print(md)
    print(f"{len(results)} episodes in {time.time() - t0:.0f} s; written to {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
