"""The Bayes-level reference of the paper 001 reproduction (filters.experiments.paper001): same runs as
Table 1, deterministic."""

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
