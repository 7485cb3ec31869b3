"""The soak command's own parts: settings it draws are accepted, memory growth is caught, ids are checked."""

import math

import gymnasium as gym
import numpy as np
import pytest

import semreloc_env
from semreloc_env.tools import soak


@pytest.mark.parametrize("env_id", ["SemReloc-v22", "SemReloc-v1", "SemSlam-v2", "SemSlam-v0"])
def test_random_settings_are_accepted_by_their_env(env_id):
    rng = np.random.default_rng(3)
    for _ in range(4):
        got, kw = soak.random_settings(rng, (env_id,))
        assert got == env_id
        kw["map_source"] = "perfect" if "map_source" in kw else None  # no mapping run in a unit test
        kw = {k: v for k, v in kw.items() if v is not None}
        env = gym.make(env_id, layout="twin_rooms", max_episode_steps=3, **kw)
        env.reset(seed=0)
        env.step(env.action_space.sample())
        env.close()


def test_random_settings_draw_every_listed_id_and_vary_the_relocalizer():
    rng = np.random.default_rng(0)
    draws = [soak.random_settings(rng, ("SemReloc-v22", "SemSlam-v2")) for _ in range(60)]
    assert {i for i, _ in draws} == {"SemReloc-v22", "SemSlam-v2"}
    reloc = [kw for i, kw in draws if i == "SemReloc-v22"]
    assert {kw["map_source"] for kw in reloc} == {"mapping", "perfect"}
    assert {kw["relocalizer"]["backend"] for kw in reloc} == {"numba", "numpy"}


def test_memory_growth_compares_late_with_early_after_warm_up():
    flat = [(k, 100.0) for k in range(0, 1001, 10)]
    assert soak.memory_growth_mb(flat, 1000) == 0.0
    growing = [(k, 100.0 + k / 10) for k in range(0, 1001, 10)]  # 0.1 MB per step
    assert soak.memory_growth_mb(growing, 1000) == pytest.approx(95.0 - 30.0)
    warm_up_only = [(k, 500.0 if k < 200 else 100.0) for k in range(0, 1001, 10)]
    assert soak.memory_growth_mb(warm_up_only, 1000) == 0.0
    assert soak.memory_growth_mb([(0, 1.0), (1000, 2.0)], 1000) is None  # no sample after the warm-up


def test_soak_fails_on_resident_growth(monkeypatch):
    grown = iter(range(10**6))
    monkeypatch.setattr(soak, "resident_mb", lambda: 100.0 + 50.0 * next(grown))
    c = soak.soak(60, seed=1, episode_steps=5, twin_every=1000, env_ids=("SemSlam-v2",), growth_limit_mb=10.0)
    assert c["steps"] >= 60 and c["FAIL_crash"] == 0
    assert c["resident_growth_mb"] > 10 and c["FAIL_memory_growth"] == 1
    monkeypatch.setattr(soak, "resident_mb", lambda: 100.0)
    c = soak.soak(60, seed=1, episode_steps=5, twin_every=1000, env_ids=("SemSlam-v2",), growth_limit_mb=10.0)
    assert c["resident_growth_mb"] == 0 and c["FAIL_memory_growth"] == 0


def test_soak_without_resident_size_says_the_check_was_skipped(monkeypatch):
    monkeypatch.setattr(soak, "resident_mb", lambda: None)
    c = soak.soak(20, seed=2, episode_steps=5, twin_every=1000, env_ids=("SemSlam-v2",), growth_limit_mb=1.0)
    assert c["memory_check_skipped"] == 1 and c["FAIL_memory_growth"] == 0


@pytest.mark.parametrize(
    "argv, needle",
    [
        (["--env-ids", "SemReloc-v99"], "SemReloc-v99"),
        (["--env-ids", "SemRelocVec-v22"], "SemRelocVec-v22"),
        (["--env-ids", "SemSlam-v2", "SemSlam-v2"], "twice"),
        (["--memory-growth-mb", "0"], "memory_growth_mb"),
        (["--memory-growth-mb", "nan"], "memory_growth_mb"),
    ],
)
def test_bad_options_are_refused(argv, needle, capsys):
    with pytest.raises(SystemExit) as e:
        soak.main(argv)
    assert e.value.code == 2
    assert needle in capsys.readouterr().err


def test_a_short_soak_of_the_newest_ids_passes_and_leaves_the_cache_untouched(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("SEMRELOC_CACHE_DIR", str(tmp_path))
    assert soak.main(["--steps", "150", "--seed", "5", "--episode-steps", "30"]) == 0
    out = capsys.readouterr().out
    assert "RESULT ok: no failure" in out
    assert int(out.split("mapping_runs")[1].split()[0]) >= 1  # seed 5 draws mapped maps: 3 of 11 episodes
    assert not any(tmp_path.iterdir())  # the soak's maps went to its own temporary cache
    assert semreloc_env.maps.cache_dir() == tmp_path.absolute() / "maps"  # the variable is restored


def test_the_default_ids_are_the_newest():
    assert soak.Args().env_ids == ("SemReloc-v22", "SemSlam-v2")
    assert all(i in semreloc_env.ENV_IDS for i in soak.Args().env_ids)
    assert math.isfinite(soak.Args().memory_growth_mb)


def test_reset_options_draw_global_tracking_and_kidnapped_starts_within_the_limit():
    rng = np.random.default_rng(4)
    draws = [soak.reset_options(rng, "SemReloc-v22", 7) for _ in range(90)]
    assert {d["kind"] for d in draws} == {"global", "tracking", "kidnap"}
    for d in draws:
        assert d.get("tracking", False) == (d["kind"] != "global")
        assert ("kidnap_at_step" in d) == (d["kind"] == "kidnap") and 1 <= d.get("kidnap_at_step", 1) <= 7
    assert soak.reset_options(rng, "SemSlam-v2", 7) == {}


def test_a_soak_of_the_relocalizer_alone_starts_every_way_and_passes(capsys):
    assert soak.main(["--steps", "400", "--seed", "6", "--episode-steps", "40", "--env-ids", "SemReloc-v22"]) == 0
    out = capsys.readouterr().out
    counts = {k: int(v) for k, v in (line.split()[:2] for line in out.splitlines() if line.startswith("starts_"))}
    assert set(counts) == {"starts_global", "starts_tracking", "starts_kidnap"}, out
