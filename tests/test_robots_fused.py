"""`agents.tools.robots_fused`: the motion and likelihood kernels fused over a batched step's robots give the
per-robot calls' results bit for bit, and the comparison notices when they do not."""

import dataclasses

import numpy as np
import pytest

from agents.tools import robots_fused
from filters.localization import likelihood_field
from filters.motion import odometry


@pytest.fixture(scope="module")
def recorded():
    """8 robots, 6 recorded steps: several robots predict in every step, and in some step several weigh."""
    return robots_fused.record_calls(8, 6, seed=1)


def test_recording_groups_the_calls_by_step_and_restores_the_kernels(recorded):
    assert recorded.robot_steps == 48
    assert type(likelihood_field.log_likelihood_kernel).__name__ == "CPUDispatcher"
    assert type(odometry._sample_kernel).__name__ == "CPUDispatcher"
    motion = recorded.calls[robots_fused.MOTION]
    assert len(motion) == 6 and all(len(g) >= 2 for g in motion)
    weighing = recorded.calls[robots_fused.LIKELIHOOD]
    assert any(len(g) >= 2 for g in weighing), [len(g) for g in weighing]
    for g in weighing:  # a group reads one set of tables
        assert len({id(a[9]) for a in g}) == 1


@pytest.mark.parametrize("name", [robots_fused.MOTION, robots_fused.LIKELIHOOD])
def test_one_fused_call_gives_each_robot_its_own_call_s_bits(recorded, name):
    for g in recorded.calls[name]:
        _, fused = robots_fused._fused_outputs(name, g)
        for mine, theirs in zip(fused, robots_fused._per_robot_outputs(name, g), strict=True):
            for a, b in zip(mine, theirs, strict=True):
                assert a.shape == b.shape and np.array_equal(a, b)


def test_compare_times_the_three_ways_and_reports_the_same_bits(recorded):
    got = robots_fused.compare(recorded, repeats=1)
    assert set(got) == {robots_fused.MOTION, robots_fused.LIKELIHOOD}
    for name, t in got.items():
        assert t.same_bits
        assert t.calls == sum(len(g) for g in recorded.calls[name]) and t.groups == len(recorded.calls[name])
        assert t.per_robot_us > 0 and t.fused_us > 0 and t.fused_laid_out_us > 0


def test_compare_reports_a_fused_kernel_that_differs(recorded, monkeypatch):
    table = robots_fused._KERNELS[robots_fused.LIKELIHOOD]

    def off_by_one_robot(*args):
        table.fused(*args)
        args[-1][args[4][-2] :] += 1e-12  # the last robot's semantic log-likelihoods

    monkeypatch.setitem(
        robots_fused._KERNELS, robots_fused.LIKELIHOOD, dataclasses.replace(table, fused=off_by_one_robot)
    )
    got = robots_fused.compare(recorded, repeats=1)
    assert not got[robots_fused.LIKELIHOOD].same_bits
    assert got[robots_fused.MOTION].same_bits
