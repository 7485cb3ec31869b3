"""Imitation of the viewpoint planner (agents.imitation): teacher labels, a tiny DAgger run saved and
reloaded through agents.load_policy, and its configuration checks."""

import csv
import json

import gymnasium as gym
import numpy as np
import pytest

import semreloc_env  # noqa: F401
from agents.imitation import ImitationConfig, TeacherLabels, imitate
from agents.learned import load_policy, read_metadata
from agents.train_active import ActiveTrainConfig
from agents.viewpoint import ViewpointPlanner


def _env(**kw):
    kw = {"layout": "twin_rooms", "relocalizer": {"n_particles": 300}, "max_episode_steps": 40, **kw}
    return gym.make("SemReloc-v22", **kw)


def _tiny_train(**kw) -> ActiveTrainConfig:
    kw = {
        "options": (),
        "repeat": 1,
        "belief_mass_weight": 0.0,
        "kinds": ("procedural_lookalike",),
        "kind_weights": None,
        "layout_seeds": (0, 2),
        "particles": 200,
        "max_episode_steps": 30,
        "n_envs": 2,
        "vec_env": "dummy",
        "features_dim": 16,
        "cnn_channels": (4, 4, 4),
        "net_arch": (8,),
        "progress_bar": False,
        **kw,
    }
    return ActiveTrainConfig(**kw)


def test_teacher_labels_are_the_planners_decisions_whatever_action_is_taken(monkeypatch):
    import agents.viewpoint as vp

    calls = []
    sample = vp.belief_sample
    monkeypatch.setattr(vp, "belief_sample", lambda *a, **k: (calls.append(1), sample(*a, **k))[1])
    # a look-alike layout: the belief is spread, so the planner subsamples it with its own generator,
    # which the teacher must seed from the reset seed (3), not from its constructor's (0); v18's KLD bound keeps the
    # belief spread for longer, without clusters that hold half the mass, so the planner subsamples it in this episode
    kw = {
        "layout": "procedural_lookalike",
        "layout_seed": 1,
        "relocalizer": {"n_particles": 2000, "kld_epsilon": 0.05},
        "max_episode_steps": 80,
    }
    env = TeacherLabels(_env(**kw), {"seed": 0})
    ref, planner = _env(**kw), ViewpointPlanner()
    planner.wrap(ref)
    obs, info = env.reset(seed=3)
    ref_obs, _ = ref.reset(seed=3)
    planner.seed = 3
    planner.reset()
    planner.observe(ref_obs)
    rng = np.random.default_rng(0)
    for t in range(70):
        label = planner.decide(ref_obs)
        assert info["teacher_action"] == label
        # first other actions than the teacher's (it must follow the robot all the same), then its own
        a = int(rng.integers(0, 4)) if t < 10 else label
        obs, *_, info = env.step(a)
        ref_obs, *_ = ref.step(a)
        planner.observe(ref_obs)
        np.testing.assert_array_equal(obs["lidar"], ref_obs["lidar"])
    assert calls, "the planner never subsampled the belief: the seed was not tested"
    with pytest.raises(TypeError, match="Discrete"):
        TeacherLabels(_env(action_type="continuous"))


@pytest.fixture(scope="module")
def dagger_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("dagger")
    config = ImitationConfig(train=_tiny_train(), rounds=2, episodes_per_round=2, epochs=2, batch_size=32)
    return out, imitate(config, out)


def test_dagger_smoke_run_writes_its_rounds_and_a_loadable_policy(dagger_run):
    out, path = dagger_run
    with open(out / "imitation.csv") as f:
        rows = list(csv.DictReader(f))
    assert [int(r["round"]) for r in rows] == [0, 1, 2]  # 2 rounds + the final network alone
    assert [float(r["beta"]) for r in rows] == [1.0, 0.5, 0.0]
    samples = [int(r["samples"]) for r in rows]
    assert samples[0] > 0 and samples == sorted(samples)  # the data set grows
    assert all(0.0 <= float(r["agreement"]) <= 1.0 for r in rows)
    assert rows[-1]["loss"] == "nan" and float(rows[0]["loss"]) > 0  # the final round fits nothing
    # strict JSON (a new user's trial: NaN is not JSON, jq refused timing.json)
    timing = json.loads((out / "timing.json").read_text(), parse_constant=lambda c: pytest.fail(f"{c} in JSON"))
    assert timing["rounds"][-1]["loss"] is None and timing["rounds"][0]["loss"] > 0
    assert (out / "learning_curve.png").stat().st_size > 0
    meta = read_metadata(path)
    assert meta["options"] == [] and meta["repeat"] == 1
    policy = load_policy(path)
    for kw in ({}, {"action_type": "continuous"}, {"relocalizer": {"n_particles": 50}, "layout": "lab"}):
        env = policy.wrap(_env(**kw))
        policy.reset()
        obs, _ = env.reset(seed=1)
        for _ in range(5):
            a = policy.act(obs)
            assert env.action_space.contains(a)
            obs, *_ = env.step(a)


def test_dagger_is_seeded(dagger_run, tmp_path):
    import torch

    out, path = dagger_run
    config = ImitationConfig(train=_tiny_train(), rounds=2, episodes_per_round=2, epochs=2, batch_size=32)
    again = imitate(config, tmp_path)
    a, b = load_policy(path).model.policy, load_policy(again).model.policy
    for pa, pb in zip(a.parameters(), b.parameters()):
        assert torch.equal(pa, pb)


def test_imitation_config_errors():
    with pytest.raises(ValueError, match="options must be empty"):
        ImitationConfig(train=_tiny_train(options=("explore",)))
    with pytest.raises(ValueError, match="repeat 1"):
        ImitationConfig(train=_tiny_train(repeat=4))
    for bad in ({"rounds": 0}, {"beta": 1.5}, {"beta_decay": -0.1}, {"learning_rate": 0.0}, {"epochs": True}):
        with pytest.raises(ValueError, match=next(iter(bad))):
            ImitationConfig(train=_tiny_train(), **bad)
    with pytest.raises(ValueError, match="planner: .*horizon"):  # ViewpointPlanner has no such argument
        ImitationConfig(train=_tiny_train(), planner={"horizon": 3})
    with pytest.raises(ValueError, match="time_budget_s applies to train_active only"):  # was taken and ignored
        ImitationConfig(train=_tiny_train(time_budget_s=60.0))


def test_a_run_whose_envs_fail_to_build_leaves_its_folder_usable(monkeypatch, tmp_path):
    """An outside audit: config.json was written before the envs were built, so a run that failed there blocked its
    own folder ("holds a training run already")."""
    import agents.imitation as imitation

    def broken(*args, **kwargs):
        raise RuntimeError("no envs today")

    monkeypatch.setattr(imitation, "make_active_venv", broken)
    with pytest.raises(RuntimeError, match="no envs today"):
        imitate(ImitationConfig(train=_tiny_train(), rounds=1, episodes_per_round=1), tmp_path / "run")
    assert not (tmp_path / "run" / "config.json").exists()
    imitation.check_fresh_out(tmp_path / "run", resumable=False)  # the folder takes a new run


def test_collected_pairs_hold_the_teachers_label_of_each_state():
    # with beta = 1 the robot takes the teacher's action, so the stored labels are the actions taken
    # (an early version stored one array object for every step, which later steps overwrote)
    from agents.imitation import _Dataset, _Rollouts
    from agents.train_active import build_model, make_active_venv

    config = ImitationConfig(train=_tiny_train(n_envs=1), rounds=1, episodes_per_round=1)
    venv = make_active_venv(config.train, teacher={})
    model = build_model(config.train, venv)
    taken = []
    step = venv.step
    venv.step = lambda actions: (taken.append(np.array(actions)), step(actions))[1]
    data = _Dataset(10_000)
    _Rollouts(venv).collect(model, 2, 1.0, np.random.default_rng(0), data)
    obs, labels = data.arrays()
    np.testing.assert_array_equal(labels, np.concatenate(taken))
    assert len(set(labels.tolist())) > 1  # a planner that only drives forward would test nothing
    assert obs["ego"].shape[0] == labels.shape[0]
    venv.close()
