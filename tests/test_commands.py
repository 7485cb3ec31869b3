"""The command lines: every console entry point resolves to a ``main(argv)`` that parses typed options
(``--help`` exits 0, a bad value exits 2), and every file in ``scripts/`` that names one calls it."""

import importlib
import math
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
# [project.scripts] of pyproject.toml (read by hand: tomllib needs Python 3.11)
_SECTION = (ROOT / "pyproject.toml").read_text().split("[project.scripts]\n", 1)[1].split("\n[", 1)[0]
ENTRY_POINTS = dict(re.findall(r'^([\w-]+) = "([\w.:]+)"$', _SECTION, re.M))
BAD = {  # one rejected value per command (checked in the Args dataclass or by the type)
    "semreloc-demo": ["--steps", "0"],
    "semreloc-repro-paper000": ["--association", "nearest"],
    "semreloc-repro-paper001": ["--runs", "1"],
    "semreloc-repro-paper004": ["--cases", "kitchen"],
    "semreloc-semslam-eval": ["--policy", "random"],
    "semreloc-evaluate-relocalizer": ["--variants", "nope"],
    "semreloc-soak": ["--episode-steps", "2"],
    "semreloc-build-maps": ["--resolution", "0"],
    "semreloc-replay-log": ["--mode", "teleport"],
    "semreloc-train-active": ["--config.repeat", "0"],
    "semreloc-imitate-active": ["--config.rounds", "0"],
    "semreloc-evaluate-active": ["--policies", "teleport"],
    "semreloc-bench": ["--only", "warp_drive"],
    "semreloc-profile-step": ["--policy", "teleport"],
    "semreloc-train-ppo": ["--config.n-envs", "0"],
}


def _main(target: str):
    module, func = target.split(":")
    return getattr(importlib.import_module(module), func)


@pytest.mark.parametrize("name", sorted(ENTRY_POINTS))
def test_entry_point_parses_typed_options(name, capsys):
    main = _main(ENTRY_POINTS[name])
    with pytest.raises(SystemExit) as ok:
        main(["--help"])
    assert ok.value.code == 0
    assert "--help" in capsys.readouterr().out
    with pytest.raises(SystemExit) as bad:
        main(BAD[name])
    assert bad.value.code == 2


def test_every_entry_point_has_its_script_and_each_script_calls_it():
    assert set(BAD) == set(ENTRY_POINTS)
    for name, target in ENTRY_POINTS.items():
        script = ROOT / "scripts" / (name.removeprefix("semreloc-").replace("-", "_") + ".py")
        if name.startswith("semreloc-repro-"):
            script = ROOT / "scripts" / ("repro_" + name.removeprefix("semreloc-repro-") + ".py")
        text = script.read_text()
        module = target.split(":")[0]
        assert re.search(rf"^from {re.escape(module)} import main$", text, re.M), script
        assert "sys.path" not in text


@pytest.mark.parametrize("name", ["stages", "belief", "robots_fused"])  # batched and batched_split: below
def test_cheap_benchmarks_run_and_print_finite_figures(name):
    """The benchmarks import what they need and measure something (tiny sizes; no timing asserted)."""
    import math

    from agents.tools import bench

    fn = getattr(bench, f"bench_{name}")
    rows = fn(bench.Args(steps=20, repeats=2, only=(name,)))
    assert rows
    assert all(math.isfinite(r.cpu) and r.cpu > 0 for r in rows), rows


@pytest.mark.filterwarnings("ignore:.*out of date.*:DeprecationWarning")
def test_the_batched_bench_puts_the_version_before_beside_the_newest_only(monkeypatch):
    """The newest id's batched rows include the previous version's R = 64 and their ratio, and the issue's env's R = 64,
    each row run on its own env (the vector envs made are recorded); an older ``--env-id`` runs its own rows without
    them (a reviewer found an IndexError there)."""
    import math

    from agents.tools import bench
    from semreloc_env.envs import batched

    made = []
    vector_env = batched.SemRelocLoopVectorEnv

    def recording(num_envs, env_id, **kwargs):
        made.append((num_envs, env_id))
        return vector_env(num_envs=num_envs, env_id=env_id, **kwargs)

    monkeypatch.setattr(batched, "SemRelocLoopVectorEnv", recording)
    rows = bench.bench_batched(bench.Args(steps=20, repeats=2, only=("batched",)))
    assert all(math.isfinite(r.cpu) and r.cpu > 0 for r in rows), rows
    new, before, issue = bench.ENV_ID, bench.PREVIOUS_ENV_ID, bench.ISSUE_ENV_ID
    assert made == [(1, new), (16, new), (64, new), (64, before), (64, issue), (64, new), (64, new)]  # the rows' order
    newest = [r.name for r in rows]
    assert newest[2:7] == ["batched env R=64", f"batched env R=64, {before}", f"  {new} / {before}",
                           f"batched env R=64, {issue}", "batched env R=64, 1000-particle filter"]  # fmt: skip
    assert math.isclose(rows[4].cpu, rows[2].cpu / rows[3].cpu)
    made.clear()
    older = bench.bench_batched(bench.Args(steps=20, repeats=2, only=("batched",), env_id=before))
    assert {e for _, e in made} == {before}
    assert not any(before in r.name or issue in r.name for r in older) and len(older) == len(newest) - 3


@pytest.mark.filterwarnings("ignore:.*out of date.*:DeprecationWarning")
def test_the_scaling_bench_holds_the_particle_counts_it_names(monkeypatch):
    """A reviewer found the 10,000-particle set held about 730 particles under KLD: the ratio measured the beams
    alone. The rows run the issue's env (a fixed set) and the newest with KLD off, and their notes give the counts
    held (two tiny timing runs; no timing asserted)."""
    from agents.tools import bench

    made = []

    def reset_only(env, steps, seed, policy=None):
        made.append((env.spec.id, env.mcl_config.kld, env.mcl_config.n_particles))
        env.reset(seed=seed)
        return 100.0, 90.0

    monkeypatch.setattr(bench, "_steps_per_s", reset_only)
    rows = bench.bench_scaling(bench.Args(steps=3, only=("scaling",)))
    v0, new = bench.ISSUE_ENV_ID, bench.ENV_ID
    assert made == [(v0, False, 2000), (v0, False, 10000), (new, False, 2000), (new, False, 10000)]  # KLD off
    assert [r.name for r in rows] == [
        f"time(10000, 180) / time(2000, 60), {bench.ISSUE_ENV_ID}",
        f"time(10000, 180) / time(2000, 60), {bench.ENV_ID}, KLD off",
    ]
    assert "the sets held 10,000 and 2,000 particles" in rows[0].note


def test_the_bench_refuses_a_run_of_nothing_and_prints_an_empty_table(capsys):
    from agents.tools import bench

    with pytest.raises(ValueError, match="--only ppo with --quick runs nothing"):
        bench.Args(only=("ppo",), quick=True)
    with pytest.raises(ValueError, match="got map_size_m=0"):
        bench.Args(map_size_m=0)
    bench.print_table([])  # a ValueError of max() before
    assert "no rows" in capsys.readouterr().out


def test_the_bench_runs_the_version_it_is_told():
    """``--env-id`` names the version the env benchmarks run (the docs compare v19 with v18 that way)."""
    from agents.tools import bench
    from filters.experiments.cli import parse

    args = parse(bench.Args, ["--env-id", "SemReloc-v18", "--only", "env"])
    assert type(bench._env(args)).__name__ == "SemRelocEnvV18"
    assert type(bench._env(parse(bench.Args, []))).__name__ == "SemRelocEnv"
    with pytest.raises(ValueError, match="env_id: 'SemSlam-v2' is not one of"):
        bench.Args(env_id="SemSlam-v2")


def test_quick_reproductions_write_under_build_not_docs():
    """A smoke run must never overwrite the shipped reports and figures in docs/."""
    from agents.experiments import paper004
    from filters.experiments import paper000, paper001
    from filters.experiments.cli import parse

    for module, report, figures in (
        (paper000, "out", "figures"),
        (paper001, "doc", "fig_dir"),
        (paper004, "out", None),
    ):
        quick = parse(module.Args, ["--quick"]).resolved()
        full = parse(module.Args, []).resolved()
        assert getattr(quick, report).startswith("build/"), module.__name__
        assert getattr(full, report).startswith("docs"), module.__name__
        if figures:
            assert getattr(quick, figures).startswith("build/") and getattr(full, figures) == "docs/figures"
    assert parse(paper004.Args, ["--quick"]).resolved().seeds == 5
    assert parse(paper004.Args, ["--quick", "--out", "x"]).resolved().out == "x"


def test_free_form_keyword_arguments_are_one_json_object_on_the_command_line():
    """--config.planner and --config.observation could not be set at all before (an empty dict gave no option)."""
    from agents.tools import imitate_active, train_active
    from filters.experiments.cli import parse

    args = parse(imitate_active.Args, ["--config.planner", '{"replan_every": 5}'])
    assert args.config.planner == {"replan_every": 5}
    args = parse(train_active.Args, ["--config.observation", '{"ego_size": 48}'])
    assert args.config.observation == {"ego_size": 48}
    assert parse(train_active.Args, []).config.observation == {}
    args = parse(train_active.Args, ["--config.reward-weights", '{"collision": -0.2, "success": 5}'])
    assert args.config.reward_weights == {"collision": -0.2, "success": 5}
    assert parse(train_active.Args, []).config.reward_weights == {"collision": -0.1}
    with pytest.raises(SystemExit):  # a misspelt term: an argument error, not a worker's traceback
        parse(train_active.Args, ["--config.reward-weights", '{"succes": 5}'])
    for bad in ("[1, 2]", "{oops"):
        with pytest.raises(SystemExit):
            parse(imitate_active.Args, ["--config.planner", bad])
    with pytest.raises(SystemExit):  # the config's own check still runs: an unknown planner argument
        parse(imitate_active.Args, ["--config.planner", '{"no_such_knob": 1}'])


def test_paper004_checks_its_relocalizer_overrides_before_any_episode():
    from agents.experiments import paper004
    from filters.experiments.cli import parse

    assert parse(paper004.Args, ["--mcl", '{"likelihood_scale": 0.05}']).mcl == {"likelihood_scale": 0.05}
    assert parse(paper004.Args, []).mcl == {}
    for bad in ('{"likelihood_scal": 0.05}', '{"likelihood_scale": -1}', "[1]", "{oops"):
        with pytest.raises(SystemExit):
            parse(paper004.Args, ["--mcl", bad])


def test_paper004_weight_plot_takes_steps_with_no_value_without_warning(tmp_path):
    """Steps before any run's first update have no lidar likelihood (NaN): no 'Mean of empty slice'."""
    import warnings

    from agents.experiments import paper004

    runs = [[math.nan, 0.2], [math.nan, 0.2, 0.3]]  # no run has a value at step 1
    results = [{"case": "lab", "semantic": sem, "weights": w} for sem in (False, True) for w in runs]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        paper004._plot_weights(results, ["lab"], tmp_path / "w.png")
    assert (tmp_path / "w.png").stat().st_size > 0


def test_the_demo_refuses_a_negative_seed_and_an_unknown_layout_before_it_runs():
    # a new user's trial: both printed a traceback from inside the episode
    from agents.tools.demo import Args

    with pytest.raises(ValueError, match="seed must be >= 0"):
        Args(seed=-1)
    with pytest.raises(ValueError, match="layout: unknown layout 'nope'"):
        Args(layout="nope")


def test_paper_scripts_refuse_what_they_would_fail_on_or_misreport():
    # a new user's trial: K = 0.5 failed inside the K sweep after the tables had run, and --mcl's
    # n_particles silently replaced --particles while the report said 2000
    from agents.experiments.paper004 import Args as Args004
    from filters.experiments.paper000 import Args as Args000

    with pytest.raises(ValueError, match=r"K must be >= 1 .* got \[0.5\]"):
        Args000(k_sweep=(0.5, math.inf))
    with pytest.raises(ValueError, match="woc_k"):
        Args000(woc_k=0.5)
    from filters.experiments.paper000 import sweep_x
    from filters.experiments.paper001 import speed_reading

    assert sweep_x([math.inf]).tolist() == [2.0]  # a sweep of inf alone crashed the figure
    assert sweep_x([1.0, 5.0, math.inf]).tolist() == [1.0, 5.0, 10.0]
    assert speed_reading(24.3).startswith("faster in this run")  # was "does not reduce work" beside +24 %
    assert speed_reading(0.0).startswith("about as fast") and "add a little" in speed_reading(-14.0)
    with pytest.raises(ValueError, match="--particles"):
        Args004(mcl={"n_particles": 500})


def test_paper000_reports_the_spread_of_plain_fastslam_over_filter_seeds():
    # an outside tester's: two seeds that happened to agree (1.086 and 1.086 m) read as "the seed barely matters"
    from filters.experiments.paper000 import LOW, Args, seed_means, verdict

    with pytest.raises(ValueError, match="seed_spread"):
        Args(seed_spread=-1)

    def runs(*errors):
        return [{"pose_err": e, "lm_err": e, "path_rmse": e, "map_rmse": e} for e in errors]

    ks = [5.0, math.inf]
    tk = {5.0: runs(1.0, 1.2), math.inf: runs(1.1, 1.1)}
    t2 = {(0, name): runs(1.4, 1.0) for name in ("FastSLAM", "WOCPF", "EKF-SLAM")}
    t2.update({(1, name): runs(1.4, 1.0) for name in ("FastSLAM", "WOCPF", "EKF-SLAM")})
    spread = [runs(1.5, 1.5), runs(0.9, 0.9)]
    assert seed_means([LOW, LOW], t2, tk, spread, ks) == pytest.approx([1.1, 1.2, 1.5, 0.9])
    t1 = {(n, name): runs(1.0, 1.0) for n in (10,) for name in ("FastSLAM", "WOCPF")}
    text = verdict(Args(runs=2), [LOW, LOW], t2, t1, tk, spread, [10], ks)
    assert "with 4 filter seeds gives mean pose errors from 0.900 m to 1.500 m" in text
    assert "a range of 0.600 m; the K sweep's means span 0.000 m" in text
    with pytest.raises(ValueError, match=r"same seed tag \(\[600, 601\]\)"):
        Args(table1_particles=(10, 295))  # Table 1's tags 600 and 601 are the seed spread's


def test_paper000_seed_spread_is_plain_fastslam_with_its_own_filter_seeds():
    from filters.experiments.paper000 import LOW, Args, drive, filter_rng, k_sweep_job, make_filter, run_filter

    args = Args(runs=1, particles=3, k_sweep=(5.0,), seed_spread=2)
    out = k_sweep_job((args, 0))
    run = drive(args, LOW, 0, 0)
    for j, res in enumerate(out["seeds"]):
        ref = run_filter(make_filter("fs", args, LOW, filter_rng(args, 0, 0, 600 + j), 3, math.inf), run)
        assert res["pose_err"] == ref["pose_err"]  # K = inf (not the sweep's or WOCPF's K), tag 600 + j
    assert len({res["pose_err"] for res in out["seeds"]} | {out[5.0]["pose_err"]}) == 3


def test_train_ppo_help_lists_every_built_in_layout(capsys):
    from semreloc_env.layouts import LAYOUT_NAMES

    with pytest.raises(SystemExit):
        _main(ENTRY_POINTS["semreloc-train-ppo"])(["--help"])
    text = re.sub(r"[\s│]+", "", capsys.readouterr().out)  # the help is wrapped in a box
    assert [n for n in LAYOUT_NAMES if n.replace("_", "") not in text.replace("_", "")] == []


SEED_FLAG = {  # each command's seed option (a twenty-fourth tester's: -1 gave a traceback, some after their work)
    "semreloc-demo": "--seed",
    "semreloc-repro-paper000": "--seed",
    "semreloc-repro-paper001": "--seed",
    "semreloc-repro-paper004": "--first-seed",
    "semreloc-evaluate-relocalizer": "--seed-base",
    "semreloc-soak": "--seed",
    "semreloc-build-maps": "--layout-seed",
    "semreloc-replay-log": "--seed",
    "semreloc-train-active": "--config.seed",
    "semreloc-bench": "--seed",
    "semreloc-profile-step": "--seed",
    "semreloc-train-ppo": "--eval-seed",
}


@pytest.mark.parametrize("name", sorted(SEED_FLAG))
def test_a_negative_seed_exits_2_before_any_work(name, capsys):
    with pytest.raises(SystemExit) as e:
        _main(ENTRY_POINTS[name])([SEED_FLAG[name], "-1"])
    err = capsys.readouterr().err
    assert e.value.code == 2 and "Unrecognized" not in err and re.search(r"seed.*(>= 0|must be)", err, re.S), err


def test_an_output_path_under_a_file_exits_2_and_ctrl_c_exits_130(tmp_path, capsys):
    from filters.experiments.cli import command

    (tmp_path / "afile").write_text("hi")
    for name, flag in (("semreloc-build-maps", "--out"), ("semreloc-repro-paper004", "--out")):
        with pytest.raises(SystemExit) as e:
            _main(ENTRY_POINTS[name])([flag, str(tmp_path / "afile" / "sub")])
        assert e.value.code == 2 and "is a file, not a folder" in capsys.readouterr().err

    (tmp_path / "bfile").write_text("hi")
    with pytest.raises(SystemExit) as e:  # an existing file where a folder is wanted
        _main(ENTRY_POINTS["semreloc-repro-paper004"])(["--out", str(tmp_path / "bfile")])
    assert e.value.code == 2 and "is a file, not a folder" in capsys.readouterr().err
    # an outside audit: a report's path that is a folder failed only after every run, leaving figures and no report
    (tmp_path / "adir").mkdir()
    for name, flag in (("semreloc-repro-paper000", "--out"), ("semreloc-repro-paper001", "--doc")):
        with pytest.raises(SystemExit) as e:
            _main(ENTRY_POINTS[name])([flag, str(tmp_path / "adir")])
        assert e.value.code == 2 and "is a folder: give the path of the file" in capsys.readouterr().err
    assert list((tmp_path / "adir").iterdir()) == []
    from filters.experiments import paper000
    from filters.experiments.cli import check_common_options

    check_common_options(paper000.Args(out=str(tmp_path / "bfile")))  # paper 000's --out is a file, suffix or not

    @command
    def interrupted(argv=None):
        raise KeyboardInterrupt

    assert interrupted([]) == 130 and "interrupted" in capsys.readouterr().err
    assert all(hasattr(_main(t), "__wrapped__") for t in ENTRY_POINTS.values())  # every command is decorated
    # from the command line the process dies of SIGINT, so that a calling shell loop stops too (a review's)
    import signal
    import subprocess
    import sys

    code = (
        "from filters.experiments.cli import command\n"
        "@command\ndef main(argv=None):\n    raise KeyboardInterrupt\n"
        "raise SystemExit(main())\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=60)
    assert proc.returncode == -signal.SIGINT and "interrupted" in proc.stderr and "Traceback" not in proc.stderr


@pytest.mark.parametrize(
    "name, argv",
    [
        ("semreloc-build-maps", ["--layout", "nosuch"]),
        ("semreloc-build-maps", ["--resolution", "inf"]),
        ("semreloc-profile-step", ["--layout", "nosuch"]),
        ("semreloc-bench", ["--map-size-m", "nan"]),
        ("semreloc-repro-paper001", ["--alpha0", "nan"]),
        ("semreloc-semslam-eval", ["--woc-k", "0.5"]),
        ("semreloc-semslam-eval", ["--odometry-alpha", "nan"]),
        ("semreloc-semslam-eval", ["--layout", "nosuch"]),  # an outside audit's two
        ("semreloc-semslam-eval", ["--figure", "frame.jpgx"]),
        ("semreloc-repro-paper001", ["--slam-runs", "1"]),
        ("semreloc-repro-paper004", ["--cases", "lab", "lab"]),
    ],
)
def test_values_a_command_failed_on_late_exit_2(name, argv, capsys):
    # a twenty-fourth tester's: each gave a traceback, some inside their first job
    with pytest.raises(SystemExit) as e:
        _main(ENTRY_POINTS[name])(argv)
    err = capsys.readouterr().err
    assert (
        e.value.code == 2 and "Unrecognized" not in err and argv[0].lstrip("-").split("-")[0] in err.replace("_", "-")
    )


@pytest.mark.filterwarnings("ignore:.*out of date.*:DeprecationWarning")
def test_the_env_and_reset_benchmarks_say_what_their_kernels_take():
    """The single env's and the global reset's rows of compiled kernels: a share of the measured time, and the bound
    on fast / reference they give (tiny sizes; no timing asserted beyond what the arithmetic must give)."""
    import math

    from agents.tools import bench

    args = bench.Args(steps=40, repeats=2)
    env_rows = bench.bench_env(args)
    names = [r.name for r in env_rows]
    for policy in ("explorer", "random"):  # each policy's rows: fast, reference, their ratio, kernels, the bound
        at = names.index(f"{bench.ENV_ID} step, {policy}, fast path")
        fast, ref, _, kernels, ref_kernels, bound = env_rows[at : at + 6]
        assert kernels.name == "  a fast-path step's compiled kernels" and bound.name == "  reference / kernels alone"
        assert ref_kernels.name == "  a reference-path step's compiled kernels"
        assert math.isclose(kernels.wall, 100 * kernels.cpu / 1e3 * fast.cpu)  # a share of the fast step
        assert math.isclose(ref_kernels.wall, 100 * ref_kernels.cpu / 1e3 * ref.cpu)
        assert math.isclose(bound.cpu, 1e3 / (kernels.cpu * ref.cpu))
        assert 0.0 < kernels.wall < 100.0 and 0.0 < ref_kernels.wall < 100.0
    reset_rows = bench.bench_reset(args)
    names = [r.name for r in reset_rows]
    at = names.index("  of which compiled kernels")
    assert names[at - 1] == "reset() (cached map)"
    row, reset = reset_rows[at], reset_rows[at - 1]
    assert 0.0 < row.cpu and math.isclose(row.wall, 100 * row.cpu / reset.cpu) and row.wall < 100.0
    issue = reset_rows[names.index(f"reset() (cached map), {bench.ISSUE_ENV_ID}")]  # the env the issue measured
    assert 0.0 < issue.cpu < 50.0 and "2000 particles" in issue.note


@pytest.mark.filterwarnings("ignore:.*out of date.*:DeprecationWarning")
def test_the_reset_rows_time_each_version_s_own_resets(monkeypatch):
    """The newest version's resets, the version before's and the issue's env's are timed in turn; each row shows its
    own env's time (a fake timer gives each env's resets a time of their own)."""
    from agents.tools import bench

    made = []
    env_of = bench._env

    def recording_env(args, env_id="", **kwargs):
        made.append(env_id or bench.ENV_ID)
        return env_of(args, env_id, **kwargs)

    monkeypatch.setattr(bench, "_env", recording_env)

    def fake_times(fns, repeats):  # the i-th function's calls take (i + 1) ms
        return [(1e-3 * (i + 1), 1e-3 * (i + 1)) for i in range(len(fns))]

    monkeypatch.setattr(bench, "_interleaved_median_times", fake_times)
    rows = {r.name: r for r in bench.bench_reset(bench.Args(steps=20, repeats=2, only=("reset",)))}
    assert made[:3] == [bench.ENV_ID, bench.PREVIOUS_ENV_ID, bench.ISSUE_ENV_ID]
    assert rows["reset() (cached map)"].cpu == 1.0 and rows[f"reset() (cached map), {bench.PREVIOUS_ENV_ID}"].cpu == 2.0
    assert rows[f"reset() (cached map), {bench.ISSUE_ENV_ID}"].cpu == 3.0


@pytest.mark.filterwarnings("ignore:.*out of date.*:DeprecationWarning")
def test_the_batched_split_rows_say_what_fusing_and_stacking_would_do():
    import math

    from agents.tools import bench

    rows = bench.bench_batched_split(bench.Args(steps=60, repeats=2, only=("batched_split",)))
    assert all(math.isfinite(r.cpu) and r.cpu > 0 for r in rows), rows
    by = {r.name: r for r in rows}
    calls, dispatch = by["  compiled calls per robot-step"].cpu, by["  one compiled call's dispatch"].cpu
    saved = by["  dispatch one call for all robots saves"]
    assert math.isclose(saved.cpu, calls * dispatch)  # us per robot-step
    assert math.isclose(saved.wall, 100 * saved.cpu / by["batched R=64: one robot-step"].cpu)
    assert calls > 5 and 0.0 < dispatch < 100.0 and by["  stacked (R, N_max, 3) / held particles"].cpu > 1.0
    names = [r.name for r in rows]  # the env the issue measured: its robot-step, and what its kernels alone allow
    at = names.index(f"batched R=64, {bench.ISSUE_ENV_ID}: one robot-step")
    step, alone = rows[at], rows[at + 1]
    assert alone.name == f"  {bench.ISSUE_ENV_ID}: robot-steps per CPU-s, kernels alone" and alone.cpu > 1e6 / step.cpu
    from agents.tools.profile_step import compiled_functions

    top = [part.rsplit(" ", 2) for part in alone.note.split("heaviest: ")[1].split(", ")]
    kernels = {name for _, _, name in compiled_functions()}
    assert len(top) == 3 and all(name.rpartition(".")[2] in kernels and unit == "%" for name, _, unit in top)


def test_the_kernels_alone_rows_of_a_batched_split():
    """A hand-made split: its robot-step, what its kernels alone allow, and the three heaviest kernels' shares of the
    kernels' time."""
    from agents.tools import bench
    from agents.tools.profile_step import BatchedSplit

    s = BatchedSplit(
        robot_steps=100, total_s=0.1, update_steps=20, update_s=0.05, audits=1, audit_s=0.01, plain_steps=80,
        plain_s=0.04, resets=0, reset_s=0.0, loop_s=0.01, kernel_s=0.04, kernel_calls=1500, weighed=1000,
        weighed_stacked=2500, kernels=(("a", 0.02), ("b", 0.01), ("c", 0.006), ("d", 0.004)),
    )  # fmt: skip
    step, alone = bench._kernels_alone_rows(s, "SemReloc-v0", "the env")
    assert step.name == "batched R=64, SemReloc-v0: one robot-step" and step.cpu == pytest.approx(1000.0)
    assert alone.cpu == pytest.approx(2500.0)
    assert alone.note == "400 us per robot-step; heaviest: a 50 %, b 25 %, c 15 %"


def test_the_batched_split_rows_run_the_newest_version_then_the_issue_s_env(monkeypatch):
    """Each env's rows come from its own split (fake splits, one per env, with robot-steps of their own cost)."""
    import dataclasses

    from agents.tools import bench, profile_step

    runs = []
    fake = profile_step.BatchedSplit(
        robot_steps=100, total_s=0.1, update_steps=20, update_s=0.05, audits=1, audit_s=0.01, plain_steps=80,
        plain_s=0.04, resets=0, reset_s=0.0, loop_s=0.01, kernel_s=0.04, kernel_calls=1500, weighed=1000,
        weighed_stacked=2500, kernels=(("a", 0.02), ("b", 0.01), ("c", 0.006), ("d", 0.004)),
    )  # fmt: skip

    def recording(num_envs, steps, seed, env_id, **kwargs):
        runs.append(env_id)
        return dataclasses.replace(fake, total_s=0.1 * len(runs))  # the first env's robot-step 1 ms, the second's 2

    monkeypatch.setattr(profile_step, "batched_split", recording)
    monkeypatch.setattr(profile_step, "dispatch_seconds", lambda calls=0: 1e-6)
    rows = {r.name: r for r in bench.bench_batched_split(bench.Args(steps=15, repeats=2, only=("batched_split",)))}
    assert runs == [bench.ENV_ID, bench.ISSUE_ENV_ID]
    assert rows["batched R=64: one robot-step"].cpu == pytest.approx(1000.0)
    assert rows[f"batched R=64, {bench.ISSUE_ENV_ID}: one robot-step"].cpu == pytest.approx(2000.0)
    runs.clear()
    older = bench.bench_batched_split(bench.Args(steps=15, repeats=2, only=("batched_split",), env_id="SemReloc-v20"))
    assert runs == ["SemReloc-v20"] and not any(bench.ISSUE_ENV_ID in r.name for r in older)


def test_compiled_median_is_the_median_call_s_time_in_the_kernels():
    import numpy as np

    from agents.tools import bench
    from agents.tools.profile_step import empty_kernel_args
    from filters.localization.likelihood_field import log_likelihood_kernel

    assert bench._compiled_median([lambda: None, lambda: np.cos(np.zeros(4))]) == 0.0
    args = empty_kernel_args()
    assert bench._compiled_median([lambda: None, lambda: log_likelihood_kernel(*args)] * 2) > 0.0  # two of four
    assert bench._compiled_median([lambda: None] * 3 + [lambda: log_likelihood_kernel(*args)]) == 0.0


def test_ppo_s_own_work_is_what_the_run_spent_outside_the_env():
    from agents.tools import bench

    own, env = bench.ppo_own_work({"steps": 1000, "cpu": 1.0, "env_cpu": 0.7, "wall": 2.0, "env_wall": 1.2})
    assert abs(own - 3e-4) < 1e-15 and abs(env - 7e-4) < 1e-15


def test_the_filing_benchmark_times_v0_under_the_code_the_issue_measured():
    """`bench_filing` runs ``SemReloc-v0`` on the code at `FILING_COMMIT` (extracted from git) and on this code, each
    in processes of their own (tiny sizes; no timing asserted)."""
    import math
    import shutil
    import subprocess

    from agents.tools import bench

    root = Path(__file__).resolve().parents[1]
    blob = f"{bench.FILING_COMMIT}:semreloc_env/__init__.py"  # the commit and its files, here
    if shutil.which("git") is None or subprocess.run(["git", "-C", str(root), "cat-file", "-e", blob]).returncode:
        pytest.skip(f"no git checkout with {bench.FILING_COMMIT[:7]} in its history")
    rows = bench.bench_filing(bench.Args(steps=40, repeats=1))
    assert [r.name for r in rows[:4]] == [
        f"SemReloc-v0 step, explorer, code at {bench.FILING_COMMIT[:7]}",
        "SemReloc-v0 step, explorer, this code",
        "  this code / code at filing, speed",
        "  this code's v0 step, compiled kernels",
    ]
    for old, new, ratio, kernels in (rows[0:4], rows[4:8]):
        assert old.cpu > 0 and new.cpu > 0 and math.isclose(ratio.cpu, old.cpu / new.cpu)
        assert "episodes ended" in new.note and 0.0 < kernels.cpu
        assert math.isclose(kernels.wall, 100 * kernels.cpu / new.cpu)


def test_the_filing_code_is_extracted_or_refused(tmp_path):
    import shutil
    import subprocess

    from agents.tools import bench

    assert not bench._code_at("0" * 40, Path("/nonexistent-dir-for-a-refused-extraction"))
    root = Path(__file__).resolve().parents[1]
    blob = f"{bench.FILING_COMMIT}:semreloc_env/__init__.py"
    if shutil.which("git") is None or subprocess.run(["git", "-C", str(root), "cat-file", "-e", blob]).returncode:
        pytest.skip(f"no git checkout with {bench.FILING_COMMIT[:7]} in its history")
    assert bench._code_at(bench.FILING_COMMIT, tmp_path)
    assert "SemReloc-v0" in (tmp_path / "semreloc_env" / "__init__.py").read_text()
    assert not (tmp_path / "semreloc_env" / "envs" / "batched.py").exists()  # the issue's first round came after


def test_a_failed_timing_process_says_why(tmp_path):
    from agents.tools import bench

    (tmp_path / "semreloc_env").mkdir()
    (tmp_path / "semreloc_env" / "__init__.py").write_text("raise ImportError('a package broken on purpose')\n")
    with pytest.raises(RuntimeError, match="failed:(.|\n)*a package broken on purpose"):
        bench._timed_v0(tmp_path, "random", 5, tmp_path / "numba")
