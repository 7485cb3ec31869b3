import json
from pathlib import Path

import numpy as np
import pytest

import agents.experiments.evaluate_active as ev
from filters.experiments.cli import parse


def test_wilson_interval_matches_the_formula():
    lo, hi = ev.wilson(8, 20)
    z, p, n = 1.959964, 0.4, 20
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z / (1 + z * z / n) * np.sqrt(p * (1 - p) / n + z * z / (4 * n * n))
    assert lo == pytest.approx(centre - half, abs=1e-5) and hi == pytest.approx(centre + half, abs=1e-5)


def test_cases_are_held_out_fixed_and_include_uninformative_starts():
    from semreloc_env.layout_sampling import is_held_out

    args = parse(ev.Args, ["--layouts-per-kind", "2", "--starts", "2"])
    cases = ev.build_cases(args)
    assert cases == ev.build_cases(args)
    assert len(cases) == (3 * 2 + 3) * 2
    assert all(is_held_out(c["layout_seed"]) for c in cases if c["layout"].startswith("procedural"))
    assert {c["kind"] for c in cases} >= {"procedural_lookalike", "twin_rooms", "lab", "lab_changed"}
    assert any(c["uninformative"] for c in cases)
    assert not any(c["uninformative"] for c in cases if c["kind"] != "procedural_lookalike")
    with pytest.raises(SystemExit):
        ev.main(["--policies", "teleport"])
    with pytest.raises(ValueError, match="unknown"):
        ev.Args(policies=("spin", "teleport"))
    with pytest.raises(ValueError, match="separate the policies with spaces"):
        ev.Args(policies=("spin,random",))
    with pytest.raises(ValueError, match="episodes.json"):
        ev.Args(reuse=("/nonexistent/run",))
    # the same pairs under other noise: only the episode seeds differ (so --reuse never mixes the two)
    other = ev.build_cases(
        parse(ev.Args, ["--layouts-per-kind", "2", "--starts", "2", "--noise-seed-offset", "100000"])
    )
    assert [{**c, "episode_seed": 0} for c in other] == [{**c, "episode_seed": 0} for c in cases]
    assert [c["episode_seed"] - 100_000 for c in other] == [c["episode_seed"] for c in cases]
    with pytest.raises(ValueError, match="noise_seed_offset must be >= 0"):
        ev.Args(noise_seed_offset=-1)
    tuning = ev.build_cases(parse(ev.Args, ["--layouts-per-kind", "2", "--starts", "2", "--seed-set", "tuning"]))
    assert len(tuning) == 3 * 2 * 2 and not any(is_held_out(c["layout_seed"]) for c in tuning)
    assert {c["episode_seed"] for c in tuning}.isdisjoint(c["episode_seed"] for c in cases)
    with pytest.raises(SystemExit):
        ev.main(["--seed-set", "train"])


def test_evaluation_runs_writes_its_outputs_and_does_not_depend_on_workers(tmp_path, capsys):
    common = ["--policies", "spin", "random", "--layouts-per-kind", "0", "--starts", "1", "--max-steps", "4"]
    common += ["--particles", "100", "--map-source", "perfect", "--no-progress"]
    assert ev.main([*common, "--workers", "1", "--out", str(tmp_path / "a")]) == 0
    assert ev.main([*common, "--workers", "2", "--out", str(tmp_path / "b")]) == 0
    rows = [json.loads((tmp_path / d / "episodes.json").read_text()) for d in "ab"]
    strip = [[{k: v for k, v in r.items() if k != "seconds"} for r in rs] for rs in rows]
    assert strip[0] == strip[1] and len(strip[0]) == 3 * 1 * 2
    for r in rows[0]:  # every step's discrete action is counted; spin only ever turns left
        assert sum(r["actions"].values()) == r["length"]
        assert r["policy"] != "spin" or set(r["actions"]) == {"1"}
    summary = json.loads((tmp_path / "a" / "summary.json").read_text())
    s = summary["all"]["spin"]
    assert s["episodes"] == 3
    assert s["success"]["count"] + s["wrong"]["count"] + s["unconverged"]["count"] == 3
    spins = [r for r in rows[0] if r["policy"] == "spin"]
    assert all(isinstance(r["first_convergence_wrong"], bool) for r in spins)
    assert s["first_wrong"]["count"] == sum(r["first_convergence_wrong"] for r in spins)
    assert all(r["first_convergence_wrong"] for r in spins if r["outcome"] == "wrong")
    assert (tmp_path / "a" / "success.png").stat().st_size > 0
    assert "| spin |" in (tmp_path / "a" / "table.md").read_text()
    assert " pairs, " not in capsys.readouterr().out  # --no-progress: no line per pair


def test_reuse_keeps_rows_only_of_the_same_policy_code(tmp_path, capsys, monkeypatch):
    common = ["--policies", "spin", "--layouts-per-kind", "0", "--starts", "1", "--max-steps", "3"]
    common += ["--particles", "100", "--map-source", "perfect", "--no-progress", "--workers", "1"]
    assert ev.main([*common, "--out", str(tmp_path / "a")]) == 0
    capsys.readouterr()
    assert ev.main([*common, "--reuse", str(tmp_path / "a"), "--out", str(tmp_path / "b")]) == 0
    assert "reused 3 episodes" in capsys.readouterr().out
    old = tmp_path / "old"  # rows from before the first convergence was recorded: run again
    old.mkdir()
    rows = json.loads((tmp_path / "a" / "episodes.json").read_text())
    (old / "episodes.json").write_text(
        json.dumps([{k: v for k, v in r.items() if k != "first_convergence_wrong"} for r in rows])
    )
    assert ev.main([*common, "--reuse", str(old), "--out", str(tmp_path / "e")]) == 0
    assert "reused 0 episodes" in capsys.readouterr().out
    again = json.loads((tmp_path / "e" / "episodes.json").read_text())
    assert [{**r, "seconds": 0} for r in again] == [{**r, "seconds": 0} for r in rows]  # the same episodes
    # nor rows without settings (a review: they were kept with a warning, scored with other particles and steps, and
    # written out without settings again, so the next --reuse kept them too)
    (old / "episodes.json").write_text(json.dumps([{k: v for k, v in r.items() if k != "settings"} for r in rows]))
    assert ev.main([*common, "--reuse", str(old), "--out", str(tmp_path / "f")]) == 0
    assert "reused 0 episodes" in capsys.readouterr().out
    monkeypatch.setattr(ev, "policy_code", lambda spec: "changed")
    assert ev.main([*common, "--reuse", str(tmp_path / "a"), "--out", str(tmp_path / "c")]) == 0
    assert "reused 0 episodes" in capsys.readouterr().out
    # nor rows made with other env or filter code (a new user's trial: a changed relocalizer's
    # episodes were reused before the fingerprint covered the code every episode runs)
    monkeypatch.undo()
    monkeypatch.setattr(ev, "env_code", lambda: "changed")
    assert ev.main([*common, "--reuse", str(tmp_path / "a"), "--out", str(tmp_path / "d")]) == 0
    assert "reused 0 episodes" in capsys.readouterr().out


def test_reuse_reruns_the_cases_of_an_edited_layout_file(tmp_path, capsys):
    from semreloc_env.layouts import get_layout

    layout = get_layout("twin_rooms").to_dict()
    path = tmp_path / "mine.json"
    path.write_text(json.dumps(layout))
    common = ["--policies", "spin", "--layouts-per-kind", "0", "--starts", "1", "--max-steps", "3"]
    common += ["--particles", "100", "--map-source", "perfect", "--no-progress", "--workers", "1"]
    common += ["--layout-files", str(path)]
    assert ev.main([*common, "--out", str(tmp_path / "a")]) == 0
    capsys.readouterr()
    assert ev.main([*common, "--reuse", str(tmp_path / "a"), "--out", str(tmp_path / "b")]) == 0
    assert "reused 4 episodes" in capsys.readouterr().out
    layout["objects"][0]["class"] = "cabinet" if layout["objects"][0]["class"] != "cabinet" else "chair"
    path.write_text(json.dumps(layout))  # the same path, another layout
    assert ev.main([*common, "--reuse", str(tmp_path / "a"), "--out", str(tmp_path / "c")]) == 0
    assert "reused 3 episodes" in capsys.readouterr().out  # all but the file's case: and spin is run whole


def test_the_env_fingerprint_covers_the_code_that_scores_an_episode(tmp_path, monkeypatch):
    # a review: agents.metrics decides success, wrong or unconverged, and a change to it kept the old rows
    import agents.metrics

    before = ev.env_code.__wrapped__()
    copy = tmp_path / "metrics.py"
    copy.write_text(Path(agents.metrics.__file__).read_text() + "\n# scored otherwise\n")
    monkeypatch.setattr(agents.metrics, "__file__", str(copy))
    assert ev.env_code.__wrapped__() != before


def test_policy_code_follows_the_modules_a_policy_draws_on():
    vp = ev.policy_modules("viewpoint")
    assert {"agents.viewpoint", "agents.info_gain", "agents.baselines", "agents.policies"} <= set(vp)
    assert "agents.viewpoint" not in ev.policy_modules("spin")
    assert "agents.viewpoint" in ev.policy_modules("ppo=agents/data/active_ppo.zip")
    assert ev.policy_code("viewpoint") != ev.policy_code("spin")
    assert ev.policy_code("ppo=agents/data/active_ppo.zip") != ev.policy_code("viewpoint")


def test_fingerprints_follow_the_libraries_episodes_compute_with(monkeypatch):
    """An upgrade of a library the episodes (or a learned policy's network) compute with reruns the rows
    ``--reuse`` would otherwise keep (an outside tester's finding: fingerprints covered source files only)."""
    import torch

    import semreloc_env.maps

    spec = "ppo=agents/data/active_ppo.zip"
    before = ev.env_code(), ev.policy_code(spec), ev.policy_code("spin")
    try:
        monkeypatch.setattr(semreloc_env.maps, "mapping_libraries", lambda: ("pymunk==0.0",))
        monkeypatch.setattr(torch, "__version__", "0.0")
        ev.env_code.cache_clear()
        ev.policy_code.cache_clear()
        assert ev.env_code() != before[0] and ev.policy_code(spec) != before[1]
        assert ev.policy_code("spin") == before[2]  # a baseline's does not name torch
    finally:
        ev.env_code.cache_clear()
        ev.policy_code.cache_clear()


def test_learned_policy_is_loaded_once_per_file_version_and_acts_as_a_fresh_load(tmp_path):
    """make_policy shares one loaded model between cases (a fresh LearnedPolicy each time, with the
    case's seed), reloads when the file changes, and acts exactly as load_policy's own object."""
    import shutil

    from agents import SHIPPED_POLICY
    from agents.learned import load_policy

    path = tmp_path / "p.zip"
    shutil.copy(SHIPPED_POLICY, path)
    spec = f"ppo={path}"
    a, b = ev.make_policy(spec, 3), ev.make_policy(spec, 4)
    assert a is not b and a.model is b.model and (a.seed, b.seed) == (3, 4)
    fresh = load_policy(path, seed=3)
    assert (a.options, a.repeat, a.observation, a.deterministic) == (
        fresh.options, fresh.repeat, fresh.observation, fresh.deterministic,
    )  # fmt: skip
    args = parse(ev.Args, ["--layouts-per-kind", "1", "--starts", "1"])
    case = ev.build_cases(args)[0]
    actions = []
    for pol in (a, fresh):
        env = pol.wrap(ev.case_env(case, args))
        pol.reset()
        obs, _ = env.reset(seed=case["episode_seed"], options={"pose": case["start"]})
        acts = []
        for _ in range(12):
            act = pol.act(obs)
            acts.append(act)
            obs = env.step(act)[0]
        actions.append(acts)
    assert actions[0] == actions[1]
    shutil.copy(SHIPPED_POLICY, path)  # a new file version (mtime) is loaded again
    path.touch()
    import os

    os.utime(path, ns=(path.stat().st_atime_ns, path.stat().st_mtime_ns + 10**9))
    assert ev.make_policy(spec, 3).model is not a.model


def test_bad_arguments_are_caught_before_any_episode(tmp_path, capsys):
    junk = tmp_path / "junk.zip"
    junk.write_text("not a zip")
    for kw, match in [
        ({"layouts_per_kind": 501}, "held-out"),
        ({"seed_set": "tuning", "layouts_per_kind": 0}, "tuning"),
        ({"layout_files": (str(tmp_path / "missing.json"),)}, "layout_files"),
        ({"policies": (f"ppo={junk}",)}, "not a policy zip"),
        ({"relocalizer": [1, 2]}, "JSON object"),
        ({"relocalizer": {"bogus": 1}}, r"relocalizer: unknown keys \['bogus'\]; valid keys: \[.*'likelihood_scale'"),
        ({"relocalizer": {"negative_evidence": {"p_detect": 2}}}, "p_detect"),
        ({"relocalizer": {"negative_evidence": {"bogus": 1}}}, "its keys are"),
        ({"relocalizer": {"n_particles": 10}}, "--particles"),
        # checked on top of the env's relocalizer: v4's has no surprise test for the option to read
        ({"env_id": "SemReloc-v4", "relocalizer": {"surprise_own_average": True}}, "needs the surprise test"),
    ]:
        with pytest.raises(ValueError, match=match):
            ev.Args(**kw)
    out = tmp_path / "out"
    assert ev.main(["--policies", "spin", "--layouts-per-kind", "0", "--gif-case", "999", "--out", str(out)]) == 2
    assert not out.exists()
    assert "--gif-case 999 is not a case" in capsys.readouterr().err
    for bad in ("[1, 2]", "{not json"):  # the command line takes one JSON object
        with pytest.raises(SystemExit) as e:
            ev.main(["--policies", "spin", "--relocalizer", bad, "--out", str(out)])
        assert e.value.code == 2 and not out.exists()


def _row(case, policy, outcome, steps=None, uninformative=False, kind="procedural", first_wrong=False, seed=None):
    return {
        "case": case, "policy": policy, "outcome": outcome, "steps_to_success": steps, "collisions": case % 2,
        "seconds": 1.0, "length": 10, "kind": kind, "uninformative": uninformative,
        "first_convergence_wrong": first_wrong, "layout": kind, "layout_seed": case if seed is None else seed,
        "scenario": "nominal",
    }  # fmt: skip


def test_paired_comparison_counts_discordant_pairs_and_tests_them():
    from scipy.stats import binomtest

    # learned "a" against "b" on 8 cases: a alone solves 0, 1, 2; b alone solves 3; both solve 4, 5
    a = ["success", "success", "success", "unconverged", "success", "success", "wrong", "unconverged"]
    b = ["unconverged", "wrong", "unconverged", "success", "success", "success", "unconverged", "unconverged"]
    rows = [_row(i, "a", o) for i, o in enumerate(a)] + [_row(i, "b", o) for i, o in enumerate(b)]
    (cmp,) = ev.paired(rows, ["a"], ["a", "b"])
    assert (cmp["policy"], cmp["against"], cmp["wins"], cmp["losses"]) == ("a", "b", 3, 1)
    assert cmp["difference"] == pytest.approx((5 - 3) / 8)
    assert cmp["mcnemar_p"] == pytest.approx(binomtest(3, 4).pvalue)
    lo, hi = cmp["ci95"]
    assert lo <= cmp["difference"] <= hi and lo < hi


def test_paired_comparison_of_a_single_case_has_no_interval():
    """One (layout, start) pair: the difference and McNemar's p, no bootstrap interval (a tester's run with
    --starts 1 on one layout file crashed here after every episode had run)."""
    rows = [_row(0, "a", "success"), _row(0, "b", "unconverged")]
    (cmp,) = ev.paired(rows, ["a"], ["a", "b"])
    assert cmp["ci95"] is None and cmp["difference"] == 1.0 and (cmp["wins"], cmp["losses"]) == (1, 0)
    assert "[n/a: one case]" in ev.paired_table([cmp])


def test_summarise_counts_each_outcome_with_its_wilson_interval():
    outcomes = ["success", "success", "wrong", "unconverged", "success"]
    first = [True, False, True, False, False]  # a success whose belief was first sure of a wrong pose
    rows = [
        _row(i, "p", o, steps=10 + i if o == "success" else None, first_wrong=f)
        for i, (o, f) in enumerate(zip(outcomes, first))
    ]
    s = ev.summarise(rows)
    for outcome, k in (("success", 3), ("wrong", 1), ("unconverged", 1), ("first_wrong", 2)):
        assert s[outcome]["count"] == k and s[outcome]["rate"] == k / 5
        assert s[outcome]["ci95"] == pytest.approx(ev.wilson(k, 5))
    assert s["median_steps"] == 11.0 and s["collisions_per_episode"] == pytest.approx(2 / 5)


def test_intervals_count_each_layouts_starts_as_one_cluster():
    """Starts of one layout succeed or fail together (an outside audit: 10 starts per layout, the Wilson interval
    over episodes too narrow). The rate's interval over layouts is wider than Wilson's when whole layouts succeed or
    fail, and it is None with one layout; the paired difference gets a layouts-resampled bootstrap interval, and
    the tables print both."""
    # 6 layouts x 5 starts: layouts 0-2 always succeed, 3-5 never (with policy "a"); "b" fails everywhere
    rows = [_row(5 * lay + k, "a", "success" if lay < 3 else "unconverged", steps=9, seed=lay)
            for lay in range(6) for k in range(5)]  # fmt: skip
    rows += [_row(5 * lay + k, "b", "unconverged", seed=lay) for lay in range(6) for k in range(5)]
    s = ev.summarise([r for r in rows if r["policy"] == "a"])
    assert s["layouts"] == 6 and s["success"]["rate"] == 0.5
    w_lo, w_hi = s["success"]["ci95"]
    lo, hi = s["success"]["ci95_layouts"]
    assert lo <= 0.5 <= hi and lo < w_lo and hi > w_hi  # wider: 6 layouts, not 30 independent episodes
    assert s["success"]["design_effect"] == pytest.approx(5 * 6 / 5)  # all-or-nothing clusters of 5, C/(C-1)
    assert ev.summarise(rows[:5])["success"]["ci95_layouts"] is None  # one layout: no clusters to count
    (cmp,) = ev.paired(rows, ["a"], ["a", "b"])
    p_lo, p_hi = cmp["ci95"]
    l_lo, l_hi = cmp["ci95_layouts"]
    assert l_lo <= cmp["difference"] == 0.5 <= l_hi and l_lo < p_lo and l_hi >= p_hi
    assert "over layouts" in ev.table({"all": {"a": s}}, ["a"]) and "[layouts resampled]" in ev.paired_table([cmp])
    # each start its own layout: the interval over layouts is Wilson's
    own = [_row(i, "a", "success" if i % 3 else "unconverged") for i in range(200)]
    assert ev.summarise(own)["success"]["ci95_layouts"] == pytest.approx(ev.summarise(own)["success"]["ci95"], abs=2e-3)


def test_continuous_actions_run_and_are_counted_by_kind(tmp_path, capsys):
    """``--action-type continuous`` makes continuous envs: the rows count motions by kind and carry the
    action type in their settings (so ``--reuse`` never mixes them with discrete rows); discrete rows
    are as before (no action_type in their settings)."""
    common = ["--policies", "viewpoint", "spin", "--layouts-per-kind", "0", "--starts", "1", "--max-steps", "6"]
    common += ["--particles", "100", "--map-source", "perfect", "--no-progress", "--workers", "1"]
    assert ev.main([*common, "--action-type", "continuous", "--out", str(tmp_path / "c")]) == 0
    rows = json.loads((tmp_path / "c" / "episodes.json").read_text())
    assert len(rows) == 3 * 2
    for r in rows:
        assert sum(r["actions"].values()) == r["length"]
        assert set(r["actions"]) <= {"turn", "arc", "straight", "reverse", "stop"}
        assert r["settings"]["action_type"] == "continuous"
        assert r["policy"] != "spin" or set(r["actions"]) == {"turn"}
    assert "continuous actions" in (tmp_path / "c" / "table.md").read_text()
    assert ev.main([*common, "--out", str(tmp_path / "d")]) == 0
    capsys.readouterr()
    assert ev.main([*common, "--reuse", str(tmp_path / "c"), "--out", str(tmp_path / "e")]) == 0
    assert "reused 0 episodes" in capsys.readouterr().out
    rows = json.loads((tmp_path / "d" / "episodes.json").read_text())
    assert all("action_type" not in r["settings"] and set(r["actions"]) <= {"0", "1", "2", "3"} for r in rows)
    with pytest.raises(SystemExit):
        ev.main(["--action-type", "diagonal"])


def test_motion_kind_names_what_a_continuous_action_does():
    kinds = [ev.motion_kind(a) for a in ([0, 1], [0, -0.2], [1, 0], [0.5, 0.1], [-1, 0], [-0.3, 0.4], [0, 0])]
    assert kinds == ["turn", "turn", "straight", "arc", "reverse", "reverse", "stop"]


def test_own_layouts_alone_and_malformed_layout_files(tmp_path):
    # a new user's trial: the built-in layouts could not be left out, and a malformed layout file
    # crashed the run with a traceback instead of an argument error
    from semreloc_env.layouts import get_layout

    path = tmp_path / "mine.json"
    path.write_text(json.dumps(get_layout("twin_rooms").to_dict()))
    args = ev.Args(layouts_per_kind=0, starts=2, layout_files=(str(path),), builtin_layouts=False, policies=("spin",))
    cases = ev.build_cases(args)
    assert [c["kind"] for c in cases] == ["mine", "mine"]
    with pytest.raises(ValueError, match="no layouts"):
        ev.Args(layouts_per_kind=0, builtin_layouts=False)
    (tmp_path / "bad.json").write_text(json.dumps({"outer": [[0, 0], [1, 0]]}))
    with pytest.raises(ValueError, match=r"layout_files: .*bad.json"):
        ev.Args(layout_files=(str(tmp_path / "bad.json"),))
    with pytest.raises(SystemExit) as exit_:  # the command's tidy argument error, not a traceback
        ev.main(["--layout-files", str(tmp_path / "bad.json"), "--policies", "spin"])
    assert exit_.value.code == 2


def test_layout_files_get_a_row_of_their_own(tmp_path, capsys, monkeypatch):
    # a new user's trial: a file named lab.json shared the built-in lab's row, and two my.yaml one row
    assert ev.layout_file_kinds(["/x/lab.json", "/a/my.yaml", "/b/my.yaml", "/c/other.json", "paired.json"]) == {
        "/x/lab.json": "file:/x/lab.json",
        "/a/my.yaml": "file:/a/my.yaml",
        "/b/my.yaml": "file:/b/my.yaml",
        "/c/other.json": "other",
        "paired.json": "file:paired.json",  # the summary's key for paired comparisons
    }
    from semreloc_env.layouts import get_layout

    path = tmp_path / "lab.json"
    path.write_text(json.dumps(get_layout("twin_rooms").to_dict()))
    cases = ev.build_cases(ev.Args(layouts_per_kind=0, starts=1, layout_files=(str(path),), policies=("spin",)))
    assert [c["kind"] for c in cases] == ["twin_rooms", "lab", "lab_changed", f"file:{path}"]
    assert [("layout_digest" in c) for c in cases] == [False, False, False, True]
    monkeypatch.setenv("SEMRELOC_LAYOUT_PATH", str(tmp_path))  # a name on the search path that a built-in takes
    with pytest.raises(ValueError, match=r"\['lab'\] name built-in layouts"):
        ev.Args(layout_files=("lab",), policies=("spin",))
    with pytest.raises(ValueError, match="more than once"):
        ev.Args(layout_files=(str(path), str(tmp_path / "." / "lab.json")), policies=("spin",))
    tiny = tmp_path / "tiny.yaml"
    tiny.write_text("outer: [[0, 0], [0.5, 0], [0.5, 0.5], [0, 0.5]]\n")
    argv = ["--layout-files", str(tiny), "--layouts-per-kind", "0", "--no-builtin-layouts", "--policies", "spin"]
    assert ev.main([*argv, "--out", str(tmp_path / "out")]) == 2  # an argument error, not a traceback
    assert "no free space" in capsys.readouterr().err


def test_env_id_and_relocalizer_overrides_reach_the_env_and_the_rows_settings():
    case = ev.build_cases(ev.Args(policies=("spin",), layouts_per_kind=1, starts=1))[0]
    plain = ev.Args(policies=("spin",), particles=100)
    v3 = ev.Args(policies=("spin",), particles=100, env_id="SemReloc-v3")
    half = ev.Args(policies=("spin",), particles=100, relocalizer={"negative_evidence": {"p_detect": 0.5}})
    for args, p_detect in ((plain, 0.8), (v3, 0.0), (half, 0.5)):
        env = ev.case_env(case, args)
        assert env.unwrapped.mcl_config.negative_evidence.p_detect == p_detect
        assert env.unwrapped.mcl_config.n_particles == 100
    assert ev.settings(plain, "spin")["env_id"] == ev.ENV_ID and "relocalizer" not in ev.settings(plain, "spin")
    assert ev.settings(v3, "spin")["env_id"] == "SemReloc-v3"  # so --reuse never mixes rows of two envs
    assert ev.settings(half, "spin")["relocalizer"]["negative_evidence"] == {"p_detect": 0.5}
    # an override that needs other fields of the env's relocalizer (checked against plain MCLConfig, it was refused)
    own = ev.Args(policies=("spin",), particles=100, env_id="SemReloc-v12", relocalizer={"surprise_own_average": True})
    assert ev.case_env(case, own).unwrapped.mcl_config.surprise_own_average


def test_one_map_for_worlds_that_differ_from_it(tmp_path):
    """--map-source LAYOUT: the filter's map is that layout's mapping run, the worlds are the layout
    files (a map object missing from the world, say); a map that does not fit is an argument error."""
    from semreloc_env.layouts import get_layout

    full = get_layout("twin_rooms").to_dict()
    world = dict(full, objects=[o for o in full["objects"] if o["name"] != "trash_bin_west"])
    (tmp_path / "map.json").write_text(json.dumps(full))
    (tmp_path / "world.json").write_text(json.dumps(world))
    files = (str(tmp_path / "world.json"),)
    args = ev.Args(layouts_per_kind=0, starts=1, layout_files=files, builtin_layouts=False, policies=("spin",),
                   map_source=str(tmp_path / "map.json"), particles=100)  # fmt: skip
    env = ev.case_env(ev.build_cases(args)[0], args)
    names = {o.name for o in env.unwrapped.layout.objects}
    grid = env.unwrapped.grid  # the map still has the bin the world lacks, at x 4.3-4.7, y 4.8-5.2
    (r0, r1), (c0, c1) = grid.world_to_cell(np.array([[4.2, 4.7], [4.8, 5.3]]))
    assert "trash_bin_west" not in names and grid.class_mask(grid.class_index("trash_bin"))[r0:r1, c0:c1].any()
    assert ev.settings(args, "spin")["map_digest"] == ev.file_digest(str(tmp_path / "map.json"))
    assert "map_digest" not in ev.settings(ev.Args(policies=("spin",)), "spin")
    kw = dict(layouts_per_kind=0, starts=1, layout_files=files, builtin_layouts=False, policies=("spin",))
    with pytest.raises(ValueError, match="does not fit"):
        ev.Args(**kw, map_source="lab")  # another building
    with pytest.raises(ValueError, match="layout-files alone"):
        ev.Args(policies=("spin",), map_source="twin_rooms")  # the procedural held-out layouts too
    with pytest.raises(ValueError, match="map_source must be"):
        ev.Args(**kw, map_source="nowhere.yaml")


def test_one_ros_map_for_every_case(tmp_path):
    """--map-source MAP.yaml: a ROS map (with its semantic sidecar) is every case's map; its digest
    follows the image, not only the .yaml; a ROS map of another building is an argument error."""
    from filters.mapping.ros_map import save_map
    from semreloc_env.config import CameraParams, LidarParams
    from semreloc_env.layouts import get_layout
    from semreloc_env.maps import maps_for

    twin = get_layout("twin_rooms")
    (tmp_path / "world.json").write_text(json.dumps(twin.to_dict()))
    yaml_path = save_map(maps_for(twin, "mapping", LidarParams(), CameraParams()), tmp_path / "twin.yaml")
    kw = dict(layouts_per_kind=0, starts=1, layout_files=(str(tmp_path / "world.json"),), builtin_layouts=False)
    kw.update(policies=("spin",), particles=100, max_steps=3)
    args = ev.Args(**kw, map_source=str(yaml_path))
    env = ev.case_env(ev.build_cases(args)[0], args)
    mapped = maps_for(twin, "mapping", LidarParams(), CameraParams())
    grid = env.unwrapped.grid  # the file's map (saved as trinary pixels), with the sidecar's classes
    assert grid.shape == mapped.shape and grid.class_names == mapped.class_names and grid.semantic is not None
    assert np.array_equal(grid.occupied_mask(), mapped.occupied_mask())
    digest = ev.settings(args, "spin")["map_digest"]
    image = next(tmp_path.glob("twin.p*m"))
    image.write_bytes(image.read_bytes()[:-1] + bytes([255 - image.read_bytes()[-1]]))  # one pixel changed
    assert ev.settings(args, "spin")["map_digest"] != digest
    out = tmp_path / "out"
    assert ev.main(["--policies", "spin", "--layouts-per-kind", "0", "--no-builtin-layouts", "--starts", "1",
                    "--layout-files", str(tmp_path / "world.json"), "--map-source", str(yaml_path),
                    "--particles", "100", "--max-steps", "3", "--no-progress", "--workers", "1",
                    "--out", str(out)]) == 0  # fmt: skip
    assert len(json.loads((out / "episodes.json").read_text())) == 1
    lab_map = save_map(maps_for(get_layout("lab"), "perfect", LidarParams(), CameraParams()), tmp_path / "lab.yaml")
    with pytest.raises(ValueError, match="does not fit"):
        ev.Args(**kw, map_source=str(lab_map))


MY_POLICY = '''
import numpy as np

from agents.policies import Policy
from helper import TURN
from sub.deep import DEPTH  # noqa: F401  (a module in a subfolder: part of the fingerprint)


class TurnLeft(Policy):
    """Always turns left (a user's own policy, defined outside the package)."""

    def act(self, obs):
        return TURN


def broken(seed):
    return object()


class NoAct(Policy):
    pass


class Bad(Policy):
    def act(self, obs):
        return 7


class LateNaN(Policy):
    """Turns left, then sends NaN at its third step (a bug that shows only within an episode)."""

    def reset(self):
        self.t = 0

    def act(self, obs):
        self.t += 1
        return 1 if self.t < 3 else float("nan")
'''


def test_a_users_own_policy_class_is_evaluated_and_its_edits_rerun(tmp_path, capsys, monkeypatch):
    # a new user's trial: a hand-written policy with the wrap/reset/act interface could not be passed
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "mypol.py").write_text(MY_POLICY)
    (tmp_path / "mine" / "helper.py").write_text("TURN = 1\n")
    (tmp_path / "mine" / "sub").mkdir()
    (tmp_path / "mine" / "sub" / "deep.py").write_text("DEPTH = 1\n")  # found as a sibling import finds it
    spec = f"left={tmp_path / 'mine' / 'mypol.py'}:TurnLeft"
    common = ["--policies", "spin", spec, "--layouts-per-kind", "0", "--starts", "1", "--max-steps", "3"]
    common += ["--particles", "100", "--map-source", "perfect", "--no-progress", "--workers", "1"]
    assert ev.main([*common, "--out", str(tmp_path / "a")]) == 0
    rows = json.loads((tmp_path / "a" / "episodes.json").read_text())
    left = [r for r in rows if r["policy"] == "left"]
    assert len(left) == 3 and all(r["actions"] == {"1": r["length"]} for r in left)
    ev.policy_code.cache_clear()  # the fingerprint does not depend on what was loaded when it was taken
    assert {r["settings"]["code"] for r in left} == {ev.policy_code(spec)}
    capsys.readouterr()
    assert ev.main([*common, "--reuse", str(tmp_path / "a"), "--out", str(tmp_path / "b")]) == 0
    assert "reused 6 episodes" in capsys.readouterr().out
    ev.policy_code.cache_clear()
    (tmp_path / "mine" / "helper.py").write_text("TURN = 2  # now right\n")  # a file it imports changed
    assert ev.main([*common, "--reuse", str(tmp_path / "a"), "--out", str(tmp_path / "c")]) == 0
    assert "reused 3 episodes" in capsys.readouterr().out  # spin's rows only
    ev.policy_code.cache_clear()
    assert ev.main([*common, "--out", str(tmp_path / "d")]) == 0
    capsys.readouterr()
    ev.policy_code.cache_clear()
    (tmp_path / "mine" / "sub" / "deep.py").write_text("DEPTH = 2\n")  # a subfolder's module changed
    assert ev.main([*common, "--reuse", str(tmp_path / "d"), "--out", str(tmp_path / "e")]) == 0
    assert "reused 3 episodes" in capsys.readouterr().out
    ev.policy_code.cache_clear()
    (tmp_path / "mine" / "unrelated.py").write_text("X = 1\n")  # a file beside it that it does not import
    assert ev.main([*common, "--reuse", str(tmp_path / "e"), "--out", str(tmp_path / "f")]) == 0
    assert "reused 6 episodes" in capsys.readouterr().out
    ev.policy_code.cache_clear()
    bad = f"bad={tmp_path / 'mine' / 'mypol.py'}:Bad"  # an invalid action names the policy and the case
    case = ev.build_cases(ev.Args(layouts_per_kind=0, starts=1))[0]
    with pytest.raises(ValueError, match=r"policy 'bad' on case 0 \(twin_rooms\), step 1: .*invalid action 7"):
        ev.run_episode(case, bad, ev.Args(policies=(bad,)))
    (row,) = ev.run_case((case, (bad,), ev.Args(policies=(bad,))))  # one policy's failure is its row's
    assert row["policy"] == "bad" and "invalid action 7" in row["error"]
    out = tmp_path / "refused"  # refused before any episode, naming the policy
    assert ev.main([*common[:3], bad, *common[3:], "--out", str(out)]) == 2 and not out.exists()
    assert "policies: bad=" in capsys.readouterr().err
    # an outside tester's trial: a policy failing within an episode cost every other policy's episodes
    late = f"late={tmp_path / 'mine' / 'mypol.py'}:LateNaN"
    argv = [*common[:3], late, *common[3:], "--max-steps", "5", "--out", str(tmp_path / "g")]
    assert ev.main(argv) == 1
    err = capsys.readouterr().err
    assert "policy 'late' failed" in err and "step 3" in err and f"--reuse {tmp_path / 'g'}" in err
    rows = json.loads((tmp_path / "g" / "episodes.json").read_text())
    assert {r["policy"] for r in rows} == {"spin", "left"} and len(rows) == 6
    assert "late" not in json.loads((tmp_path / "g" / "summary.json").read_text())["all"]
    (tmp_path / "file.txt").write_text("x")
    with pytest.raises(ValueError, match="is a file; the outputs go into a folder"):
        ev.Args(policies=("spin",), out=str(tmp_path / "file.txt"))
    for bad, match in [
        (f"x={tmp_path / 'mine' / 'mypol.py'}:broken", r"lacks \['wrap', 'reset', 'act'\]"),
        (f"x={tmp_path / 'mine' / 'mypol.py'}:NoAct", r"NoAct lacks \['act'\]"),
        (f"x={tmp_path / 'mine' / 'mypol.py'}:Nope", "mypol.py has no 'Nope'"),
        ("x=no_such_module_here:Policy", "cannot import no_such_module_here: ModuleNotFoundError"),
        ("x=not a spec", "no policy file"),
        (f"x={tmp_path / 'mine' / 'mypol.py'}", "name the class too"),
    ]:
        with pytest.raises(ValueError, match=match):
            ev.Args(policies=(bad,))


def test_a_package_policys_fingerprint_covers_what_it_imports_and_the_packages_on_its_path(tmp_path, monkeypatch):
    """``pkg:Class`` and ``pkg.sub.mod:Class``: the package's ``__init__`` files, absolute and relative imports
    inside the package; not a file it does not import, not installed packages (a review)."""
    pkg = tmp_path / "mypkg"
    (pkg / "sub").mkdir(parents=True)
    (pkg / "__init__.py").write_text(
        "import numpy\nfrom agents.policies import Policy\nfrom mypkg import helper\nfrom . import rel\n\n\n"
        "class P(Policy):\n    def act(self, obs):\n        return helper.X + rel.Y\n"
    )
    (pkg / "helper.py").write_text("X = 0\n")
    (pkg / "rel.py").write_text("Y = 0\n")
    (pkg / "unused.py").write_text("Z = 1\n")
    (pkg / "sub" / "__init__.py").write_text("")
    (pkg / "sub" / "pol.py").write_text("from ..helper import X\nfrom agents.policies import Policy as Q\n")
    monkeypatch.chdir(tmp_path)
    monkeypatch.syspath_prepend(str(tmp_path))
    names = {}
    for spec in ("a=mypkg:P", "b=mypkg.sub.pol:Q"):
        module = ev._user_module(ev._user_target(spec)["source"])
        names[spec] = [f.relative_to(tmp_path).as_posix() for f in ev._local_files(module)]
    assert names["a=mypkg:P"] == ["mypkg/__init__.py", "mypkg/helper.py", "mypkg/rel.py"]
    assert names["b=mypkg.sub.pol:Q"] == [
        "mypkg/__init__.py", "mypkg/helper.py", "mypkg/rel.py", "mypkg/sub/__init__.py", "mypkg/sub/pol.py"
    ]  # fmt: skip
    # the fingerprint keys each file by its path in the tree, so same-named files in two folders count apart
    (pkg / "sub" / "helper.py").write_text("X = 1\n")
    (pkg / "sub" / "pol.py").write_text(
        "from ..helper import X\nfrom . import helper\nfrom agents.policies import Policy as Q\n"
    )
    module = ev._user_module(ev._user_target("b=mypkg.sub.pol:Q")["source"])
    assert [key for key, _ in ev._keyed(ev._local_files(module))] == [
        "__init__.py", "helper.py", "rel.py", "sub/__init__.py", "sub/helper.py", "sub/pol.py"
    ]  # fmt: skip
