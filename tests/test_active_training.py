"""Active-relocalization training: ActionRepeat, the CNN + MLP extractor, a PPO smoke run saved and
reloaded through agents.load_policy, the shipped policy, and evaluate_active with learned policies."""

import csv
import dataclasses
import json
import zipfile

import gymnasium as gym
import numpy as np
import pytest
import torch

import agents.experiments.evaluate_active as ev
import semreloc_env  # noqa: F401
from agents.active_features import ActiveExtractor
from agents.learned import META_NAME, SHIPPED_POLICY, load_policy, read_metadata
from agents.train_active import ActiveTrainConfig, train_active
from filters.experiments.cli import parse
from semreloc_env.observations import ActiveObservation
from semreloc_env.wrappers import ActionRepeat


def _env(**kw):
    kw = {"layout": "twin_rooms", "relocalizer": {"n_particles": 300}, "max_episode_steps": 50, **kw}
    return gym.make("SemReloc-v22", **kw)


def test_action_repeat_sums_rewards_and_terms_and_stops_at_the_episode_end():
    plain, rep = _env(max_episode_steps=10), ActionRepeat(_env(max_episode_steps=10), 4)
    plain.reset(seed=6)  # a start from which the filter does not converge within 10 steps
    rep.reset(seed=6)
    total, terms = 0.0, {}
    for _ in range(4):
        _, r, _, _, info = plain.step(0)
        total += r
        for k, v in info["rewards"].items():
            terms[k] = terms.get(k, 0.0) + v
    obs_r, r_r, term_r, trunc_r, info_r = rep.step(0)
    assert r_r == pytest.approx(total)
    assert info_r["rewards"] == pytest.approx(terms) and info_r["inner_steps"] == 4
    np.testing.assert_array_equal(info_r["pose"], info["pose"])
    rep.step(0)  # 8 steps
    *_, trunc, info = rep.step(0)  # only 2 steps left before the time limit
    assert trunc and info["inner_steps"] == 2
    for bad in (0, -1, 1.5, True):
        with pytest.raises(ValueError):
            ActionRepeat(_env(), bad)


def test_extractor_handles_every_active_key_and_rejects_small_images():
    env = ActiveObservation(_env())
    ext = ActiveExtractor(env.observation_space, features_dim=16, cnn_channels=(4, 4, 4), image_dim=8, vector_dim=8)
    assert ext.image_keys == ["ego", "global"]
    assert "semantic_class" in ext.vector_keys and "hypotheses" in ext.vector_keys
    from stable_baselines3.common.preprocessing import preprocess_obs

    obs, _ = env.reset(seed=0)
    batch = {k: torch.as_tensor(np.asarray(v)[None]) for k, v in obs.items()}
    feats = ext(preprocess_obs(batch, env.observation_space))
    assert feats.shape == (1, 16) and torch.all(torch.isfinite(feats))
    small = gym.spaces.Dict({"img": gym.spaces.Box(0, 1, (3, 4, 4), np.float32)})
    with pytest.raises(ValueError, match="H, W >= 8"):
        ActiveExtractor(small)


def test_learning_curve_needs_logged_rollouts(tmp_path):
    from agents.train_active import plot_learning_curve

    (tmp_path / "progress.csv").write_text("time/total_timesteps,rollout/success_rate,rollout/ep_rew_mean\n")
    with pytest.raises(ValueError, match="no rows"):
        plot_learning_curve(tmp_path / "progress.csv", tmp_path / "c.png")


def test_config_rejects_bad_values():
    with pytest.raises(ValueError):
        ActiveTrainConfig(vec_env="ray")
    with pytest.raises(ValueError):
        ActiveTrainConfig(repeat=0)
    with pytest.raises(ValueError):
        ActiveTrainConfig(layout_seeds=(5, 5))
    with pytest.raises(ValueError, match=r"kind-weights None"):  # says how to fix it
        ActiveTrainConfig(kind_weights=(1.0,))
    with pytest.raises(ValueError, match="unknown ActiveObservation"):
        ActiveTrainConfig(observation={"ego_pixels": 3})
    # caught here, not as a torch error after the logs are written or inside the env workers
    for bad, match in [
        ({"gamma": float("nan")}, "gamma"),
        ({"learning_rate": -1.0}, "learning_rate"),
        ({"vf_coef": float("inf")}, "vf_coef"),
        ({"device": "bogus"}, "device"),
        ({"kinds": ("nosuch",), "kind_weights": (1.0,)}, "kinds"),
        ({"kinds": (), "files": ("/no/such/layout.json",), "kind_weights": None}, "layout"),
        ({"env_id": "SemReloc-v1"}, "env_id"),  # the flat observation: ActiveObservation needs v2 or newer
        ({"env_id": "SemSlam-v2"}, "env_id"),
        ({"n_steps": 1, "n_envs": 1, "batch_size": 1}, r"n_steps \* n_envs"),  # SB3's AssertionError before
        # an audit's: these failed in every env worker, or in the extractor, after the run folder was made
        ({"belief_mass_weight": float("nan")}, "belief_mass_weight"),
        ({"belief_mass_weight": float("inf")}, "belief_mass_weight"),
        ({"observation": {"ego_size": 4}}, "ego_size must be at least 8"),
        ({"observation": {"global_size": 7}}, "global_size must be at least 8"),
    ]:
        with pytest.raises((ValueError, OSError), match=match):
            ActiveTrainConfig(**bad)
    if not torch.cuda.is_available():  # SB3 trained on the CPU without a word, and the run said "cuda"
        with pytest.raises(ValueError, match=r"device 'cuda': torch finds no CUDA device here"):
            ActiveTrainConfig(device="cuda")


def test_workers_give_the_training_envs_of_one_process():
    """`vec_env="workers"` splits the envs over worker processes (`agents.worker_vec_env.WorkersVecEnv`): the
    observations, rewards, dones and infos of `make_active_venv` in one process (dummy), bit for bit."""
    from agents.train_active import make_active_venv
    from agents.worker_vec_env import WorkersVecEnv

    with pytest.raises(ValueError, match="workers must be an int >= 1"):
        ActiveTrainConfig(workers=0)
    with pytest.raises(ValueError, match=r"workers must be at most n_envs \(2\), got 3"):
        ActiveTrainConfig(vec_env="workers", n_envs=2, workers=3)
    config = ActiveTrainConfig(
        kinds=("procedural",), kind_weights=None, particles=100, max_episode_steps=12, n_envs=3, vec_env="dummy"
    )
    one = make_active_venv(config)
    two = make_active_venv(dataclasses.replace(config, vec_env="workers", workers=2))
    try:
        assert isinstance(two, WorkersVecEnv) and two.workers == 2
        first = one.reset(), two.reset()
        assert all(np.array_equal(first[0][k], first[1][k]) for k in first[0])
        rng, ends = np.random.default_rng(0), 0
        for _ in range(8):  # the decisions repeat actions: episodes of 12 steps end within these
            actions = rng.integers(0, one.action_space.n, 3)
            (o1, r1, d1, i1), (o2, r2, d2, i2) = one.step(actions), two.step(actions)
            assert all(np.array_equal(o1[k], o2[k]) for k in o1)
            for info in i1 + i2:  # SB3's Monitor times its episodes: a wall-clock figure
                info.get("episode", {}).pop("t", None)
            assert np.array_equal(r1, r2) and np.array_equal(d1, d2) and repr(i1) == repr(i2)
            ends += int(d1.sum())
        assert ends >= 3
    finally:
        one.close()
        two.close()


def test_a_model_that_cannot_be_set_up_leaves_no_worker_running(monkeypatch, tmp_path):
    import multiprocessing

    import agents.train_active as ta

    def broken(config, venv):
        raise RuntimeError("no model today")

    monkeypatch.setattr(ta, "build_model", broken)
    config = ActiveTrainConfig(
        kinds=("procedural",), kind_weights=None, particles=100, n_envs=2, vec_env="workers", progress_bar=False
    )
    before = set(multiprocessing.active_children())
    with pytest.raises(RuntimeError, match="no model today"):
        train_active(config, tmp_path / "run")
    assert not set(multiprocessing.active_children()) - before


def test_training_envs_draw_layout_files(tmp_path):
    # a new user's trial: train_active could not train on one's own layout files
    from agents.train_active import make_active_env
    from semreloc_env.layouts import get_layout

    layout = get_layout("twin_rooms").to_dict()
    layout["name"] = "mine"
    (tmp_path / "mine.json").write_text(json.dumps(layout))
    config = ActiveTrainConfig(kinds=(), files=(str(tmp_path / "mine.json"),), kind_weights=None, particles=100)
    env = make_active_env(config, seed=0)
    env.reset(seed=0)
    assert env.unwrapped.layout.name == "mine"
    assert env.unwrapped.spec.id == "SemReloc-v22"  # the newest unless told
    older = make_active_env(dataclasses.replace(config, env_id="SemReloc-v10"), seed=0)
    assert older.unwrapped.spec.id == "SemReloc-v10" and older.unwrapped.mapping_run_version == "4"


def test_training_envs_take_reset_options_look_alike_kidnappings_among_them():
    """``reset_options``: every training episode resets with them (SB3 resets without options), here a tracking start
    kidnapped at step 6 to a look-alike place; a reset given options replaces them entry by entry; bad ones are
    refused when the config is made."""
    from agents.train_active import make_active_env

    opts = {"tracking": True, "kidnap_at_step": 6, "kidnap_pose": "lookalike"}
    config = ActiveTrainConfig(kinds=("procedural",), kind_weights=None, particles=100, repeat=1, reset_options=opts)
    env = make_active_env(config, seed=0)
    env.reset(seed=0)
    base = env.unwrapped
    assert base._tracking and base._kidnap_at == 6 and base._kidnap_pose == "lookalike"
    kidnapped = [env.step(3)[-1]["kidnapped"] for _ in range(6)]  # stop
    assert kidnapped == [False] * 5 + [True]
    env.reset(seed=1, options={"kidnap_at_step": 3})  # a call's own options win, entry by entry
    assert base._tracking and base._kidnap_at == 3 and base._kidnap_pose == "lookalike"
    assert json.loads(json.dumps(config.as_dict()))["reset_options"] == opts  # config.json records them
    for bad, match in (
        ({"kidnap": 5}, r"reset_options: \['kidnap'\] cannot be given to every episode"),
        ({"pose": [1.0, 1.0, 0.0]}, r"\['pose'\] cannot be given to every episode .*the layout changes"),
        ({"tracking": True, "kidnap_at_step": 500}, r"kidnap_at_step must be an int in \[1, max_episode_steps\]"),
        ({"tracking": True, "kidnap_at_step": 30, "kidnap_pose": "look-alike"}, "kidnap_pose can only be 'lookalike'"),
        ({"tracking": True, "kidnap_at_step": 30, "kidnap_pose": [1.0, 1.0, 0.0]}, "kidnap_pose can only be"),
        ({"tracking": "yes", "kidnap_at_step": 30}, "tracking must be true or false"),
        ({"tracking": True}, "a tracking start needs a kidnap_at_step"),
    ):
        with pytest.raises(ValueError, match=match):
            ActiveTrainConfig(reset_options=bad)


@pytest.fixture(scope="module")
def smoke_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("active")
    config = ActiveTrainConfig(
        env_id="SemReloc-v10",  # not the default, so that the tests see it recorded
        kinds=("procedural",),
        kind_weights=None,
        layout_seeds=(0, 2),
        particles=200,
        max_episode_steps=40,
        repeat=3,
        n_envs=2,
        vec_env="dummy",
        total_timesteps=128,
        n_steps=32,
        batch_size=32,
        n_epochs=1,
        features_dim=16,
        cnn_channels=(4, 4, 4),
        net_arch=(8,),
        checkpoint_every=64,
        progress_bar=False,
    )
    return out, train_active(config, out)


def test_ppo_smoke_run_writes_logs_checkpoints_and_a_loadable_policy(smoke_run):
    out, path = smoke_run
    assert path == out / "policy.zip"
    assert (out / "progress.csv").read_text().count("\n") >= 2
    assert list(out.glob("events.out.tfevents.*")), "no TensorBoard events"
    assert list((out / "checkpoints").glob("ppo_*_steps.zip"))
    assert (out / "learning_curve.png").stat().st_size > 0
    timing = json.loads((out / "timing.json").read_text())
    assert timing["decisions"] >= 128 and timing["env_steps_max"] == 3 * timing["decisions"]
    meta = read_metadata(path)
    assert meta["repeat"] == 3 and meta["explorer_option"] and meta["extra"]["config"]["particles"] == 200
    assert meta["extra"]["env_id"] == meta["extra"]["config"]["env_id"] == "SemReloc-v10"


def test_resume_continues_the_step_count_and_keeps_the_earlier_logs(smoke_run, tmp_path):
    import dataclasses
    import shutil

    out, _ = smoke_run
    run = tmp_path / "run"
    shutil.copytree(out, run)
    ckpt = sorted((run / "checkpoints").glob("ppo_*_steps.zip"))[0]
    config = ActiveTrainConfig(**json.loads((run / "config.json").read_text()))
    before = json.loads((run / "timing.json").read_text())["decisions"]
    train_active(dataclasses.replace(config, total_timesteps=192, checkpoint_every=None), run, resume=ckpt)
    from stable_baselines3 import PPO

    done = PPO.load(ckpt).num_timesteps
    assert (run / f"progress_before_{done}.csv").is_file() and (run / f"timing_before_{done}.json").is_file()
    assert (run / f"policy_before_{done}.zip").is_file() and (run / "policy.zip").is_file()  # both networks kept
    assert json.loads((run / f"timing_before_{done}.json").read_text())["decisions"] == before
    timing = json.loads((run / "timing.json").read_text())
    assert timing["decisions"] >= done + 192
    assert timing["decisions_this_run"] == timing["decisions"] - done  # what this run's seconds paid for
    # the resumed rows count this run's episodes only: the checkpoint's buffers used to fill rollout/*
    assert len(PPO.load(ckpt).ep_success_buffer) > 0
    with open(run / "progress.csv") as f:
        rows = list(csv.DictReader(f))
    assert rows and any(r.get("reloc/success_rate") for r in rows)
    for r in rows:
        assert r.get("rollout/success_rate", "") == r.get("reloc/success_rate", "")


def test_a_run_folder_is_never_mixed_with_another_run(smoke_run, tmp_path, capsys):
    """A new run into a used --out, a missing checkpoint, or a resume with other spaces are refused
    before any env is built; other layouts are allowed but said (a new user's trial)."""
    import dataclasses

    from agents.tools import train_active as tool
    from agents.train_active import RunFolderError, check_resume

    out, policy = smoke_run
    config = ActiveTrainConfig(**json.loads((out / "config.json").read_text()))
    with pytest.raises(RunFolderError, match="holds a training run already"):
        train_active(config, out)
    with pytest.raises(RunFolderError, match="no such checkpoint"):
        train_active(config, tmp_path / "new", resume=tmp_path / "none.zip")
    ckpt = sorted((out / "checkpoints").glob("ppo_*_steps.zip"))[0]
    assert check_resume(str(ckpt)[: -len(".zip")], config) == ckpt  # SB3 adds .zip too
    with pytest.raises(RunFolderError, match=r"options=\['explore'\].*options=\['explore', 'viewpoint'\]"):
        check_resume(ckpt, dataclasses.replace(config, options=("explore", "viewpoint")))
    with pytest.raises(RunFolderError, match="repeat"):
        check_resume(policy, dataclasses.replace(config, repeat=1))
    check_resume(ckpt, dataclasses.replace(config, observation={"ego_size": 32}))  # a default, given: the same
    lone = tmp_path / "lone"
    lone.mkdir()
    (lone / "policy.zip").write_bytes(policy.read_bytes())  # no config.json beside it: its metadata tells
    with pytest.raises(RunFolderError, match="repeat"):
        check_resume(lone / "policy.zip", dataclasses.replace(config, repeat=2))
    with pytest.raises(RunFolderError, match="holds a training run already"):  # another run's folder
        check_resume(lone / "policy.zip", config, out=out)
    assert check_resume(ckpt, config, out=out) == ckpt  # its own run's folder
    old = tmp_path / "old"  # a run saved before `options` existed: explorer_option stands for them
    (old / "checkpoints").mkdir(parents=True)
    (old / "checkpoints" / ckpt.name).write_bytes(ckpt.read_bytes())
    saved = {k: v for k, v in json.loads((out / "config.json").read_text()).items() if k not in ("options", "env_id")}
    (old / "config.json").write_text(json.dumps({**saved, "explorer_option": True}))
    assert check_resume(old / "checkpoints" / ckpt.name, config) is not None
    with pytest.raises(RunFolderError, match="options"):
        check_resume(old / "checkpoints" / ckpt.name, dataclasses.replace(config, options=()))
    capsys.readouterr()
    check_resume(ckpt, dataclasses.replace(config, kinds=("procedural_sym",)))
    assert "kinds ['procedural'] -> ['procedural_sym']" in capsys.readouterr().out
    # another env is said too, also for a run whose config.json predates the field (its policy.zip names the env)
    assert config.env_id == "SemReloc-v10"
    check_resume(ckpt, dataclasses.replace(config, env_id="SemReloc-v22"))
    assert "env_id 'SemReloc-v10' -> 'SemReloc-v22'" in capsys.readouterr().out
    (old / "policy.zip").write_bytes(policy.read_bytes())
    check_resume(old / "checkpoints" / ckpt.name, dataclasses.replace(config, env_id="SemReloc-v22"))
    assert "env_id 'SemReloc-v10' -> 'SemReloc-v22'" in capsys.readouterr().out
    check_resume(old / "checkpoints" / ckpt.name, config)
    assert "env_id" not in capsys.readouterr().out
    (old / "policy.zip").unlink()  # an interrupted run of those days: nothing records its env
    check_resume(old / "checkpoints" / ckpt.name, config)
    assert "does not record its env" in capsys.readouterr().out
    assert not (tmp_path / "new").exists()
    assert tool.main(["--out", str(out), "--config.particles", "100"]) == 2
    assert "holds a training run already" in capsys.readouterr().err
    # an outside tester's trial: a file that is no checkpoint gave a traceback after the envs were built
    (tmp_path / "notes.txt").write_text("not a checkpoint")
    with pytest.raises(RunFolderError, match="notes.txt: not a checkpoint of a training run"):
        check_resume(tmp_path / "notes.txt", config)
    argv = ["--out", str(tmp_path / "resumed"), "--resume", str(tmp_path / "notes.txt")]
    assert tool.main(argv) == 2 and not (tmp_path / "resumed").exists()
    assert "not a checkpoint of a training run" in capsys.readouterr().err


def test_resume_compares_layout_files_by_path_not_spelling(monkeypatch, tmp_path):
    """``./a.json`` and ``a.json`` (and its absolute path) are one file to a resumed run: no note."""
    from agents.train_active import _comparable

    monkeypatch.chdir(tmp_path)
    spellings = ["a.json", "./a.json", str(tmp_path / "a.json"), "sub/../a.json"]
    assert len({json.dumps(_comparable({"files": [f]})) for f in spellings}) == 1
    assert _comparable({"files": ["a.json"]}) != _comparable({"files": ["b.json"]})
    # an audit's: a DAgger run's config kept kind_weights "auto", and resuming printed "auto -> [1.0, 1.0, 2.0]"
    default = ActiveTrainConfig()
    assert _comparable({**default.as_dict(), "kind_weights": "auto"}) == _comparable(default.as_dict())
    from semreloc_env.layouts import get_layout

    (tmp_path / "x.json").write_text(json.dumps(get_layout("twin_rooms").to_dict()))
    files_only = ActiveTrainConfig(kinds=(), files=(str(tmp_path / "x.json"),), kind_weights="auto")
    assert _comparable({**files_only.as_dict(), "kind_weights": "auto"})["kind_weights"] is None


def test_kind_weights_per_kind_give_files_weight_one(tmp_path):
    from semreloc_env.layouts import get_layout

    for name in ("a", "b"):
        (tmp_path / f"{name}.json").write_text(json.dumps({**get_layout("twin_rooms").to_dict(), "name": name}))
    config = ActiveTrainConfig(files=(str(tmp_path / "a.json"), str(tmp_path / "b.json")))
    assert config._entry_weights() == [1.0, 1.0, 2.0, 1.0, 1.0]
    with pytest.raises(ValueError, match="per kind and file \\(5\\) or per kind \\(3\\)"):
        ActiveTrainConfig(files=(str(tmp_path / "a.json"), str(tmp_path / "b.json")), kind_weights=(1.0, 2.0))


def test_the_default_kind_weights_apply_only_to_the_default_kinds(tmp_path):
    # (1, 1, 2) was applied to whatever kinds and files were given: one kind and two files drew the second
    # file twice as often, and two kinds without weights failed over a setting never given
    from agents.imitation import ImitationConfig
    from agents.train_active import TRAIN_KINDS
    from semreloc_env.layouts import get_layout

    files = []
    for name in ("a", "b"):
        (tmp_path / f"{name}.json").write_text(json.dumps({**get_layout("twin_rooms").to_dict(), "name": name}))
        files.append(str(tmp_path / f"{name}.json"))
    assert ActiveTrainConfig().weights == (1.0, 1.0, 2.0) and ActiveTrainConfig().kind_weights == "auto"
    assert ActiveTrainConfig().as_dict()["kind_weights"] == (1.0, 1.0, 2.0)  # what config.json records
    one_kind = ActiveTrainConfig(kinds=("procedural",), files=tuple(files))
    assert one_kind.weights is None and one_kind.layout_sampler().config()["weights"] is None
    assert ActiveTrainConfig(kinds=("procedural", "procedural_sym")).weights is None
    assert ActiveTrainConfig(kinds=("procedural", "procedural_sym"), kind_weights=(1.0, 3.0)).weights == (1.0, 3.0)
    assert parse(ActiveTrainConfig, ["--kinds", "procedural_ring"]).weights is None
    assert parse(ActiveTrainConfig, ["--kind-weights", "None"]).weights is None
    # "auto" survives copies of a built config (a review: imitate_active's default train config kept (1, 1, 2))
    ring = dataclasses.replace(ActiveTrainConfig(), kinds=("procedural_ring",))
    assert ring.weights is None
    assert dataclasses.replace(ring, kinds=TRAIN_KINDS).weights == (1.0, 1.0, 2.0)
    assert parse(ImitationConfig, ["--train.kinds", "procedural_ring"]).train.weights is None
    with pytest.raises(ValueError, match="kind_weights"):
        ActiveTrainConfig(kind_weights="equal")


def test_loaded_policy_acts_deterministically_on_another_layout_and_particle_count(smoke_run):
    _, path = smoke_run
    runs = []
    for _ in range(2):
        policy = load_policy(path)
        env = policy.wrap(_env(layout="lab", relocalizer={"n_particles": 1500}, max_episode_steps=12))
        policy.reset()
        obs, _ = env.reset(seed=4)
        actions = []
        for _ in range(12):
            a = policy.act(obs)
            assert env.action_space.contains(a)
            actions.append(a)
            obs, *_ = env.step(a)
        runs.append(actions)
    assert runs[0] == runs[1]
    for k in range(0, 12, 3):  # one decision held for `repeat` steps
        assert len(set(runs[0][k : k + 3])) == 1


def test_load_policy_errors(smoke_run, tmp_path):
    _, path = smoke_run
    with pytest.raises(FileNotFoundError):
        load_policy(tmp_path / "missing.zip")
    (tmp_path / "junk.zip").write_text("not a zip")
    with pytest.raises(ValueError, match="not a policy zip"):
        load_policy(tmp_path / "junk.zip")
    bare = tmp_path / "bare.zip"
    with zipfile.ZipFile(path) as src, zipfile.ZipFile(bare, "w") as dst:
        for name in src.namelist():
            if name != META_NAME:
                dst.writestr(name, src.read(name))
    with pytest.raises(ValueError, match="no semreloc_policy.json.*A model of scripts/train_ppo.py is no such policy"):
        load_policy(bare)
    # an outside tester's trial: wrapping twice said the action space was wrong
    policy = load_policy(path)
    once = policy.wrap(gym.make("SemReloc-v22", layout="twin_rooms", map_source="perfect"))
    with pytest.raises(ValueError, match="own observations.*wrapped by ActiveObservation already"):
        policy.wrap(once)
    # an eleventh tester's: an env that repeats actions already made each decision last repeat x repeat steps
    with pytest.raises(ValueError, match=r"ActionRepeat\(repeat=4\).*each would last"):
        policy.wrap(ActionRepeat(gym.make("SemReloc-v22", layout="twin_rooms", map_source="perfect"), 4))
    for name, meta, keep_model, match in [
        ("badjson.zip", "{nope", True, "not valid JSON"),
        ("list.zip", "[1]", True, "JSON object"),
        ("fmtonly.zip", '{"format": 1}', True, "lacks"),
        ("nomodel.zip", None, False, "not a loadable"),
        ("badweights.zip", None, "policy.pth", "not a loadable.*UnpicklingError"),  # an audit: came out raw
    ]:
        broken = tmp_path / name
        with zipfile.ZipFile(path) as src, zipfile.ZipFile(broken, "w") as dst:
            for member in src.namelist():
                if member == META_NAME:
                    dst.writestr(member, src.read(member) if meta is None else meta)
                elif keep_model == member:
                    dst.writestr(member, b"garbage, not torch's pickle")
                elif keep_model:
                    dst.writestr(member, src.read(member))
        with pytest.raises(ValueError, match=match):
            load_policy(broken)
    with pytest.raises(ValueError, match="device"):
        load_policy(path, device="bogus")
    from_bare = load_policy(bare, observation={}, repeat=3)  # explore action inferred from Discrete(5)
    assert from_bare.repeat == 3 and from_bare.explorer_option
    from_bare.wrap(_env())
    policy = load_policy(path)
    with pytest.raises(ValueError, match=r"observation space differs.*'semantic_class': env MultiDiscrete\(16,\)"):
        policy.wrap(_env(camera={"n_beams": 16}))  # says what differs, not the whole of both spaces
    policy.wrap(_env(action_type="continuous"))  # its options send (v, omega)
    with pytest.raises(ValueError, match="action space"):
        policy.wrap(gym.wrappers.RescaleAction(_env(action_type="continuous"), np.float32(-2), np.float32(2)))


def test_evaluate_active_runs_a_learned_policy_and_reuses_earlier_rows(smoke_run, tmp_path):
    _, path = smoke_run
    common = ["--layouts-per-kind", "0", "--starts", "1", "--max-steps", "6", "--particles", "100"]
    common += ["--map-source", "perfect", "--workers", "1", "--no-progress"]
    ev.main([*common, "--policies", "spin", "--out", str(tmp_path / "a")])
    ev.main(
        [*common, "--policies", "spin", f"ppo={path}", "--reuse", str(tmp_path / "a"), "--out", str(tmp_path / "b")]
    )
    a = json.loads((tmp_path / "a" / "episodes.json").read_text())
    b = json.loads((tmp_path / "b" / "episodes.json").read_text())
    assert [r for r in b if r["policy"] == "spin"] == a
    assert sum(r["policy"] == "ppo" for r in b) == len(a) == 3
    (cmp,) = json.loads((tmp_path / "b" / "summary.json").read_text())["paired"]
    assert cmp["policy"] == "ppo" and cmp["against"] == "spin" and 0 <= cmp["mcnemar_p"] <= 1
    assert "paired" in (tmp_path / "b" / "table.md").read_text()
    # rows made with other settings are run again, not reused
    other = [x if x != "100" else "120" for x in common]
    ev.main([*other, "--policies", "spin", "--reuse", str(tmp_path / "a"), "--out", str(tmp_path / "c")])
    c = json.loads((tmp_path / "c" / "episodes.json").read_text())
    assert {r["settings"]["particles"] for r in c} == {120}
    # sampled actions are seeded per episode: two runs give the same rows
    sampled = [[*common, "--policies", f"ppo={path}", "--sample-learned", "--out", str(tmp_path / d)] for d in "de"]
    for argv in sampled:
        ev.main(argv)
    d, e = (json.loads((tmp_path / x / "episodes.json").read_text()) for x in "de")
    strip = [[{k: v for k, v in r.items() if k != "seconds"} for r in rows] for rows in (d, e)]
    assert strip[0] == strip[1] and all(r["settings"]["sample_learned"] for r in d)
    with pytest.raises(SystemExit):
        ev.main(["--policies", f"ppo={tmp_path / 'nope.zip'}"])
    # an outside tester's trial: a saved policy whose spaces do not fit the env failed in the first episode,
    # with a traceback, and lost the other policies' episodes; now it is refused before any episode
    other = tmp_path / "other.zip"
    with zipfile.ZipFile(path) as src, zipfile.ZipFile(other, "w") as dst:
        for member in src.namelist():
            meta = json.loads(src.read(member)) if member == META_NAME else None
            if meta is not None:
                meta["observation"] = {**meta["observation"], "ego_size": 48}
            dst.writestr(member, src.read(member) if meta is None else json.dumps(meta))
    assert ev.main([*common, "--policies", "spin", f"other={other}", "--out", str(tmp_path / "f")]) == 2
    assert not (tmp_path / "f").exists()


def test_shipped_policy_loads_and_acts():
    assert SHIPPED_POLICY.is_file(), "agents/data/active_ppo.zip is missing (package data)"
    assert SHIPPED_POLICY.stat().st_size <= 10 * 2**20
    policy = load_policy(SHIPPED_POLICY)
    env = policy.wrap(_env(layout="procedural_lookalike", layout_seed=7, max_episode_steps=8))
    policy.reset()
    obs, _ = env.reset(seed=0)
    for _ in range(8):
        a = policy.act(obs)
        assert env.action_space.contains(a)
        obs, *_ = env.step(a)
    # and it localizes: the README's example episode (twin rooms, seed 0) succeeds
    env = policy.wrap(_env(layout="twin_rooms", max_episode_steps=200))
    policy.reset()
    obs, info = env.reset(seed=0)
    while True:
        obs, _, terminated, truncated, info = env.step(policy.act(obs))
        if terminated or truncated:
            break
    assert info["is_success"]
    # with continuous actions too (its options send (v, omega); the planner drives arcs)
    env = policy.wrap(_env(layout="twin_rooms", action_type="continuous", max_episode_steps=200))
    assert env.action_space == gym.spaces.Discrete(6)
    policy.reset()
    obs, info = env.reset(seed=0)
    while True:
        obs, _, terminated, truncated, info = env.step(policy.act(obs))
        assert env.unwrapped.action_space.contains(info.get("option_action", np.zeros(2, np.float32)))
        if terminated or truncated:
            break
    assert info["is_success"]
    raw, _ = _env().reset(seed=0)
    policy.reset()  # a new decision is due: it reads the observation
    with pytest.raises(ValueError, match="policy.wrap"):  # the raw env's observation, not the wrapped one
        policy.act(raw)


def test_explorer_option_steps_as_the_explorer_and_checks_its_actions():
    from agents.baselines import WallFollowExplorer
    from agents.options import EXPLORE, ExplorerOption

    env = ExplorerOption(_env(max_episode_steps=60))
    ref, explorer = _env(max_episode_steps=60), WallFollowExplorer()
    obs, _ = env.reset(seed=2)
    ref_obs, _ = ref.reset(seed=2)
    for _ in range(40):
        a = explorer(ref_obs)
        ref_obs, *_ = ref.step(a)
        obs, _, _, _, info = env.step(EXPLORE)
        assert info["option_action"] == a
        np.testing.assert_array_equal(obs["lidar"], ref_obs["lidar"])
    for bad in (5, -1, 1.5, True, "0"):
        with pytest.raises(ValueError):
            env.step(bad)
    with pytest.raises(TypeError, match="action space"):  # a Box of other bounds is not a SemReloc one
        ExplorerOption(gym.wrappers.RescaleAction(_env(action_type="continuous"), np.float32(-2), np.float32(2)))


def test_options_over_continuous_actions_send_the_same_motions():
    # forward / turns as (1, 0) / (0, +-1) drive exactly as the discrete actions do, so the
    # explorer's episode is the same bit for bit; stop is (0, 0)
    from agents.options import EXPLORE, ExplorerOption

    disc, cont = ExplorerOption(_env()), ExplorerOption(_env(action_type="continuous"))
    assert disc.action_space == cont.action_space == gym.spaces.Discrete(5)
    d_obs, _ = disc.reset(seed=4)
    c_obs, _ = cont.reset(seed=4)
    for a in [EXPLORE] * 20 + [0, 1, 2, 3] + [EXPLORE] * 10:
        d_obs, _, _, _, d_info = disc.step(a)
        c_obs, _, _, _, c_info = cont.step(a)
        np.testing.assert_array_equal(d_obs["lidar"], c_obs["lidar"])
        np.testing.assert_array_equal(d_info["pose"], c_info["pose"])
        if a == EXPLORE:
            expected = {0: [1, 0], 1: [0, 1], 2: [0, -1], 3: [0, 0]}[d_info["option_action"]]
            np.testing.assert_array_equal(c_info["option_action"], expected)


def test_viewpoint_option_over_continuous_actions_is_the_planner_driving_arcs():
    from agents.options import MotionOptions
    from agents.viewpoint import ViewpointPlanner

    env = MotionOptions(_env(action_type="continuous", max_episode_steps=60), ("explore", "viewpoint"))
    ref, planner = _env(action_type="continuous", max_episode_steps=60), ViewpointPlanner(seed=4)
    planner.wrap(ref)
    planner.reset()
    obs, _ = env.reset(seed=4)  # an episode of 22 steps, 12 of them arcs (v21)
    ref_obs, _ = ref.reset(seed=4)
    arcs = 0
    for _ in range(60):
        a = planner.act(ref_obs)
        ref_obs, _, term, trunc, _ = ref.step(a)
        obs, _, _, _, info = env.step(5)
        np.testing.assert_array_equal(info["option_action"], a)
        np.testing.assert_array_equal(obs["lidar"], ref_obs["lidar"])
        arcs += bool(a[0] > 0 and a[1] != 0)
        if term or trunc:
            break
    assert arcs > 0, "the planner never drove an arc: the test did not test continuous actions"


def test_viewpoint_option_steps_as_the_planner_even_between_other_actions():
    from agents.options import MotionOptions
    from agents.viewpoint import ViewpointPlanner

    env = MotionOptions(_env(max_episode_steps=80), ("explore", "viewpoint"))
    assert env.action_space.n == 6
    ref, planner = _env(max_episode_steps=80), ViewpointPlanner(seed=3)
    planner.wrap(ref)
    planner.reset()
    obs, _ = env.reset(seed=3)  # the planner follows a path within the episode (v21)
    ref_obs, _ = ref.reset(seed=3)
    planner.observe(ref_obs)
    # the planner drives until it follows a path, the policy then turns twice, the planner resumes:
    # it must have seen the turns in its odometry (same pose along its path as the reference's)
    turns, steps = 0, 0
    while steps < 60:
        following = env.planner._path.shape[0] > 0 and not env.planner._exploring
        if following and turns < 2:
            a, action, turns = 1, 1, turns + 1
        else:
            a, action = planner.decide(ref_obs), 5
        ref_obs, *_ = ref.step(a)
        planner.observe(ref_obs)
        obs, _, term, trunc, info = env.step(action)
        steps += 1
        assert info.get("option_action", a) == a
        np.testing.assert_array_equal(obs["lidar"], ref_obs["lidar"])
        np.testing.assert_array_equal(env.planner._pose, planner._pose)
        if term or trunc:
            break
    assert turns == 2, "the planner never followed a path: the test did not test anything"
    with pytest.raises(ValueError, match="options"):
        MotionOptions(_env(), ("explore", "explore"))
    with pytest.raises(ValueError, match="options"):
        MotionOptions(_env(), ("teleport",))


def test_bare_checkpoints_take_their_options_from_the_run(tmp_path):
    import json

    from gymnasium import spaces

    from agents.learned import _checkpoint_options

    ckpt = tmp_path / "run" / "checkpoints" / "ppo_512_steps.zip"
    ckpt.parent.mkdir(parents=True)
    assert _checkpoint_options(ckpt, spaces.Discrete(5)) == ("explore",)  # old runs: the explorer
    assert _checkpoint_options(ckpt, spaces.Discrete(4)) == ()
    with pytest.raises(ValueError, match="options"):
        _checkpoint_options(ckpt, spaces.Discrete(6))  # no record: refuse to guess the order
    (tmp_path / "run" / "config.json").write_text(json.dumps({"options": ["viewpoint", "explore"]}))
    assert _checkpoint_options(ckpt, spaces.Discrete(6)) == ("viewpoint", "explore")
    (tmp_path / "run" / "config.json").write_text(json.dumps({"explorer_option": True}))
    assert _checkpoint_options(ckpt, spaces.Discrete(5)) == ("explore",)


def test_a_bare_checkpoint_of_a_run_takes_its_repeat_and_observation_from_the_run(smoke_run, tmp_path):
    """An eleventh tester's: a bare checkpoint needed repeat and observation passed by hand, and any value was
    taken; in a run's checkpoints/ folder they now come from the run's config.json unless given."""
    import json

    _, path = smoke_run
    ckpt = tmp_path / "run" / "checkpoints" / "ppo_512_steps.zip"
    ckpt.parent.mkdir(parents=True)
    with zipfile.ZipFile(path) as src, zipfile.ZipFile(ckpt, "w") as dst:
        for name in src.namelist():
            if name != META_NAME:
                dst.writestr(name, src.read(name))
    with pytest.raises(ValueError, match="no semreloc_policy.json"):
        load_policy(ckpt)  # no record of the run either
    saved = read_metadata(path)
    config = {"repeat": 3, "observation": saved["observation"], "options": saved.get("options", [])}
    (tmp_path / "run" / "config.json").write_text(json.dumps(config))
    policy = load_policy(ckpt)
    assert policy.repeat == 3 and policy.observation == saved["observation"]
    assert load_policy(ckpt, repeat=2).repeat == 2  # an explicit override still wins
    policy.wrap(_env())
    # a seventeenth tester's: evaluate_active refused what load_policy(path) loads, pointing at train_ppo.py
    from agents.experiments.evaluate_active import Args

    Args(policies=(f"ck={ckpt}",), layouts_per_kind=1)
    (tmp_path / "run" / "config.json").unlink()
    with pytest.raises(ValueError, match=r"policies: ck=.*save_policy\(policy.model"):
        Args(policies=(f"ck={ckpt}",), layouts_per_kind=1)


def test_a_policy_of_continuous_actions_wraps_a_continuous_env(tmp_path):
    # a review found wrap putting the four-action mapping in front of every Box env, so a policy
    # trained on continuous actions could no longer be wrapped on its own kind of env
    from stable_baselines3 import PPO

    from agents.learned import save_policy

    train_env = ActiveObservation(_env(action_type="continuous"))
    model = PPO("MultiInputPolicy", train_env, n_steps=16, batch_size=16, seed=0,
                policy_kwargs={"features_extractor_class": ActiveExtractor,
                               "features_extractor_kwargs": {"features_dim": 16, "cnn_channels": (4, 4, 4)},
                               "net_arch": [8]})  # fmt: skip
    path = save_policy(model, tmp_path / "box.zip", observation={}, repeat=1)
    policy = load_policy(path)
    env = policy.wrap(_env(action_type="continuous"))
    assert isinstance(env.action_space, gym.spaces.Box)
    policy.reset()
    obs, _ = env.reset(seed=0)
    a = np.asarray(policy.act(obs), dtype=np.float32)
    assert env.action_space.contains(a)  # SB3 clips a Box policy's actions to the space
    env.step(a)


def test_a_model_trained_through_vec_normalize_is_refused(tmp_path):
    """An outside audit: such a model saved silently and then acted on raw observations, its normalisation's
    statistics gone."""
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    from agents.learned import LearnedPolicy, save_policy

    venv = VecNormalize(DummyVecEnv([lambda: ActiveObservation(_env())]), norm_obs_keys=["lidar"])
    model = PPO("MultiInputPolicy", venv, n_steps=16, batch_size=16, seed=0,
                policy_kwargs={"features_extractor_class": ActiveExtractor,
                               "features_extractor_kwargs": {"features_dim": 16, "cnn_channels": (4, 4, 4)},
                               "net_arch": [8]})  # fmt: skip
    with pytest.raises(ValueError, match="VecNormalize"):
        save_policy(model, tmp_path / "norm.zip", observation={}, repeat=1)
    assert not (tmp_path / "norm.zip").exists()
    with pytest.raises(ValueError, match="VecNormalize"):
        LearnedPolicy(model, {}, 1)
    venv.close()


def test_a_policy_of_another_algorithm_loads_with_its_own_class(tmp_path):
    # an outside tester's trial: a DQN saved with save_policy failed in PPO.load with a traceback
    from stable_baselines3 import DQN

    from agents.learned import save_policy

    model = DQN("MultiInputPolicy", ActiveObservation(_env()), buffer_size=16, learning_starts=0, seed=0,
                policy_kwargs={"features_extractor_class": ActiveExtractor,
                               "features_extractor_kwargs": {"features_dim": 16, "cnn_channels": (4, 4, 4)},
                               "net_arch": [8]})  # fmt: skip
    path = save_policy(model, tmp_path / "dqn.zip", observation={}, repeat=2)
    assert read_metadata(path)["algorithm"] == "DQN"
    policy = load_policy(path)
    assert isinstance(policy.model, DQN)
    env = policy.wrap(_env())
    policy.reset()
    obs, _ = env.reset(seed=0)
    assert env.action_space.contains(policy.act(obs))
    with pytest.raises(ValueError, match="DQN policy has none"):  # sampling needs an action distribution
        load_policy(path, deterministic=False)
    other = tmp_path / "other.zip"
    with zipfile.ZipFile(path) as src, zipfile.ZipFile(other, "w") as dst:
        for member in src.namelist():
            meta = {**json.loads(src.read(member)), "algorithm": "MyAlgo"} if member == META_NAME else None
            dst.writestr(member, src.read(member) if meta is None else json.dumps(meta))
    with pytest.raises(ValueError, match=r"algorithm 'MyAlgo' is none of stable-baselines3's.*LearnedPolicy\(model"):
        load_policy(other)


def test_resume_never_overwrites_an_earlier_run_and_keeps_the_checkpoints_settings(smoke_run, tmp_path, capsys):
    # a new user's trial: resuming twice from one checkpoint replaced the first run's *_before_* files,
    # resuming with checkpoints rewrote the run's later ones, and PPO settings given on resume were
    # ignored while config.json recorded them
    import dataclasses
    import shutil

    from agents.train_active import RunFolderError

    out, _ = smoke_run
    run = tmp_path / "run"
    shutil.copytree(out, run)
    ckpt = run / "checkpoints" / "ppo_64_steps.zip"  # 128 exists too
    config = ActiveTrainConfig(**json.loads((run / "config.json").read_text()))
    files = {f: f.read_bytes() for f in run.rglob("*") if f.is_file() and "events" not in f.name}
    with pytest.raises(RunFolderError, match=r"would overwrite ppo_128_steps.zip"):
        train_active(dataclasses.replace(config, total_timesteps=64), run, resume=ckpt)
    assert {f: f.read_bytes() for f in files} == files  # nothing moved or written
    given = dataclasses.replace(config, total_timesteps=32, checkpoint_every=None, learning_rate=0.01, net_arch=(64,))
    capsys.readouterr()
    train_active(given, run, resume=ckpt)
    note = capsys.readouterr().out
    assert "keeps its own PPO and network settings" in note and "learning_rate 0.0003 (given 0.01)" in note
    recorded = json.loads((run / "config.json").read_text())
    assert recorded["learning_rate"] == 3e-4 and recorded["net_arch"] == [8]
    with pytest.raises(RunFolderError, match=r"would overwrite progress_before_64.csv"):
        train_active(given, run, resume=ckpt)  # again from the same checkpoint
    train_active(given, tmp_path / "branch", resume=ckpt)  # into a new folder: fine


def test_a_bare_checkpoint_kept_outside_its_run_is_checked_against_the_runs_spaces(smoke_run, tmp_path):
    """An outside audit: such a checkpoint resumed with other options failed in SB3 with a traceback (and a dump of
    both spaces) after the new run's folder was made."""
    import dataclasses
    import shutil

    from agents.train_active import RunFolderError, check_resume

    out, _ = smoke_run
    alone = tmp_path / "ppo_64_steps.zip"
    shutil.copy(out / "checkpoints" / "ppo_64_steps.zip", alone)
    config = ActiveTrainConfig(**json.loads((out / "config.json").read_text()))
    assert check_resume(alone, config, tmp_path / "new") == alone  # the same options: fine
    other = dataclasses.replace(config, options=("explore", "viewpoint"))
    with pytest.raises(RunFolderError, match=r"space.* differ.*checkpoint Discrete\(5\), run Discrete\(6\)"):
        check_resume(alone, other, tmp_path / "new")
    assert not (tmp_path / "new").exists()


def test_loading_a_policy_leaves_the_global_generators_as_they_were(smoke_run):
    """An outside audit: load_policy reset Python's, NumPy's and torch's global streams to the model's training seed
    (SB3's load), against the docstring's word."""
    import random

    _, path = smoke_run
    random.seed(999), np.random.seed(999), torch.manual_seed(999)  # noqa: NPY002 - the global streams, on purpose
    expected = (random.random(), np.random.random(), torch.rand(1).item())  # noqa: NPY002
    random.seed(999), np.random.seed(999), torch.manual_seed(999)  # noqa: NPY002
    load_policy(path)
    assert (random.random(), np.random.random(), torch.rand(1).item()) == expected  # noqa: NPY002


def test_a_resumed_run_is_seeded_by_its_config(smoke_run, tmp_path):
    """An outside audit: SB3's load reseeded the envs and torch with the checkpoint's seed, so --config.seed was
    ignored on --resume while config.json recorded it."""
    import dataclasses

    out, _ = smoke_run
    ckpt = out / "checkpoints" / "ppo_64_steps.zip"
    config = ActiveTrainConfig(**json.loads((out / "config.json").read_text()))
    weights = []
    for seed in (0, 7):
        run = dataclasses.replace(config, total_timesteps=32, checkpoint_every=None, seed=seed)
        path = train_active(run, tmp_path / f"s{seed}", resume=ckpt)
        assert json.loads((tmp_path / f"s{seed}" / "config.json").read_text())["seed"] == seed
        weights.append([p.detach().clone() for p in load_policy(path).model.policy.parameters()])
    assert any(not torch.equal(a, b) for a, b in zip(*weights))


def test_a_sampling_policy_draws_from_its_own_generator():
    """``deterministic=False``: actions come from the policy's seeded generator, so a robot's episode does
    not change when another sampling policy acts in the same process, and `reset` leaves torch's,
    NumPy's and Python's global streams alone (SB3's ``set_random_seed`` reseeded all three)."""
    import random

    def make(seed):
        p = load_policy(SHIPPED_POLICY, deterministic=False, seed=seed)
        return p, p.wrap(_env(layout="three_rooms", max_episode_steps=25))

    def run(interleave: bool) -> list[int]:
        (pa, ea), (pb, eb) = make(5), make(6)
        pa.reset()
        pb.reset()
        oa, _ = ea.reset(seed=3)
        ob, _ = eb.reset(seed=4)
        acts = []
        for _ in range(25):
            a = pa.act(oa)
            acts.append(int(a))
            oa, _, te, tr, _ = ea.step(a)
            if interleave:
                ob, *_ = eb.step(pb.act(ob))
            if te or tr:
                break
        return acts

    assert run(False) == run(True)
    p = load_policy(SHIPPED_POLICY, deterministic=False, seed=5)
    # the global streams themselves are what this checks
    torch.manual_seed(1), np.random.seed(1), random.seed(1)  # noqa: NPY002
    before = (torch.rand(1).item(), np.random.random(), random.random())  # noqa: NPY002
    torch.manual_seed(1), np.random.seed(1), random.seed(1)  # noqa: NPY002
    p.reset()
    assert (torch.rand(1).item(), np.random.random(), random.random()) == before  # noqa: NPY002


@pytest.mark.parametrize("space", ["discrete", "multi_discrete", "box"])
def test_sample_action_follows_the_models_distribution(space):
    from stable_baselines3 import PPO

    from agents.learned import sample_action

    act_space = {
        "discrete": gym.spaces.Discrete(3),
        "multi_discrete": gym.spaces.MultiDiscrete([2, 3]),
        "box": gym.spaces.Box(-1.0, 1.0, (2,), np.float32),
    }[space]

    class Toy(gym.Env):
        observation_space = gym.spaces.Box(-1.0, 1.0, (2,), np.float32)
        action_space = act_space

    model = PPO("MlpPolicy", Toy(), seed=0, device="cpu", policy_kwargs={"log_std_init": -1.0})
    obs = np.array([0.3, -0.2], np.float32)
    rng = np.random.default_rng(0)
    draws = np.array([sample_action(model, obs, rng) for _ in range(4000)])
    assert all(act_space.contains(np.asarray(d, dtype=act_space.dtype).reshape(act_space.shape)) for d in draws[:50])
    obs_t, _ = model.policy.obs_to_tensor(obs)
    with torch.no_grad():
        dist = model.policy.get_distribution(obs_t)
    if space == "box":
        mean = dist.distribution.mean[0].numpy()
        std = dist.distribution.stddev[0].numpy()
        assert np.allclose(draws.mean(axis=0), np.clip(mean, -1, 1), atol=0.02)
        assert np.allclose(draws.std(axis=0), std, rtol=0.1)  # exp(-1) = 0.37: clipping is rare near 0
    else:
        parts = dist.distribution if space == "multi_discrete" else [dist.distribution]
        cols = draws.reshape(len(draws), -1)
        for k, part in enumerate(parts):
            probs = part.probs[0].numpy()
            freq = np.bincount(cols[:, k], minlength=probs.size) / len(draws)
            assert np.allclose(freq, probs, atol=0.03)
    rng_a, rng_b = np.random.default_rng(7), np.random.default_rng(7)
    assert all(np.array_equal(sample_action(model, obs, rng_a), sample_action(model, obs, rng_b)) for _ in range(5))


def test_a_sampling_policy_refuses_a_state_dependent_exploration_model():
    from stable_baselines3 import PPO

    from agents.learned import LearnedPolicy

    class Toy(gym.Env):
        observation_space = gym.spaces.Box(-1.0, 1.0, (2,), np.float32)
        action_space = gym.spaces.Box(-1.0, 1.0, (2,), np.float32)

    model = PPO("MlpPolicy", Toy(), seed=0, device="cpu", use_sde=True)
    with pytest.raises(ValueError, match="use_sde"):
        LearnedPolicy(model, {}, deterministic=False)
    assert LearnedPolicy(model, {}, deterministic=True).deterministic
