"""The Bayes-level reference of the paper 001 reproduction (filters.experiments.paper001): same runs as
Table 1, deterministic."""

from pathlib import Path

import numpy as np
import pytest

from filters.experiments import paper001
from filters.experiments.cli import parse
from filters.smc.models import GrowthModel
from filters.smc.pf import BootstrapPF, PFConfig, rmse


def _args(*argv: str) -> paper001.Args:
    return parse(paper001.Args, list(argv))


def test_reference_pf_runs_over_table1_runs_and_is_deterministic():
    args = _args("--runs", "3", "--steps", "20", "--reference-particles", "300")
    ref = paper001.run_reference(args)
    assert np.array_equal(ref, paper001.run_reference(args))
    model = GrowthModel()
    xs, ys = model.simulate(20, np.random.default_rng([0, 1]))  # run 1 of Table 1
    est = BootstrapPF(PFConfig(n_particles=300)).run(model, ys, np.random.default_rng([0, 1, 300, 0]))
    assert ref[1] == rmse(est, xs)
    line = paper001.reference_line(args, ref)
    assert "300 particles over the same 3 runs" in line and "1.8843" in line


def test_reference_line_says_the_bound_only_when_the_interval_is_above_the_paper():
    args = _args("--runs", "3")
    assert "no filter can reach" in paper001.reference_line(args, np.array([3.1, 3.2, 3.3]))
    assert "not ruled out" in paper001.reference_line(args, np.array([1.0, 1.2, 1.1]))


def test_reference_options_are_checked():
    with pytest.raises(SystemExit):
        _args("--reference-particles", "-1")
    with pytest.raises(SystemExit):
        _args("--reference-only", "--reference-particles", "0")


def test_settings_that_failed_at_the_end_of_a_run_are_refused_up_front():
    """An outside audit: each of these ran every table, then crashed before the report."""
    for argv in (["--slam-runs", "1"], ["--slam-particles"], ["--particles"]):
        with pytest.raises(SystemExit):
            _args(*argv)
    assert _args("--slam-runs", "2").slam_runs == 2


def test_the_report_follows_the_arguments(tmp_path):
    """An outside audit: with --alpha0 3 the report said alpha0 = 1 "fixed before the first run" (and Table 3 ran
    alpha0 = 1 whatever was given); the run-time heading said 100 steps whatever --steps was."""
    from filters.experiments.paper001 import make_slam_filters
    from filters.simulators.car_sim import CarSimConfig
    from filters.slam.ifa_fastslam import FireflySLAMConfig

    out = ["--doc", str(tmp_path / "r.md"), "--fig-dir", str(tmp_path / "f")]
    args = _args("--runs", "2", "--steps", "5", "--particles", "10", "--no-ablations", "--reference-particles", "0",
                 "--alpha0", "3", "--no-slam", *out)  # fmt: skip
    t1 = paper001.run_table1(args)
    text = Path(paper001.write_report(args, [], t1, None, [], 1.0)).read_text()
    assert "alpha0 = 3.0" in text and "fixed before its first run" in text and "never changed" not in text
    assert "Run time per run of 5 steps" in text and "U[0, 1)" in text
    filters = make_slam_filters(10, 1, CarSimConfig(), alpha0=3.0)
    for name in ("FA-FastSLAM", "IFA-FastSLAM"):
        assert filters[name](np.random.default_rng(0)).firefly.alpha0 == 3.0
    assert isinstance(filters["IFA-FastSLAM"](np.random.default_rng(0)).firefly, FireflySLAMConfig)
