"""The Bayes-level reference of scripts/repro_paper001.py: same runs as Table 1, deterministic."""

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

from filters.smc.models import GrowthModel
from filters.smc.pf import BootstrapPF, PFConfig, rmse


def _load():
    path = Path(__file__).resolve().parents[1] / "scripts" / "repro_paper001.py"
    spec = importlib.util.spec_from_file_location("repro_paper001", path)
    mod = importlib.util.module_from_spec(spec)
    sys.modules["repro_paper001"] = mod
    spec.loader.exec_module(mod)
    return mod


def test_reference_pf_runs_over_table1_runs_and_is_deterministic():
    rp = _load()
    args = rp.parse_args(["--runs", "3", "--steps", "20", "--reference-particles", "300"])
    ref = rp.run_reference(args)
    assert np.array_equal(ref, rp.run_reference(args))
    model = GrowthModel()
    xs, ys = model.simulate(20, np.random.default_rng([0, 1]))  # run 1 of Table 1
    est = BootstrapPF(PFConfig(n_particles=300)).run(model, ys, np.random.default_rng([0, 1, 300, 0]))
    assert ref[1] == rmse(est, xs)
    line = rp.reference_line(args, ref)
    assert "300 particles over the same 3 runs" in line and "1.8843" in line


def test_reference_line_says_the_bound_only_when_the_interval_is_above_the_paper():
    rp = _load()
    args = rp.parse_args(["--runs", "3"])
    assert "no filter can reach" in rp.reference_line(args, np.array([3.1, 3.2, 3.3]))
    assert "not ruled out" in rp.reference_line(args, np.array([1.0, 1.2, 1.1]))


def test_reference_options_are_checked():
    rp = _load()
    with pytest.raises(SystemExit):
        rp.parse_args(["--reference-particles", "-1"])
    with pytest.raises(SystemExit):
        rp.parse_args(["--reference-only", "--reference-particles", "0"])
