"""agents.relocalizer_eval: episode specs (global start, then a kidnap), the per-episode scoring, the rows."""

import math
from pathlib import Path

import pytest

from agents.experiments.evaluate_relocalizer import GLOBAL_KIDNAP_ROWS, Args, kidnap_table, specs_for, table
from agents.relocalizer_eval import EpisodeSpec, make_policy, run_episode, score_steps, summarize, twin_image

TWIN_OFFICES = Path(__file__).resolve().parents[1] / "docs" / "layouts" / "twin_offices.json"

# ------------------------------------------------------------------ specs

DOCS_LAYOUTS = Path(__file__).resolve().parents[1] / "docs" / "layouts"


def test_row_names_and_reset_options():
    glob = EpisodeSpec(layout="lab", seed=0, policy="spin", n_steps=350, kidnap_at_step=150, kidnap_after_global=True)
    assert glob.row == "lab_global_kidnap"
    assert glob.reset_options == {"kidnap_at_step": 150}  # no "tracking": a global start
    track = EpisodeSpec(layout="lab", seed=0, policy="spin", kidnap_at_step=30)
    assert track.row == "lab_kidnap"
    assert track.reset_options == {"tracking": True, "kidnap_at_step": 30}
    assert EpisodeSpec(layout="lab", seed=0, policy="spin", tracking=True).row == "lab_tracking"
    assert EpisodeSpec(layout="lab", seed=0, policy="spin").reset_options is None
    changed = EpisodeSpec(
        layout="lab", seed=0, policy="spin", scenario="changed", kidnap_at_step=5, kidnap_after_global=True
    )
    assert changed.row == "lab_changed_global_kidnap"


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"kidnap_after_global": True}, "kidnap_after_global needs kidnap_at_step >= 1"),
        ({"kidnap_after_global": True, "kidnap_at_step": 0}, "kidnap_after_global needs kidnap_at_step >= 1"),
        ({"kidnap_after_global": True, "kidnap_at_step": 5, "tracking": True}, "tracking must be False"),
        ({"kidnap_after_global": True, "kidnap_at_step": 500}, "after the last step"),
        ({"kidnap_at_step": -1}, "kidnap_at_step must be an integer >= 0"),
        ({"kidnap_at_step": 2.0}, "kidnap_at_step must be an integer >= 0"),
        ({"kidnap_at_step": True}, "kidnap_at_step must be an integer >= 0"),
        ({"kidnap_after_global": "yes", "kidnap_at_step": 5}, "kidnap_after_global must be True or False"),
        ({"n_steps": 0}, "n_steps must be an integer >= 1"),
        ({"kidnap_to_twin": True, "kidnap_at_step": 30}, r"kidnap_to_twin needs a layout of \['twin_rooms'\]"),
        ({"kidnap_to_twin": True, "layout": "twin_rooms"}, "kidnap_to_twin needs a tracking start"),
        ({"kidnap_to_twin": True, "layout": "twin_rooms", "kidnap_at_step": 1}, "kidnap_at_step >= 2"),
        ({"kidnap_to_twin": 1, "layout": "twin_rooms", "kidnap_at_step": 30}, "kidnap_to_twin must be True or False"),
        ({"kidnap_to_lookalike": True}, "kidnap_to_lookalike needs a tracking start"),
        ({"kidnap_to_lookalike": True, "kidnap_at_step": 1}, "kidnap_at_step >= 2"),
        ({"kidnap_to_lookalike": True, "kidnap_at_step": 5, "kidnap_after_global": True}, "needs a tracking start"),
        ({"global_at_lookalike": True, "kidnap_at_step": 30}, "global_at_lookalike is a global start without a kidnap"),
        ({"global_at_lookalike": True, "tracking": True}, "global_at_lookalike is a global start without a kidnap"),
        ({"global_at_lookalike": 1}, "global_at_lookalike must be True or False"),
    ],
)
def test_bad_specs_are_refused(kwargs, match):
    with pytest.raises(ValueError, match=match):
        EpisodeSpec(**{"layout": "lab", "seed": 0, "policy": "spin", **kwargs})


def test_global_kidnap_rows_make_global_start_kidnap_specs():
    for row in GLOBAL_KIDNAP_ROWS:
        specs = specs_for(row, 4, 0, [0], {}, "after")
        assert [s.row for s in specs] == [row] * 4
        assert all(s.kidnap_after_global and not s.tracking for s in specs)
        assert {(s.kidnap_at_step, s.n_steps) for s in specs} == {(150, 350)}
        assert [s.policy for s in specs] == ["random", "spin", "wall_follow", "random"]
    (s,) = specs_for("lab_kidnap", 1, 0, [0], {}, "after")  # the tracking kidnap rows are unchanged
    assert (s.kidnap_after_global, s.kidnap_at_step, s.n_steps, s.reset_options["tracking"]) == (False, 30, 230, True)


# ------------------------------------------------------------------ the env does what the spec says


def test_a_global_kidnap_spec_starts_global_and_teleports_at_k_also_after_termination():
    from semreloc_env.envs.semreloc import SemRelocEnv

    spec = EpisodeSpec(
        layout="lab", seed=0, policy="wall_follow", n_steps=12, kidnap_at_step=8, kidnap_after_global=True
    )
    env = SemRelocEnv(layout="lab")
    obs, info = env.reset(seed=spec.seed, options=spec.reset_options)
    assert not info["belief"]["converged"] and info["belief"]["pos_std_m"] > 1.0  # spread over the map
    policy = make_policy(spec.policy, spec.seed)
    flags, terminated = [], []
    for _ in range(spec.n_steps):
        obs, _, term, _, info = env.step(policy(obs))
        flags.append(info["kidnapped"])
        terminated.append(term)
    assert flags == [False] * 7 + [True] * 5  # teleported at step 8 exactly
    assert any(terminated[:7])  # this seed succeeds before the kidnap: the env said terminated...
    # ...and run_episode steps on, so the kidnap happens and the steps after it are scored
    out = run_episode(spec)
    assert out["row"] == "lab_global_kidnap"
    assert out["kidnapped_at"] == 8
    assert out["pre_kidnap_success"] is True
    assert out["converged_steps"] <= 5  # steps 8..12 only
    for name in ("reconverged_wrong", "converged_at_kidnap"):
        assert isinstance(out[name], bool)
    assert out["recovery_steps"] >= 0 and out["stale_audits"] >= 0


def test_a_lookalike_kidnap_teleports_to_the_place_that_looks_most_like_the_pose_before_it():
    """``<layout>_lookalike_kidnap``: tracking, then at step 30 a teleport to `lookalike_kidnap_pose` of the pose
    after step 29; in ``twin_rooms`` that is the half-turned image (the same walls and shapes, other classes)."""
    from agents.relocalizer_eval import lookalike_kidnap_pose
    from semreloc_env.envs.semreloc import SemRelocEnv
    from semreloc_env.lookalike import view_mismatch

    (spec,) = specs_for("twin_rooms_lookalike_kidnap", 1, 3, [0], {}, "after")
    expected = ("twin_rooms_lookalike_kidnap", "twin_rooms", 30, 230)
    assert (spec.row, spec.layout, spec.kidnap_at_step, spec.n_steps) == expected
    assert spec.kidnap_to_lookalike and not spec.kidnap_to_twin
    assert "twin_rooms_lookalike_kidnap" not in Args().rows  # not a default row
    short = EpisodeSpec(**{**spec.__dict__, "n_steps": 32})
    out = run_episode(short)
    again = run_episode(short)
    assert {k: v for k, v in out.items() if k != "cpu_s_per_step"} == {
        k: v for k, v in again.items() if k != "cpu_s_per_step"
    }  # the search is seeded by the episode
    env = SemRelocEnv(layout="twin_rooms")
    obs, info = env.reset(seed=short.seed, options={"tracking": True})
    policy = make_policy(short.policy, short.seed)
    for _ in range(29):
        obs, _, _, _, info = env.step(policy(obs))
    found = lookalike_kidnap_pose(env, info["pose"], short.seed)
    assert out["kidnapped_at"] == 30 and out["kidnap_pose"] == found.pose.tolist()
    # this pose lies 0.2 m from the rooms' shared wall, its half-turned image 1.25 m away: too near to be a kidnap
    assert math.dist(info["pose"][:2], twin_image("twin_rooms", info["pose"])[:2]) < 3.0 <= found.distance_m
    assert view_mismatch(env.world, info["pose"], found.pose) == pytest.approx(found.mismatch_m, abs=0.02)
    # a cluttered 3.2 m x 2.6 m room has no free place 3 m from most poses: the kidnapping goes half as far, or less
    tiny = SemRelocEnv(layout=str(DOCS_LAYOUTS / "outside_v11" / "d4_tiny_cluttered.json"), map_source="perfect")
    tiny.reset(seed=0)
    near = lookalike_kidnap_pose(tiny, [0.8476569465482231, 1.4808593565037547, 0.0], 0)
    assert 0.375 <= near.distance_m < 3.0 and tiny.world.is_free(near.pose[:2])


@pytest.mark.parametrize("policy", ["wall_follow", "viewpoint"])
def test_a_lookalike_global_row_starts_globally_where_the_lookalike_kidnap_row_teleports_seed_for_seed(policy):
    """``<layout>_lookalike_global``: a global start (a spread belief, no kidnap) at the pose the
    ``<layout>_lookalike_kidnap`` episode of the same seed and policy teleports to, scored over 200 steps."""
    from semreloc_env.envs.semreloc import SemRelocEnv

    (kid,) = specs_for("twin_rooms_lookalike_kidnap", 1, 4, [0], {}, "after", policies=(policy,))
    (glob,) = specs_for("twin_rooms_lookalike_global", 1, 4, [0], {}, "after", policies=(policy,))
    expected = ("twin_rooms_lookalike_global", "twin_rooms", 4, policy)
    assert (glob.row, glob.layout, glob.seed, glob.policy) == expected
    assert (glob.n_steps, glob.kidnap_at_step, glob.tracking, glob.reset_options) == (200, 0, False, None)
    assert glob.global_at_lookalike and not kid.global_at_lookalike
    assert "twin_rooms_lookalike_global" not in Args().rows  # not a default row
    kidnapped = run_episode(EpisodeSpec(**{**kid.__dict__, "n_steps": 31}))
    out = run_episode(EpisodeSpec(**{**glob.__dict__, "n_steps": 3}))
    assert out["row"] == "twin_rooms_lookalike_global" and out["kidnapped_at"] is None and out["kidnap_pose"] is None
    assert out["start_pose"] == kidnapped["kidnap_pose"] and kidnapped["start_pose"] is None
    env = SemRelocEnv(layout="twin_rooms")
    _, info = env.reset(seed=glob.seed, options={"pose": out["start_pose"]})
    assert info["pose"] == pytest.approx(out["start_pose"], abs=1e-9)
    assert not info["belief"]["converged"] and info["belief"]["pos_std_m"] > 1.0  # spread over the map
    assert out["reconverged_wrong"] is None  # scored as a global start


def test_a_twin_kidnap_teleports_to_the_half_turned_image_of_the_pose_before_it():
    """``twin_rooms_twin_kidnap``: tracking, then at step 30 a teleport to the half-turned image of the pose after
    step 29 (the other room: the same walls and furniture shapes, other classes). The default rows include it."""
    from semreloc_env.envs.semreloc import SemRelocEnv

    assert "twin_rooms_twin_kidnap" in Args().rows
    (spec,) = specs_for("twin_rooms_twin_kidnap", 1, 3, [0], {}, "after")
    assert (spec.row, spec.layout, spec.kidnap_at_step, spec.n_steps) == (
        "twin_rooms_twin_kidnap",
        "twin_rooms",
        30,
        230,
    )
    assert spec.kidnap_to_twin and spec.reset_options == {"tracking": True, "kidnap_at_step": 30}
    assert twin_image("twin_rooms", [1.0, 2.0, 0.5]) == pytest.approx([11.0, 4.0, 0.5 - math.pi])
    assert twin_image("twin_rooms", [1.0, 2.0, -0.5])[2] == pytest.approx(math.pi - 0.5)
    short = EpisodeSpec(**{**spec.__dict__, "n_steps": 34})
    out = run_episode(short)
    env = SemRelocEnv(layout="twin_rooms")  # the steps before the kidnap, by hand
    obs, info = env.reset(seed=short.seed, options={"tracking": True})
    policy = make_policy(short.policy, short.seed)
    for _ in range(29):
        obs, _, _, _, info = env.step(policy(obs))
    assert out["kidnapped_at"] == 30 and out["kidnap_pose"] == twin_image("twin_rooms", info["pose"])
    assert out["converged_at_kidnap"] is True and out["pre_kidnap_success"] is True
    obs, info = env.reset(seed=short.seed, options={**short.reset_options, "kidnap_pose": out["kidnap_pose"]})
    policy = make_policy(short.policy, short.seed)
    for _ in range(30):
        before = info["pose"]
        obs, _, _, _, info = env.step(policy(obs))
    assert info["kidnapped"] and math.dist(info["pose"][:2], out["kidnap_pose"][:2]) < 0.1  # landed there
    assert (before[0] - 6.0) * (out["kidnap_pose"][0] - 6.0) < 0.0  # from the other room (the wall at x = 6 m)


# ------------------------------------------------------------------ scoring (no env)

C, U = True, False  # converged, unconverged
R, W = True, False  # near the truth (right), not (wrong)


def score(conv, near, k=0):
    return score_steps(conv, near, k)


def test_scoring_without_a_kidnap():
    s = score([U, U, C, C, U], [W, W, W, R, R])
    assert (s["outcome"], s["steps"], s["ever_wrong"]) == ("success", 3, True)
    assert (s["converged_steps"], s["converged_correct_steps"]) == (2, 1)
    assert s["reconverged_wrong"] is None and s["pre_kidnap_success"] is None and s["converged_at_kidnap"] is None
    assert score([U, U, C], [W, W, W])["outcome"] == "wrong"
    assert score([U, C, U], [W, R, W])["outcome"] == "success"
    assert score([U, C, U], [W, W, W])["outcome"] == "unconverged"


def test_reconverged_wrong_needs_the_belief_to_leave_the_stale_place_first():
    # index 0 = the reset, kidnap at step 3: the teleport finds the belief converged (step 2)
    stale_only = score([U, C, C, C, C, U, C], [W, R, R, W, W, W, R], k=3)
    assert stale_only["ever_wrong"] and not stale_only["reconverged_wrong"]  # converged wrong: the old place only
    assert stale_only["outcome"] == "success" and stale_only["steps"] == 4  # step 6, counted from step 3
    assert stale_only["pre_kidnap_success"] and stale_only["converged_at_kidnap"]
    assert (stale_only["converged_steps"], stale_only["converged_correct_steps"]) == (3, 1)  # steps 3..6 only

    again = score([U, C, C, C, U, U, C, C, C], [W, R, R, W, W, W, W, W, R], k=3)
    assert again["reconverged_wrong"] and again["ever_wrong"] and again["outcome"] == "success"

    # after the first success, a wrong convergence is not a failed recovery
    late = score([U, C, C, U, C, U, C], [W, R, R, W, R, W, W], k=3)
    assert not late["reconverged_wrong"] and late["steps"] == 2

    # the teleport found the belief unconverged (no pre-kidnap convergence): converging wrong counts
    fresh = score([U, U, U, C, C], [W, W, W, W, W], k=3)
    assert fresh["reconverged_wrong"] and fresh["outcome"] == "wrong"
    assert not fresh["pre_kidnap_success"] and not fresh["converged_at_kidnap"]

    # a kidnap at step 1: the belief it finds is the reset's
    assert score([U, C, C], [W, W, R], k=1)["reconverged_wrong"]
    assert not score([C, C, U, C], [R, W, W, R], k=1)["reconverged_wrong"]
    # pre-kidnap success counts steps 1..K-1 only (not the reset, not the kidnap step)
    assert not score([C, U, C, C], [R, W, R, R], k=2)["pre_kidnap_success"]
    assert score([U, C, U, U], [W, R, W, W], k=2)["pre_kidnap_success"]


def test_scoring_refuses_bad_input():
    with pytest.raises(ValueError, match="same length"):
        score_steps([U, C], [W], 0)
    with pytest.raises(ValueError, match="same length >= 2"):
        score_steps([U], [W], 0)
    with pytest.raises(ValueError, match=r"kidnap_at_step must be an integer in \[0, 2\]"):
        score_steps([U, C, C], [W, R, R], 3)


def test_summary_and_tables_carry_the_kidnap_columns():
    base = {"label": "after", "steps": 4, "ever_wrong": True, "converged_steps": 10, "converged_correct_steps": 9,
            "cpu_s_per_step": 1e-3, "mean_particles": 500.0, "median_error_m": 0.05, "kidnapped_at": 150,
            "converged_at_kidnap": True, "recovery_steps": 0, "max_p_inject": 0.0, "w_slow_at_kidnap": 0.08,
            "w_fast_at_kidnap": 0.7, "reinit_steps": 0, "audits": 2, "audit_adds": 1, "stale_audits": 1,
            "stale_audit_adds": 1, "surprises": 1}  # fmt: skip
    rs = [
        {
            **base,
            "row": "lab_global_kidnap",
            "outcome": "success",
            "reconverged_wrong": k < 1,
            "pre_kidnap_success": k < 3,
        }
        for k in range(4)
    ]
    s = summarize(rs)
    assert s["reconverged_wrong"][:3] == (1, 4, 0.25)
    assert s["pre_kidnap_success"][:3] == (3, 4, 0.75)
    assert math.isnan(summarize([{**rs[0], "reconverged_wrong": None}])["reconverged_wrong"][2])
    md = table(rs, ["after"], ["lab_global_kidnap"])
    assert "reconverged wrong" in md.splitlines()[0] and "| 1 · 25 % [" in md
    kt = kidnap_table(rs, ["after"], ["lab_global_kidnap"])
    assert "stale-window audits (added)" in kt and "| 4 (4) |" in kt
    assert "| surprise |" in kt.splitlines()[0] and "| 0 | 4 | 4 (4) | 4 (4) |" in kt  # re-inits, surprises, audits
    no_surprise = [{k: v for k, v in r.items() if k != "surprises"} for r in rs]  # results made before the column
    assert "| 0 | 0 | 4 (4) | 4 (4) |" in kidnap_table(no_surprise, ["after"], ["lab_global_kidnap"])
    old = [{k: v for k, v in r.items() if k not in ("reconverged_wrong", "pre_kidnap_success")} for r in rs]
    assert table(old, ["after"], ["lab_global_kidnap"]).splitlines()[2].endswith("| — | — |")  # older results


def test_the_pair_table_pairs_lookalike_kidnaps_with_global_starts_at_the_same_places():
    """Per layout and policy with both rows, the same (seed, policy) pairs whose global start is at the kidnapping's
    place; a row without its pair, another variant's episodes, an unpaired episode and a pair whose places differ
    are left out; an ``all`` line per policy sums the layouts; McNemar's exact p."""
    from agents.experiments.evaluate_relocalizer import lookalike_pair_table
    from filters.experiments.stats import mcnemar_exact_p

    def ep(row, seed, ok, label="after", policy="viewpoint", place=None):
        place = [float(seed), 1.0, 0.0] if place is None else place
        where = {"kidnap_pose": place} if row.endswith("_kidnap") else {"start_pose": place}
        return {"row": row, "seed": seed, "policy": policy, "label": label, "outcome": "success" if ok else "wrong",
                **where}  # fmt: skip

    a_kid = [True, True, False, False, False, True]  # seeds 0-5 of layout a: kidnapping ...
    a_glob = [True, False, True, True, False, True]  # ... and the global start at its place
    rs = [ep("a_lookalike_kidnap", i, k) for i, k in enumerate(a_kid)]
    rs += [ep("a_lookalike_global", i, g) for i, g in enumerate(a_glob)]
    rs += [ep("a_lookalike_kidnap", 9, True), ep("a_lookalike_global", 0, False, label="before")]  # unpaired, other
    rs += [ep("a_lookalike_kidnap", 7, False), ep("a_lookalike_global", 7, True, place=[0.0, 0.0, 0.0])]  # elsewhere
    rs += [ep("b_lookalike_kidnap", 0, False), ep("b_lookalike_global", 0, True), ep("c_lookalike_kidnap", 0, True)]
    rs += [ep("a_lookalike_kidnap", 0, False, policy="spin"), ep("a_lookalike_global", 0, False, policy="spin")]
    rows = ["a_lookalike_kidnap", "a_lookalike_global", "b_lookalike_kidnap", "b_lookalike_global",
            "c_lookalike_kidnap"]  # fmt: skip
    lines = lookalike_pair_table(rs, ["after"], rows).splitlines()
    assert lines[2] == f"| a | after | spin | 1 | 0 | 0 | 0 | 0 | {mcnemar_exact_p(0, 0):.2g} |"
    assert lines[3] == f"| a | after | viewpoint | 6 | 3 | 4 | 1 | 2 | {mcnemar_exact_p(1, 2):.2g} |"
    assert lines[4] == f"| b | after | viewpoint | 1 | 0 | 1 | 0 | 1 | {mcnemar_exact_p(0, 1):.2g} |"
    assert lines[5] == f"| all | after | viewpoint | 7 | 3 | 5 | 1 | 3 | {mcnemar_exact_p(1, 3):.2g} |"
    assert len(lines) == 6  # no line for c, which has no global row, nor an "all" for spin's one layout
    assert lookalike_pair_table(rs, ["after"], ["c_lookalike_kidnap"]) == ""


def test_a_row_name_with_two_kinds_endings_is_refused():
    """Only one kind's ending is taken off a row's name: ``lab_kidnap_lookalike_global`` ran ``lab_lookalike_global``'s
    episodes under a name no table line shows (a review's); now its layout is ``lab_kidnap``, which does not exist,
    and it is refused before any episode runs, as ``lab_tracking_kidnap`` is."""
    from agents.experiments.evaluate_relocalizer import row_kind

    assert row_kind("lab_kidnap_lookalike_global") == ("lab_kidnap", "lookalike_global")
    assert row_kind("lab_changed_global_kidnap") == ("lab_changed", "global_kidnap")
    assert row_kind("procedural_sym") == ("procedural_sym", "global")
    for row, base in (("lab_kidnap_lookalike_global", "lab_kidnap"), ("lab_tracking_kidnap", "lab_tracking")):
        with pytest.raises(ValueError, match=f"unknown row '{row}': unknown layout '{base}'"):
            Args(rows=(row,), log_starts=0)


# ------------------------------------------------------------------ layout files of your own


def test_layout_files_add_four_rows_named_by_the_file(tmp_path):
    """``--layout-files``: a global, a tracking-then-kidnap, a tracking-then-look-alike-kidnap and a
    global-then-kidnap row per file, named by its stem; the episodes run on the file's layout and the table has
    the rows."""
    import json
    import shutil

    from agents.experiments import evaluate_relocalizer as er

    path = tmp_path / "my_offices.json"
    shutil.copy(TWIN_OFFICES, path)
    files, rows = er.file_rows([path])
    assert files == {"my_offices": str(path)}
    assert rows == ["my_offices", "my_offices_kidnap", "my_offices_lookalike_kidnap", "my_offices_global_kidnap"]
    (s,) = specs_for("my_offices_global_kidnap", 1, 0, [0], {}, "after", files)
    assert (s.layout, s.row, s.kidnap_after_global) == (str(path), "my_offices_global_kidnap", True)
    out = tmp_path / "out"
    out.mkdir()
    (out / "log_results.jsonl").write_text('{"an earlier run": 1}\n')  # this run has no log phase
    argv = ["--variants", "after", "--rows", "none", "--layout-files", str(path), "--episodes", "1", "--log-starts",
            "0", "--log-tracking-seeds", "0", "--workers", "1", "--no-progress", "--out", str(out)]  # fmt: skip
    assert er.main(argv) == 0
    assert not (out / "log_results.jsonl").exists()  # the folder holds this run's files only
    results = [json.loads(line) for line in (out / "results.jsonl").read_text().splitlines()]
    assert sorted(r["row"] for r in results) == sorted(rows)
    md = (out / "table.md").read_text()
    assert all(f"| {row} | after | 1 |" in md for row in rows)


def test_bad_layout_files_are_refused_before_any_episode(tmp_path):
    from agents.experiments import evaluate_relocalizer as er

    bad = tmp_path / "bad.json"
    bad.write_text('{"outer": [[0, 0], [1, 0]]}')
    lab = tmp_path / "lab.json"
    lab.write_text(TWIN_OFFICES.read_text())
    twin = tmp_path / "sub"
    twin.mkdir()
    (twin / "lab2.json").write_text(lab.read_text())
    (tmp_path / "lab2.json").write_text(lab.read_text())
    for paths, match in [
        ([bad], r"layout file '.*bad\.json'.*outer: needs at least 3 points"),
        ([tmp_path / "missing.json"], "not found"),
        ([lab], "row name 'lab' is taken \\(by a built-in row\\)"),
        ([tmp_path / "lab2.json", twin / "lab2.json"], "row name 'lab2' is taken \\(by '"),
        (["docs/layouts"], "must end in one of"),
        ([tmp_path / "hall_kidnap.json"], "ending in _kidnap or _tracking or"),
        # a review's: office_lookalike's random-kidnap row, office_lookalike_kidnap, ran as office's look-alike row
        ([tmp_path / "office_lookalike.json"], "names a row kind"),
        ([tmp_path / "office_twin.json"], "names a row kind"),
        ([tmp_path / "office_global.json"], "names a row kind"),
    ]:
        with pytest.raises(ValueError, match=match):
            er.file_rows(paths)
    with pytest.raises(SystemExit):  # the command line refuses it while parsing
        er.main(["--rows", "none", "--layout-files", str(bad), "--out", str(tmp_path / "o")])


def test_variants_are_checked_on_top_of_the_env_relocalizer_before_any_episode(tmp_path):
    """A variant that turns the audit off but leaves an option on that needs it is refused while parsing, with
    every option to switch off named (a documented command crashed inside its first episode)."""
    from agents.experiments import evaluate_relocalizer as er

    common = ["--rows", "none", "--log-starts", "1", "--log-steps", "1", "--log-tracking-seeds", "0"]
    common += ["--out", str(tmp_path / "o"), "--workers", "1"]
    with pytest.raises(SystemExit):
        er.main(["--variants", "v4", "--extra", '{"v4": {"audit_window": 0}}', *common])
    with pytest.raises(
        ValueError, match="variant 'v4': .*'audit_after_surprise': False, 'audit_after_surprise_once': F"
    ):
        er.Args(variants=("v4",), extra='{"v4": {"audit_window": 0}}')
    with pytest.raises(ValueError, match="audit_after_surprise needs.*; .*surprise_own_average needs.*; .*semantic"):
        er.Args(variants=("v5",), extra='{"v5": {"surprise_ratio": 0.0}}')
    ok = (
        '{"v5": {"surprise_ratio": 0.0, "audit_after_surprise": false, "audit_after_surprise_once": false, '
        '"surprise_own_average": false, "semantic_surprise_ratio": 0}}'
    )
    assert er.main(["--variants", "v5", "--extra", ok, *common]) == 0


def test_a_variant_with_an_env_id_runs_that_version_and_its_relocalizer():
    """``{"env_id": "SemReloc-v18"}`` runs v18 as it was (its relocalizer and its odometry), the other keys override
    that version's relocalizer; an id that is no SemReloc id is refused while parsing."""
    from agents.experiments import evaluate_relocalizer as er
    from agents.relocalizer_eval import env_class, variant_parts

    assert variant_parts({"env_id": "SemReloc-v18", "kld": False}) == ("SemReloc-v18", {"kld": False})
    assert variant_parts({"kld": False}) == ("", {"kld": False})
    for falsy in (None, "", 0):  # a reviewer's case: these ran the newest version without a word
        with pytest.raises(ValueError, match="env_id must name a SemReloc id"):
            variant_parts({"env_id": falsy})
    assert env_class("SemReloc-v18").__name__ == "SemRelocEnvV18" and env_class("").__name__ == "SemRelocEnv"
    (spec,) = specs_for("lab", 1, 0, [0], {"env_id": "SemReloc-v18", "kld_epsilon": 0.1}, "old")
    assert spec.env_id == "SemReloc-v18" and spec.mcl == {"kld_epsilon": 0.1}
    short = dict(layout="twin_rooms", seed=3, policy="spin", n_steps=4)
    old = run_episode(EpisodeSpec(**short, env_id="SemReloc-v18"))
    new = run_episode(EpisodeSpec(**short))
    assert old["mean_particles"] > new["mean_particles"]  # v18's KLD bound keeps about three times the particles
    for bad in ("SemReloc-v99", "SemSlam-v2"):
        with pytest.raises(ValueError, match=f"variant 'x': no SemReloc relocalizer for env id '{bad}'"):
            er.Args(variants=("x",), extra=f'{{"x": {{"env_id": "{bad}"}}}}')
    with pytest.raises(ValueError, match="variant .x.: .*lost_hold_window"):  # checked against v15's relocalizer
        er.Args(variants=("x",), extra='{"x": {"env_id": "SemReloc-v15", "lost_hold_window": 5}}')


def test_a_policy_file_without_saved_settings_is_refused_before_any_episode(tmp_path):
    # an outside audit's: a train_ppo model.zip failed inside the first episode, as a traceback, leaving --out
    import zipfile

    from agents.experiments import evaluate_relocalizer as er

    bare = tmp_path / "model.zip"
    with zipfile.ZipFile(bare, "w") as z:
        z.writestr("data", "{}")
    out = tmp_path / "er"
    with pytest.raises(ValueError, match=r"policies: x=.*model.zip: .*has no semreloc_policy.json"):
        er.Args(rows=("twin_rooms",), episodes=1, log_starts=0, policies=(f"x={bare}",), out=str(out))
    assert not out.exists()


def test_a_run_with_nothing_to_do_or_a_row_twice_is_refused_before_anything_changes(tmp_path):
    # a twenty-fourth tester's: nothing to run exited 0 and emptied an earlier run's files; a row given twice
    # counted the same seeded episodes twice; an unknown row failed inside its first episode
    from agents.experiments import evaluate_relocalizer as er

    out = tmp_path / "er"
    out.mkdir()
    (out / "table.md").write_text("old")
    for kwargs, match in (
        ({"rows": ("none",), "log_starts": 0}, "nothing to run"),
        ({"rows": ("lab",), "episodes": 0, "log_starts": 0}, "nothing to run"),
        ({"rows": ("lab", "lab")}, r"rows: \['lab'\] given more than once"),
        ({"rows": ("lab",), "variants": ("after", "after")}, r"variants: \['after'\] given more than once"),
        ({"rows": ("bogus",)}, "unknown row 'bogus'"),
        (
            {"rows": ("quad_rooms",), "layout_files": (str(DOCS_LAYOUTS / "quad_rooms.json"),)},
            r"\['quad_rooms'\] given more",
        ),
    ):
        with pytest.raises(ValueError, match=match):
            er.Args(**kwargs, out=str(out))
    with pytest.raises(SystemExit) as e:
        er.main(["--rows", "none", "--log-starts", "0", "--out", str(out)])
    assert e.value.code == 2 and (out / "table.md").read_text() == "old"
    # what a review found refused that runs: "before" episodes alone, a layout on the search path
    er.Args(rows=("lab",), variants=("before",), episodes=0, before_episodes=5, log_starts=0)
    er.Args(rows=(str(DOCS_LAYOUTS / "quad_rooms.json"),), log_starts=0)


def test_rows_can_run_other_policies_the_viewpoint_planner_among_them(tmp_path):
    """``--policies``: the rows' episodes take the given policies in turn (the default three keep the documented
    rows); a policy of `agents.policies` (the viewpoint planner) runs through its own ``wrap``, deterministically."""
    from agents.experiments import evaluate_relocalizer as er

    specs = specs_for("lab_kidnap", 4, 0, [0], {}, "after", policies=("viewpoint", "spin"))
    assert [s.policy for s in specs] == ["viewpoint", "spin", "viewpoint", "spin"]
    assert [s.policy for s in specs_for("lab_kidnap", 3, 0, [0], {}, "after")] == ["random", "spin", "wall_follow"]
    assert er.Args().policies == ("random", "spin", "wall_follow")
    with pytest.raises(ValueError, match=r"policies: unknown \['nope'\]"):
        er.Args(policies=("nope",))
    with pytest.raises(ValueError, match="EpisodeSpec.policy: unknown policy 'nope'"):
        EpisodeSpec(layout="lab", seed=0, policy="nope")
    spec = EpisodeSpec(layout="twin_rooms", seed=1, policy="viewpoint", n_steps=33, kidnap_at_step=30,
                       kidnap_to_lookalike=True, env_kwargs={"map_source": "perfect"})  # fmt: skip
    out, again = run_episode(spec), run_episode(spec)
    assert out["kidnapped_at"] == 30 and out["kidnap_pose"] == again["kidnap_pose"]
    assert {k: v for k, v in out.items() if k != "cpu_s_per_step"} == {
        k: v for k, v in again.items() if k != "cpu_s_per_step"
    }


def test_rows_run_your_own_policy_class_as_evaluate_active_takes_it(tmp_path):
    """``--policies NAME=file.py:CLASS`` (or ``NAME=PATH`` of a saved policy): a class that turns left at every step
    gives the built-in spin's episode, bit for bit but for the policy's name; bad specs are refused up front."""
    from agents.experiments import evaluate_relocalizer as er

    (tmp_path / "mine.py").write_text(
        "from agents.baselines import TURN_LEFT\n\n\n"
        "class Spin:\n"
        "    def __init__(self, seed=0):\n        pass\n\n"
        "    def wrap(self, env):\n        return env\n\n"
        "    def reset(self):\n        pass\n\n"
        "    def act(self, obs):\n        return TURN_LEFT\n"
    )  # fmt: skip
    mine = f"mine={tmp_path / 'mine.py'}:Spin"
    (ours,) = specs_for("twin_rooms_lookalike_kidnap", 1, 2, [0], {}, "after", policies=("spin",))
    (theirs,) = specs_for("twin_rooms_lookalike_kidnap", 1, 2, [0], {}, "after", policies=(mine,))
    a = run_episode(EpisodeSpec(**{**ours.__dict__, "n_steps": 40}))
    b = run_episode(EpisodeSpec(**{**theirs.__dict__, "n_steps": 40}))
    assert b["policy"] == mine
    same = ("cpu_s_per_step", "policy")
    assert {k: v for k, v in a.items() if k not in same} == {k: v for k, v in b.items() if k not in same}
    er.Args(rows=("lab_kidnap",), policies=("spin", mine), log_starts=0)
    import agents

    shipped = f"ppo={agents.SHIPPED_POLICY}"  # a saved PPO policy: its own observation wrappers around the env
    out = run_episode(EpisodeSpec(**{**theirs.__dict__, "policy": shipped, "n_steps": 32}))
    assert (out["policy"], out["kidnapped_at"]) == (shipped, 30) and out["kidnap_pose"] != a["kidnap_pose"]  # drove
    for policies, match in (
        ((f"x={tmp_path / 'missing.zip'}",), "no policy file"),
        ((f"x={tmp_path / 'mine.py'}:Nope",), "has no 'Nope'"),
        (("bogus",), r"unknown \['bogus'\]"),
        ((mine, mine), "names must be unique"),
    ):
        with pytest.raises(ValueError, match=match):
            er.Args(rows=("lab_kidnap",), policies=policies, log_starts=0)
