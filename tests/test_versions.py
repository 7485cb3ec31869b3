"""The registered ids behave as their Version History says: SemReloc-v22 (v21 whose odometry and motion model move a
step under 1 cm in its own direction and whose KLD sampling draws one sequence), SemReloc-v21 (v20 whose relocalizer
does less work: half the particles at a global start, no noise drawn for a still step),
SemReloc-v20 (v19 whose belief between updates is the last update's carried by the odometry), SemReloc-v19 (v18
whose wheel odometry reads no slide
along a wall, whose KLD sampling allows three times the error and whose remembered places follow the odometry),
SemReloc-v18 (v17 whose audit after a lost hold judges
only the scans since it faded), SemReloc-v17 (v16 whose tracking start holds its pose),
SemReloc-v16 (v15 whose audit also follows a held
convergence lost without a surprise), SemReloc-v15 (v14 whose audit after a surprise turns off once it clears),
SemReloc-v14 (v13 with a surprise test of the camera's own), SemReloc-v13 (v12 whose surprise test keeps its own
average), SemReloc-v12 (v11 with maps from a drive that also enters narrow passages), SemReloc-v11 (v10 with maps
whose space beyond the lidar's returns is cleared by its beams without a return), SemReloc-v10 (v9 with maps without
stray class cells and a screen pause that follows the place), SemReloc-v9 (v8 whose convergence audit also screens
the whole map), SemReloc-v8 (v7 with the maps of the mapping run's version 3), SemReloc-v7 (v6's relocalizer whose
convergence audit searches more places and comes before "converged"), SemReloc-v6 (v5's relocalizer whose belief
holds a convergence), SemReloc-v5 (v4's relocalizer with the convergence audit), SemReloc-v4 (v3's relocalizer with
evidence from objects not seen), SemReloc-v3 (v2 with lookalike layouts that break their half turn), SemReloc-v2 /
SemSlam-v1 (typed observation, not-computed info values left out) against SemReloc-v1 / SemSlam-v0 (flat
observation, None)."""

import dataclasses
import math
import warnings
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import semreloc_env
from semreloc_env.envs.spaces import semantic_parts
from semreloc_env.layouts import CLASS_NAMES, get_layout
from semreloc_env.observations import ActiveObservation

DOCS_LAYOUTS = Path(__file__).resolve().parents[1] / "docs" / "layouts"
FAST = {"map_source": "perfect", "relocalizer": {"n_particles": 300}}
SLAM_FAST = {"slam": {"n_particles": 20}}
START = {"pose": [2.0, 5.0, 0.0]}  # lab: objects in the camera's view within a few steps
SLAM_START = {"pose": [2.0, 5.0, 1.5707963267948966]}  # lab: no object in view at first
ACTIONS = [3, 0, 0, 1, 1, 3, 0, 2, 0, 0, 3, 1, 0, 0, 2, 3]  # 3 = stop: the motion gate skips that update


def make(env_id, **kw):
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=".*out of date.*", category=DeprecationWarning)
        return gym.make(env_id, **kw)


def rollout(env, seed=4, options=START, actions=ACTIONS):
    obs, info = env.reset(seed=seed, options=options)
    out = [(obs, 0.0, False, False, info)]
    for a in actions:
        out.append(env.step(a))
    return out


def assert_one_option_apart(new: str, old: str, **option) -> None:
    """``new``'s relocalizer is ``old``'s with ``option`` set (which ``old`` does not have), on maps of the same
    mapping run (version 6), and its ``SemRelocVec`` id runs it."""
    a, b = make(new, **FAST).unwrapped, make(old, **FAST).unwrapped
    assert a.mcl_config == dataclasses.replace(b.mcl_config, **option)
    assert all(getattr(b.mcl_config, k) != v for k, v in option.items())
    assert a.mapping_run_version == b.mapping_run_version == "6"
    venv = gym.make_vec(new.replace("-", "Vec-"), num_envs=1, vectorization_mode="vector_entry_point", **FAST)
    assert all(getattr(venv.envs[0].unwrapped.mcl_config, k) == v for k, v in option.items())
    venv.close()


def assert_same_episode(new: str, old: str, options: dict = START) -> list:
    """The lab episode of ``options`` (a global start unless told) and ``ACTIONS``, then turns and drives, runs the
    same in ``new`` and ``old``, bit for bit; returns ``new``'s steps."""
    actions = ACTIONS + [1] * 20 + [0] * 10
    a = rollout(make(new, **FAST), options=options, actions=actions)
    b = rollout(make(old, **FAST), options=options, actions=actions)
    for x, y in zip(a, b):
        np.testing.assert_equal(x, y)
    return a


def test_registered_ids_and_versions():
    assert semreloc_env.ENV_IDS == (
        "SemReloc-v22",
        "SemReloc-v21",
        "SemReloc-v20",
        "SemReloc-v19",
        "SemReloc-v18",
        "SemReloc-v17",
        "SemReloc-v16",
        "SemReloc-v15",
        "SemReloc-v14",
        "SemReloc-v13",
        "SemReloc-v12",
        "SemReloc-v11",
        "SemReloc-v10",
        "SemReloc-v9",
        "SemReloc-v8",
        "SemReloc-v7",
        "SemReloc-v6",
        "SemReloc-v5",
        "SemReloc-v4",
        "SemReloc-v3",
        "SemReloc-v2",
        "SemReloc-v1",
        "SemReloc-v0",
        "SemSlam-v2",
        "SemSlam-v1",
        "SemSlam-v0",
    )
    for env_id in (*semreloc_env.ENV_IDS, *semreloc_env.VECTOR_ENV_IDS):
        assert env_id in gym.registry
    typed = {"lidar", "odometry", "semantic_class", "semantic_range"}
    flat = {"lidar", "odometry", "semantic"}
    for env_id, keys in [
        ("SemReloc-v22", typed),
        ("SemReloc-v21", typed),
        ("SemReloc-v20", typed),
        ("SemReloc-v19", typed),
        ("SemReloc-v18", typed),
        ("SemReloc-v17", typed),
        ("SemReloc-v16", typed),
        ("SemReloc-v15", typed),
        ("SemReloc-v14", typed),
        ("SemReloc-v13", typed),
        ("SemReloc-v12", typed),
        ("SemReloc-v11", typed),
        ("SemReloc-v10", typed),
        ("SemReloc-v9", typed),
        ("SemReloc-v8", typed),
        ("SemReloc-v7", typed),
        ("SemReloc-v6", typed),
        ("SemReloc-v5", typed),
        ("SemReloc-v4", typed),
        ("SemReloc-v3", typed),
        ("SemReloc-v2", typed),
        ("SemReloc-v1", flat),
        ("SemReloc-v0", flat),
        ("SemSlam-v2", typed),
        ("SemSlam-v1", typed),
        ("SemSlam-v0", flat),
    ]:
        env = make(env_id, **(SLAM_FAST if "Slam" in env_id else FAST))
        assert set(env.observation_space.spaces) == keys, env_id
    with pytest.warns(DeprecationWarning, match="out of date"):
        gym.make("SemReloc-v1", **FAST)


def test_typed_observation_space():
    env = make("SemReloc-v2", camera={"n_beams": 7, "range_max_m": 5.0}, **FAST)
    sc, sr = env.observation_space["semantic_class"], env.observation_space["semantic_range"]
    assert isinstance(sc, gym.spaces.MultiDiscrete) and sc.dtype == np.int64
    np.testing.assert_array_equal(sc.nvec, [1 + len(CLASS_NAMES)] * 7)
    assert isinstance(sr, gym.spaces.Box) and sr.dtype == np.float32 and sr.shape == (7,)
    assert sr.low.min() == 0.0 and sr.high.max() == np.float32(5.0)


@pytest.mark.parametrize(
    "new_id, old_id, kw, start, info_key, missing",
    [
        (
            "SemReloc-v2",
            "SemReloc-v1",
            FAST,
            START,
            "mcl",
            ("ess", "mean_lidar_beam_likelihood", "audit_log_ratio", "w_semantic"),
        ),
        ("SemSlam-v1", "SemSlam-v0", SLAM_FAST, SLAM_START, "slam_error", ("landmark",)),
    ],
)
def test_new_and_old_ids_give_the_same_episode_in_their_own_layout(new_id, old_id, kw, start, info_key, missing):
    actions = ACTIONS + [1] * 20 + [0] * 10  # turn until objects come into view
    new, old = (
        rollout(make(new_id, **kw), options=start, actions=actions),
        rollout(make(old_id, **kw), options=start, actions=actions),
    )
    dropped = 0
    for (o2, r2, t2, tr2, i2), (o1, r1, t1, tr1, i1) in zip(new, old):
        # observation: the same numbers, typed in v2
        assert o2["semantic_class"].dtype == np.int64
        np.testing.assert_array_equal(o2["lidar"], o1["lidar"])
        np.testing.assert_array_equal(o2["odometry"], o1["odometry"])
        n = o2["semantic_range"].size
        np.testing.assert_array_equal(o2["semantic_range"], o1["semantic"][:n])
        np.testing.assert_array_equal(o2["semantic_class"], o1["semantic"][n:])
        for o in (o1, o2):
            ranges, labels = semantic_parts(o)
            np.testing.assert_array_equal(ranges, o2["semantic_range"])
            np.testing.assert_array_equal(labels, o2["semantic_class"])
        assert (r2, t2, tr2) == (r1, t1, tr1)
        # info: the same, except that v2 leaves out what v1 sets to None
        for k in missing:
            if i1[info_key][k] is None:
                assert k not in i2[info_key]
                dropped += 1
                i1 = {**i1, info_key: {kk: v for kk, v in i1[info_key].items() if kk != k}}
        np.testing.assert_equal(i2, i1)
        assert not any(v is None for v in i2[info_key].values())
        assert not any(isinstance(v, float) and np.isnan(v) for v in i2[info_key].values())
    assert dropped > 0  # the rollout did hit steps with values not computed
    assert any((o["semantic_class"] > 0).any() for o, *_ in new)  # and saw objects


def test_vector_env_v2_batches_info_as_typed_arrays_and_follows_semreloc_v2():
    kw = dict(layout="twin_rooms", relocalizer={"n_particles": 200}, max_episode_steps=10)
    venv = gym.make_vec("SemRelocVec-v2", num_envs=2, vectorization_mode="vector_entry_point", **kw)
    single = make("SemReloc-v2", **kw)
    assert venv.single_observation_space == single.observation_space
    obs, infos = venv.reset(seed=3)
    ref = single.reset(seed=3)
    np.testing.assert_equal({k: v[0] for k, v in obs.items()}, ref[0])
    rng = np.random.default_rng(0)
    kinds = set()
    for _ in range(12):
        actions = rng.integers(0, 4, size=2)
        actions[0] = 3 if rng.random() < 0.5 else actions[0]  # stops: updates the gate skips
        obs, rewards, terms, truncs, infos = venv.step(actions)
        for key, arr in infos["mcl"].items():
            assert arr.dtype != object, key  # v1 made object arrays of None here
        if "ess" in infos["mcl"]:
            kinds.add(tuple(infos["mcl"]["_ess"]))
            assert np.isfinite(infos["mcl"]["ess"][infos["mcl"]["_ess"]]).all()
    assert kinds  # some step had the ESS computed for a robot
    venv.close()
    with pytest.raises(TypeError, match="SemReloc-v2"):
        gym.make_vec("SemRelocVec-v2", num_envs=1, vectorization_mode="vector_entry_point", env_id="SemReloc-v1")
    v1 = gym.make_vec("SemRelocVec-v1", num_envs=2, vectorization_mode="vector_entry_point", **kw)
    assert "semantic" in v1.single_observation_space.spaces
    v1.close()


def test_active_observation_is_the_same_on_v1_and_v2():
    """ActiveObservation reads either raw layout and gives the same spaces and values."""
    kw = dict(layout="lab", **FAST)
    a1, a2 = ActiveObservation(make("SemReloc-v1", **kw)), ActiveObservation(make("SemReloc-v2", **kw))
    assert a1.observation_space == a2.observation_space
    seen = False
    for (o1, *rest1), (o2, *rest2) in zip(rollout(a1), rollout(a2)):
        np.testing.assert_equal(o2, o1)
        assert rest1[:3] == rest2[:3]
        seen |= bool((o2["semantic_class"] > 0).any())
    assert seen


LOOKALIKE_CHANGED = 26  # a lookalike seed whose version-1 layout is symmetric to within 0.5 m (end-wall cabinets)
LOOKALIKE_KEPT = 3  # a lookalike seed whose version-1 layout passes version 2's check


def test_v3_differs_from_v2_only_in_the_lookalike_layouts_that_were_symmetric():
    from semreloc_env.layouts import half_turn_asymmetry

    def corridor_asymmetry(layout):
        x0, x1, y0, y1 = layout.bounds()
        objs = [{"class": o.cls, "center": list(o.centroid())} for o in layout.objects]
        return half_turn_asymmetry(objs, x1 - x0, y1 - y0)

    kw = dict(layout="procedural_lookalike", map_source="perfect", relocalizer={"n_particles": 200})
    v2, v3 = (make(i, layout_seed=LOOKALIKE_CHANGED, **kw).unwrapped for i in ("SemReloc-v2", "SemReloc-v3"))
    assert v2.layout != v3.layout
    assert v2.layout.walls == v3.layout.walls  # only corridor objects are drawn again
    assert corridor_asymmetry(v2.layout) < 0.5 <= 1.0 <= corridor_asymmetry(v3.layout)
    assert (
        make("SemSlam-v1", layout="procedural_lookalike", layout_seed=LOOKALIKE_CHANGED).unwrapped.layout == v2.layout
    )
    v2.set_layout("procedural_lookalike", LOOKALIKE_CHANGED)  # set_layout resolves names with the env's version
    assert v2.layout != v3.layout
    v3.set_layout("procedural_lookalike", LOOKALIKE_CHANGED)
    assert v3.layout != v2.layout
    kept = [make(i, layout_seed=LOOKALIKE_KEPT, **kw) for i in ("SemReloc-v2", "SemReloc-v3")]
    assert kept[0].unwrapped.layout == kept[1].unwrapped.layout
    from semreloc_env.layout_sampling import LayoutSampler, RandomLayout

    for env_id, env in (("SemReloc-v2", v2), ("SemReloc-v3", v3)):  # RandomLayout draws with its env's version
        drawn = RandomLayout(
            make(env_id, **kw), LayoutSampler(kinds=("procedural_lookalike",), seeds=[LOOKALIKE_CHANGED])
        )
        drawn.reset(seed=0)
        assert drawn.unwrapped.layout == env.layout, env_id
    for lay in ({"layout": "lab"}, {"layout_seed": LOOKALIKE_KEPT}):
        a, b = (
            rollout(make(i, **{**kw, **lay}), options=None, actions=ACTIONS) for i in ("SemReloc-v2", "SemReloc-v3")
        )
        np.testing.assert_equal(a, b)


def test_vector_env_v3_runs_semreloc_v3():
    kw = dict(layout="procedural_lookalike", layout_seed=LOOKALIKE_CHANGED, map_source="perfect",
              relocalizer={"n_particles": 100})  # fmt: skip
    venv = gym.make_vec("SemRelocVec-v3", num_envs=2, vectorization_mode="vector_entry_point", **kw)
    obs, _ = venv.reset(seed=5)
    ref, _ = make("SemReloc-v3", **kw).reset(seed=5)
    np.testing.assert_equal({k: v[0] for k, v in obs.items()}, ref)
    venv.close()
    with pytest.raises(TypeError, match="SemReloc-v3"):
        gym.make_vec("SemRelocVec-v3", num_envs=1, vectorization_mode="vector_entry_point", env_id="SemReloc-v1")


def test_v4_is_v3_with_negative_evidence():
    from filters.localization.likelihood_field import NegativeEvidenceConfig

    v4, v3 = make("SemReloc-v4", **FAST).unwrapped, make("SemReloc-v3", **FAST).unwrapped
    assert v4.mcl_config.negative_evidence.p_detect > 0
    assert v3.mcl_config.negative_evidence == NegativeEvidenceConfig()
    assert v4.mcl_config == v3.mcl_config.__class__(
        **{**v3.mcl_config.as_dict(), "negative_evidence": v4.mcl_config.negative_evidence}
    )
    # turned off, v4 gives v3's episode bit for bit; on, another one (the same world and sensors)
    off = {**FAST, "relocalizer": {**FAST["relocalizer"], "negative_evidence": {"p_detect": 0.0}}}
    actions = ACTIONS + [1] * 20 + [0] * 10
    a = rollout(make("SemReloc-v4", **off), actions=actions)
    b = rollout(make("SemReloc-v3", **FAST), actions=actions)
    c = rollout(make("SemReloc-v4", **FAST), actions=actions)
    for x, y in zip(a, b):
        np.testing.assert_equal(x, y)
    for x, z in zip(a, c):
        np.testing.assert_equal(x[0], z[0])  # observations do not depend on the filter
    assert any(x[4]["belief"] != z[4]["belief"] for x, z in zip(a, c))


def test_v5_is_v4_with_the_convergence_audit():
    """v5's relocalizer is v4's with ``audit_window`` 20; with the audit off, v5 gives v4's episode bit for
    bit; on, the audit runs where the belief becomes converged and the beliefs part from there."""
    v5, v4 = make("SemReloc-v5", **FAST).unwrapped, make("SemReloc-v4", **FAST).unwrapped
    assert (v5.mcl_config.audit_window, v4.mcl_config.audit_window) == (20, 0)
    assert v5.mcl_config.audit_margin == 1.0
    for vec_id, window in (("SemRelocVec-v5", 20), ("SemRelocVec-v4", 0)):
        venv = gym.make_vec(vec_id, num_envs=1, vectorization_mode="vector_entry_point", **FAST)
        assert venv.envs[0].unwrapped.mcl_config.audit_window == window
        venv.close()
    assert v5.mcl_config == v4.mcl_config.__class__(
        **{**v4.mcl_config.as_dict(), "audit_window": 20, "audit_margin": v5.mcl_config.audit_margin}
    )
    off = _same_until_the_first_audit("SemReloc-v5", "SemReloc-v4", {"audit_window": 0})
    assert all("audit_log_ratio" not in x[4]["mcl"] for x in off)  # NaN (no audit) is left out of info


def _same_until_the_first_audit(new_id: str, old_id: str, off: dict) -> list:
    """``new_id`` with the relocalizer overrides ``off`` gives ``old_id``'s episode bit for bit; at its defaults
    the same episode up to the first audit of either (some audit runs). Returns the run with ``off``."""
    kw = {**FAST, "relocalizer": {**FAST["relocalizer"], **off}}
    actions = ACTIONS + [0, 0, 1] * 20
    a = rollout(make(new_id, **kw), actions=actions)
    b = rollout(make(old_id, **FAST), actions=actions)
    c = rollout(make(new_id, **FAST), actions=actions)
    for x, y in zip(a, b):
        np.testing.assert_equal(x, y)
    audited = [i for run in (b, c) for i, x in enumerate(run) if "audit_log_ratio" in x[4]["mcl"]]
    assert audited  # the belief became converged and was audited
    for x, z in zip(b[: min(audited)], c[: min(audited)]):
        np.testing.assert_equal(x, z)
    return a


def test_v6_is_v5_whose_belief_holds_a_convergence():
    """v6's relocalizer is v5's with ``belief.converged_hold_weight`` 0.85 and ``surprise_ratio`` 0.3; with both
    off, v6 gives v5's episode bit for bit; on, the particles are v5's step for step up to a surprise (none in
    this episode), and the belief is converged wherever v5's is and at some steps where v5's flickered off."""
    v6, v5 = make("SemReloc-v6", **FAST).unwrapped, make("SemReloc-v5", **FAST).unwrapped
    assert (v6.mcl_config.belief.converged_hold_weight, v5.mcl_config.belief.converged_hold_weight) == (0.85, None)
    assert (v6.mcl_config.surprise_ratio, v5.mcl_config.surprise_ratio) == (0.3, 0.0)
    for vec_id, hold in (("SemRelocVec-v6", 0.85), ("SemRelocVec-v5", None)):
        venv = gym.make_vec(vec_id, num_envs=1, vectorization_mode="vector_entry_point", **FAST)
        assert venv.envs[0].unwrapped.mcl_config.belief.converged_hold_weight == hold
        venv.close()
    off = {
        **FAST,
        "relocalizer": {**FAST["relocalizer"], "belief": {"converged_hold_weight": None}, "surprise_ratio": 0.0},
    }
    actions = ACTIONS + [0, 0, 0, 1, 0, 0, 2, 0, 3] * 25
    a = rollout(make("SemReloc-v6", **off), actions=actions)
    b = rollout(make("SemReloc-v5", **FAST), actions=actions)
    for x, y in zip(a, b):
        np.testing.assert_equal(x, y)
    runs = {}
    for env_id in ("SemReloc-v6", "SemReloc-v5"):
        env = make(env_id, **FAST)
        env.reset(seed=4, options=START)
        steps = []
        for act in actions:
            info = env.step(act)[4]
            mcl = env.unwrapped.mcl
            steps.append(
                (mcl.poses.copy(), mcl.log_weights.copy(), info["belief"]["converged"], info["mcl"]["surprise"])
            )
        runs[env_id] = steps
    assert not any(s for *_, s in runs["SemReloc-v6"])
    for (p6, w6, c6, _), (p5, w5, c5, _) in zip(runs["SemReloc-v6"], runs["SemReloc-v5"]):
        np.testing.assert_array_equal(p6, p5)
        np.testing.assert_array_equal(w6, w5)
        assert c6 or not c5
    assert sum(c for _, _, c, _ in runs["SemReloc-v6"]) > sum(c for _, _, c, _ in runs["SemReloc-v5"])


def test_v7_is_v6_whose_audit_searches_more_places_and_comes_first():
    """v7's relocalizer is v6's with ``audit_places`` 16, ``audited_convergence`` and 14 audit candidates per m^2;
    with all three off, v7 gives v6's episode bit for bit; on, the same episode up to the first audit."""
    v7, v6 = make("SemReloc-v7", **FAST).unwrapped, make("SemReloc-v6", **FAST).unwrapped
    assert (v7.mcl_config.audit_places, v6.mcl_config.audit_places) == (16, 0)
    assert (v7.mcl_config.audited_convergence, v6.mcl_config.audited_convergence) == (True, False)
    assert v7.mcl_config == v6.mcl_config.__class__(
        **{**v6.mcl_config.as_dict(), "audit_places": 16, "audited_convergence": True, "audit_candidates_per_m2": 14.0}
    )
    for vec_id, places in (("SemRelocVec-v7", 16), ("SemRelocVec-v6", 0)):
        venv = gym.make_vec(vec_id, num_envs=1, vectorization_mode="vector_entry_point", **FAST)
        assert venv.envs[0].unwrapped.mcl_config.audit_places == places
        venv.close()
    v7_off = {"audit_places": 0, "audited_convergence": False, "audit_candidates_per_m2": 0.0}
    _same_until_the_first_audit("SemReloc-v7", "SemReloc-v6", v7_off)


def test_v8_is_v7_with_maps_whose_camera_no_returns_clear_nothing(monkeypatch):
    """v8 differs from v7 only in the mapping run behind ``map_source="mapping"`` (version 3: the camera's
    no-return beams, objects nearer than its minimum range among them, update nothing): the same relocalizer,
    the same episode bit for bit on a map that is not a mapping run's, and on a layout whose mapping drive
    passes within the camera's minimum range of a cabinet against a block, more of the cabinet mapped (an
    outside trial's layout, cut down: v7's map lost most of it, and the belief converged at its twin)."""
    from semreloc_env.mapping_run import build_maps

    v8, v7 = make("SemReloc-v8", **FAST).unwrapped, make("SemReloc-v7", **FAST).unwrapped
    v6 = make("SemReloc-v6", **FAST).unwrapped
    assert (v8.mapping_run_version, v7.mapping_run_version, v6.mapping_run_version) == ("3", "2", "2")
    assert v8.mcl_config == v7.mcl_config
    for vec_id, version in (("SemRelocVec-v8", "3"), ("SemRelocVec-v7", "2")):
        venv = gym.make_vec(vec_id, num_envs=1, vectorization_mode="vector_entry_point", **FAST)
        assert venv.envs[0].unwrapped.mapping_run_version == version
        venv.close()
    # each version's env gets its mapping run's map, also for a layout set later; v7's keeps the key it had
    from semreloc_env.config import CameraParams, LidarParams
    from semreloc_env.maps import map_key, mapped

    sensors = (LidarParams(), CameraParams())
    with monkeypatch.context() as m:  # the key's text is what it was before it named the libraries it appends
        m.setattr(semreloc_env.maps, "mapping_libraries", lambda: ())
        assert map_key(get_layout("lab"), *sensors, version="2") == "0dc7b7f6ab70a8810d1b227a455888b5"
    versions = {"SemReloc-v12": "6", "SemReloc-v11": "5", "SemReloc-v10": "4", "SemReloc-v9": "3", "SemReloc-v8": "3"}
    versions["SemReloc-v7"] = "2"
    for env_id, version in versions.items():
        env = make(env_id, layout="twin_rooms").unwrapped
        assert env.grid is mapped(get_layout("twin_rooms"), *sensors, version)
        env.set_layout("three_rooms")
        assert env.grid is mapped(get_layout("three_rooms"), *sensors, version)
    assert mapped(get_layout("twin_rooms"), *sensors, "2") is not mapped(get_layout("twin_rooms"), *sensors, "3")
    a, b = rollout(make("SemReloc-v8", **FAST)), rollout(make("SemReloc-v7", **FAST))
    for (o1, r1, t1, u1, i1), (o2, r2, t2, u2, i2) in zip(a, b):
        for k in o1:
            np.testing.assert_array_equal(o1[k], o2[k])
        assert (r1, t1, u1) == (r2, t2, u2)
        np.testing.assert_array_equal(i1["belief"]["estimate"], i2["belief"]["estimate"])

    # an outside trial's layout: two halls alike up to a translation of 11 m (a door panel tells them apart)
    cab, chair, bin_ = "cabinet", "chair", "trash_bin"
    objects = [(cab, 0.3, 6.0, 0.6, 1.2), (chair, 3, 5, 0.5, 0.5), (chair, 6.5, 8, 0.5, 0.5), (bin_, 8, 3, 0.4, 0.4),
               (cab, 6, 2.3, 1.2, 0.6), ("door", 1.2, 10.95, 0.9, 0.1)]  # fmt: skip
    objects += [(c, x + 11, y, w, h) for c, x, y, w, h in objects[:5]]
    halls = get_layout({
        "name": "translated_halls", "outer": [[0, 0], [20, 0], [20, 11], [0, 11]],
        "walls": [[[0, 2], [4, 2]], [[5, 2], [15, 2]], [[16, 2], [20, 2]]],
        "blocks": [[[9, 2], [11, 2], [11, 11], [9, 11]]],
        "objects": [{"class": c, "center": [x, y], "size": [w, h]} for c, x, y, w, h in objects],
    })  # fmt: skip
    maps = {v: build_maps(halls, version=v) for v in ("2", "3")}
    np.testing.assert_array_equal(maps["2"].occupancy, maps["3"].occupancy)  # the lidar's map is the same

    def cabinet_cells(g, x):  # class cells of the cabinet against the west wall of a hall
        k, res, (ox, oy) = g.class_names.index("cabinet"), g.resolution_m, g.origin_xy_m
        rows, cols = (
            slice(round((5.4 - oy) / res), round((6.6 - oy) / res)),
            slice(round((x - ox) / res), round((x + 0.6 - ox) / res)),
        )
        return int((g.semantic[k][rows, cols] > g.semantic_thresh).sum())

    old, new = ([cabinet_cells(maps[v], x) for x in (0, 11)] for v in ("2", "3"))  # (west hall, east hall)
    assert old[1] == 0 < old[0]  # v7's map lost the east hall's cabinet (the drive passed within 0.5 m of it)
    assert min(new) > 0.8 * max(new)  # v8's maps both, about alike
    with pytest.raises(ValueError, match="mapping run version must be one of"):
        build_maps(halls, version="9")


def test_build_maps_command_offers_every_mapping_run_version(tmp_path, capsys):
    import typing

    from semreloc_env.mapping_run import MAPPING_RUN_VERSIONS
    from semreloc_env.tools import build_maps as cli

    assert typing.get_args(typing.get_type_hints(cli.Args)["mapping_version"]) == MAPPING_RUN_VERSIONS
    assert cli.Args().mapping_version == MAPPING_RUN_VERSIONS[-1]
    assert cli.main(["--layout", "twin_rooms", "--mapping-version", "2", "--out", str(tmp_path)]) == 0
    assert (tmp_path / "twin_rooms.yaml").is_file()


def test_v9_is_v8_whose_audit_screens_the_whole_map():
    """v9's relocalizer is v8's with ``audit_screen``; with it off, v9 gives v8's episode bit for bit; on,
    the same episode up to the first audit. The maps are v8's."""
    v9, v8 = make("SemReloc-v9", **FAST).unwrapped, make("SemReloc-v8", **FAST).unwrapped
    assert (v9.mcl_config.audit_screen, v8.mcl_config.audit_screen) == (True, False)
    assert v9.mcl_config == v8.mcl_config.__class__(**{**v8.mcl_config.as_dict(), "audit_screen": True})
    assert v9.mapping_run_version == v8.mapping_run_version == "3"
    for vec_id, screen in (("SemRelocVec-v9", True), ("SemRelocVec-v8", False)):
        venv = gym.make_vec(vec_id, num_envs=1, vectorization_mode="vector_entry_point", **FAST)
        assert venv.envs[0].unwrapped.mcl_config.audit_screen is screen
        venv.close()
    _same_until_the_first_audit("SemReloc-v9", "SemReloc-v8", {"audit_screen": False})


def test_v10_is_v9_with_maps_without_stray_class_cells():
    """v10's maps are v9's without the class cells no confident cell of their class backs up (the mapping run's
    version 4), and its relocalizer is v9's whose screen pause follows the place; with that off, v10 gives v9's
    episode bit for bit on a map that is not a mapping run's. On the third outside tester's shifted twin rooms,
    v9's map holds a door cell on the east room's cabinet (the stray cell a mislabelled detection matched);
    v10's does not, and keeps nearly every other class cell."""
    from filters.mapping.occupancy import drop_unsupported_class_cells
    from semreloc_env.mapping_run import STRAY_RADIUS_M, STRAY_SUPPORT_P, build_maps

    v10, v9 = make("SemReloc-v10", **FAST).unwrapped, make("SemReloc-v9", **FAST).unwrapped
    assert (v10.mapping_run_version, v9.mapping_run_version) == ("4", "3")
    assert make("SemReloc-v8", **FAST).unwrapped.mapping_run_version == "3"
    assert v10.mcl_config == v9.mcl_config.__class__(**{**v9.mcl_config.as_dict(), "audit_screen_pause_place": True})
    for vec_id, version in (("SemRelocVec-v10", "4"), ("SemRelocVec-v9", "3")):
        venv = gym.make_vec(vec_id, num_envs=1, vectorization_mode="vector_entry_point", **FAST)
        assert venv.envs[0].unwrapped.mapping_run_version == version
        venv.close()
    _same_until_the_first_audit("SemReloc-v10", "SemReloc-v9", {"audit_screen_pause_place": False})

    layout = semreloc_env.load_layout(DOCS_LAYOUTS / "outside_v8" / "b7_shifted_stub_twins.json")
    old, new = build_maps(layout, version="3"), build_maps(layout, version="4")
    np.testing.assert_array_equal(old.occupancy, new.occupancy)
    want = drop_unsupported_class_cells(old, STRAY_SUPPORT_P, STRAY_RADIUS_M)
    np.testing.assert_array_equal(new.semantic, want.semantic)
    door = old.class_names.index("door")
    (r, c) = old.world_to_cell(np.array([[5.23, 4.03]]))  # on the east room's cabinet
    assert old.class_mask(door)[r[0], c[0]] and not new.class_mask(door)[r[0], c[0]]
    kept = sum(new.class_mask(k).sum() for k in range(len(new.class_names)))
    before = sum(old.class_mask(k).sum() for k in range(len(old.class_names)))
    assert 0.95 * before < kept < before


def test_v11_is_v10_with_maps_whose_unobserved_space_is_cleared():
    """v11 differs from v10 only in its maps (the mapping run's version 5). On the lab the two maps are the same,
    so are the episodes, bit for bit; in the third outside tester's 24 m x 16 m hall, v10's map leaves unknown
    the free space farther than the lidar's 8 m from every surface, v11's marks it free, and neither marks free
    a cell the world holds an obstacle in; occupancy above 0.5 and every class cell stay as they were."""
    from semreloc_env.mapping_run import build_maps
    from semreloc_env.world import build_world

    v11, v10 = make("SemReloc-v11", layout="lab").unwrapped, make("SemReloc-v10", layout="lab").unwrapped
    assert (v11.mapping_run_version, v10.mapping_run_version) == ("5", "4")
    assert v11.mcl_config == v10.mcl_config
    for vec_id, version in (("SemRelocVec-v11", "5"), ("SemRelocVec-v10", "4")):
        venv = gym.make_vec(vec_id, num_envs=1, vectorization_mode="vector_entry_point", **FAST)
        assert venv.envs[0].unwrapped.mapping_run_version == version
        venv.close()
    np.testing.assert_array_equal(v11.grid.occupancy, v10.grid.occupancy)
    a, b = rollout(make("SemReloc-v11", layout="lab")), rollout(make("SemReloc-v10", layout="lab"))
    for (o1, r1, t1, u1, i1), (o2, r2, t2, u2, i2) in zip(a, b, strict=True):
        for k in o1:
            np.testing.assert_array_equal(o1[k], o2[k])
        assert (r1, t1, u1) == (r2, t2, u2)
        np.testing.assert_array_equal(i1["belief"]["estimate"], i2["belief"]["estimate"])

    hall = semreloc_env.load_layout(DOCS_LAYOUTS / "outside_v8" / "b8_hall_wall_huggers.json")
    held_out = [("procedural", 1_000_008), ("procedural_sym", 1_000_000), ("procedural", 1_000_021)]
    for layout in [hall] + [get_layout(kind, seed=seed) for kind, seed in held_out]:
        old, new = build_maps(layout, version="4"), build_maps(layout, version="5")
        world = build_world(layout)
        rows, cols = np.indices(old.shape)
        xy = old.cell_centers(rows.ravel(), cols.ravel())
        open_space = world.free_points(xy, margin_m=0.3).reshape(old.shape)  # the robot fits with 0.3 m to spare
        solid = ~world.free_points(xy, margin_m=-world.robot_params.radius_m).reshape(old.shape)  # in an obstacle
        changed = new.occupancy != old.occupancy
        assert not (changed & solid).any()  # (procedural 1 000 021: a first version cleared 3 cells in a cabinet)
        assert (open_space & ~new.free_mask()).sum() == 0
        np.testing.assert_array_equal(new.occupied_mask(), old.occupied_mask())
        assert (old.occupancy[changed] <= 0.5).all() and (new.occupancy[changed] < old.occupancy[changed]).all()
        np.testing.assert_array_equal(new.semantic, old.semantic)
        if layout is hall:
            assert (open_space & ~old.free_mask()).sum() > 5000  # 16.5 m^2 in 0.05 m cells
        else:
            assert changed.sum() < 10  # a few shadowed cells, if any


def test_v12_is_v11_with_maps_from_a_drive_that_enters_narrow_passages():
    """v12 differs from v11 only in its maps (the mapping run's version 6). In a fifth outside tester's corridor
    pods (two room-and-corridor pods, the second the first turned by 180 deg about the junction) v11's drive never
    entered the 1 m corridors, so their walls were mapped from the corridors' ends, in dashes, and a scan scored
    at its true pose and at the look-alike pose differed by the dashes; v12's drive enters them and maps the
    walls whole, and the two places score alike."""
    import math

    from filters.localization.likelihood_field import cached_model
    from semreloc_env.mapping_run import mapping_drive

    v12, v11 = make("SemReloc-v12", **FAST).unwrapped, make("SemReloc-v11", **FAST).unwrapped
    assert (v12.mapping_run_version, v11.mapping_run_version) == ("6", "5")
    # and a surprise turns the audit on in a tracking episode (tests/test_audit.py); global starts are v11's
    assert not v11.mcl_config.audit_after_surprise
    assert v12.mcl_config == dataclasses.replace(v11.mcl_config, audit_after_surprise=True)
    venv = gym.make_vec("SemRelocVec-v12", num_envs=1, vectorization_mode="vector_entry_point", **FAST)
    assert venv.envs[0].unwrapped.mapping_run_version == "6"
    venv.close()

    pods = DOCS_LAYOUTS / "outside_v11" / "d10_rotated_pods_180.json"
    layout = semreloc_env.load_layout(pods)
    for narrow, in_corridor in ((False, 0), (True, 100)):
        poses, _ = mapping_drive(layout, narrow=narrow)
        inside = (poses[:, 0] > 6.5) & (poses[:, 0] < 15.5) & (poses[:, 1] > 2.0) & (poses[:, 1] < 3.0)
        assert (inside.sum() > in_corridor) if narrow else (inside.sum() == 0)

    def image(p):  # the 180 deg turn about (20, 2.5) that maps one pod onto the other
        return np.array([40.0 - p[0], 5.0 - p[1], math.atan2(-math.sin(p[2]), -math.cos(p[2]))])

    spread, wall = {}, {}
    for env_id in ("SemReloc-v12", "SemReloc-v11"):
        env = make(env_id, layout=str(pods)).unwrapped
        env.reset(seed=0)
        grid, cfg, world = env.grid, env.mcl_config, env.world
        # the corridor's south wall (y = 2 m, x 7-15 m): the row of cells just below it, as the returns mark it
        r, c = grid.world_to_cell(np.column_stack([np.arange(7.0, 15.0, 0.05) + 0.025, np.full(160, 1.975)]))
        wall[env_id] = grid.occupied_mask()[r, c].mean()
        model = cached_model(grid, cfg.lidar_field, cfg.semantic_field, cfg.backend, cfg.negative_evidence)
        rng = np.random.default_rng(1)
        diffs = []
        while len(diffs) < 120:
            p = np.array([rng.uniform(0.3, 15.7), rng.uniform(0.0, 5.0), rng.uniform(-math.pi, math.pi)])
            if not world.is_free(p[:2]):
                continue
            ll_l, _, _ = model.log_likelihood_terms(np.stack([p, image(p)]), env.lidar.read(world, p, rng))
            diffs.append(cfg.likelihood_scale * (ll_l[0] - ll_l[1]))
        spread[env_id] = float(np.std(diffs))
    assert wall["SemReloc-v11"] < 0.6 and wall["SemReloc-v12"] > 0.9  # dashes, then a whole wall
    # the lidar's per-scan difference between the places (tempered nats, sd over 120 poses): 0.141 on v11's maps,
    # 0.007 on v12's
    assert spread["SemReloc-v12"] < 0.3 * spread["SemReloc-v11"]


def test_v13_is_v12_whose_surprise_test_keeps_its_own_average():
    """v13 differs from v12 only in its relocalizer's surprise test (`MCLConfig.surprise_own_average`). A tracking
    start in a held-out half-turn symmetric layout, then a kidnapping: augmented MCL had restarted its averages
    just before (pf.c's rule), so v12's test took the kidnapped scans for the new normal, raised no surprise and
    ran no audit, and the belief converged at a wrong place for many steps; v13's test raises the surprise, the
    audit runs, and the belief does not converge at a wrong place."""
    v13, v12 = make("SemReloc-v13", **FAST).unwrapped, make("SemReloc-v12", **FAST).unwrapped
    assert v13.mcl_config == dataclasses.replace(v12.mcl_config, surprise_own_average=True)
    assert v13.mapping_run_version == v12.mapping_run_version == "6"
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=".*out of date.*", category=DeprecationWarning)
        venv = gym.make_vec("SemRelocVec-v13", num_envs=1, vectorization_mode="vector_entry_point", **FAST)
    assert venv.envs[0].unwrapped.mcl_config.surprise_own_average
    venv.close()

    from agents.policies import POLICIES

    surprises, wrong = {}, {}
    for env_id in ("SemReloc-v12", "SemReloc-v13"):
        env = make(env_id, layout="procedural_sym", layout_seed=1_000_001, action_type="continuous",
                   max_episode_steps=120)  # fmt: skip
        policy = POLICIES["wall_follow"](6)
        env = policy.wrap(env)
        policy.reset()
        start = [3.576013847763177, 2.4092756478046384, 1.8835095557959116]  # free poses of this layout
        kidnap = [4.279667509118021, 6.8438457773019135, -0.06945666012141727]
        options = {"tracking": True, "pose": start, "kidnap_at_step": 60, "kidnap_pose": kidnap}
        obs, info = env.reset(seed=6, options=options)
        surprises[env_id], wrong[env_id] = 0, 0
        for t in range(1, 121):
            obs, _, terminated, truncated, info = env.step(policy.act(obs))
            surprises[env_id] += bool(info["mcl"].get("surprise", False))
            if t > 70 and info["belief"]["converged"] and info["pose_error"]["position"] > 0.5:
                wrong[env_id] += 1
            if terminated or truncated:
                break
    assert surprises["SemReloc-v12"] == 0 and wrong["SemReloc-v12"] > 10
    assert surprises["SemReloc-v13"] > 0 and wrong["SemReloc-v13"] == 0


def test_v14_is_v13_with_a_surprise_test_of_the_cameras_own():
    """v14 differs from v13 only in its relocalizer's semantic surprise test (`MCLConfig.semantic_surprise_ratio`).
    A tracking start in ``twin_rooms``, then a kidnapping to the half-turned image of the pose, where the walls and
    furniture shapes are the same and the classes differ: v13 raises no surprise and its held convergence keeps
    the belief in the old room for 44 steps while the camera contradicts it; v14's camera test raises one at
    the second contradicting update, and the belief stops calling the old room converged."""
    assert_one_option_apart("SemReloc-v14", "SemReloc-v13", semantic_surprise_ratio=0.4)

    from agents.policies import POLICIES

    surprises, wrong = {}, {}
    for env_id in ("SemReloc-v13", "SemReloc-v14"):
        env = make(env_id, layout="twin_rooms", max_episode_steps=120)
        policy = POLICIES["wall_follow"](0)
        env = policy.wrap(env)
        policy.reset()
        start = [1.669010996218475, 4.252202990915117, -1.6954030247145493]
        kidnap = [10.511201514783071, 3.186554615799275, 1.4461896288752438]  # the image of the pose at step 29
        options = {"tracking": True, "pose": start, "kidnap_at_step": 30, "kidnap_pose": kidnap}
        obs, info = env.reset(seed=8, options=options)
        surprises[env_id], wrong[env_id] = 0, 0
        for t in range(1, 121):
            obs, _, terminated, truncated, info = env.step(policy.act(obs))
            if t >= 30:
                surprises[env_id] += bool(info["mcl"]["semantic_surprise"])
                wrong[env_id] += info["belief"]["converged"] and info["pose_error"]["position"] > 0.5
            if terminated or truncated:
                break
    assert surprises["SemReloc-v13"] == 0 and wrong["SemReloc-v13"] > 30
    assert surprises["SemReloc-v14"] > 0 and wrong["SemReloc-v14"] <= 6


def test_v15_is_v14_whose_audit_after_a_surprise_turns_off_once_it_clears():
    """v15 differs from v14 only in its relocalizer's `MCLConfig.audit_after_surprise_once` (its effect on a
    kidnapping: tests/test_audit.py). A global start's audit is on from the start, so its episode is v14's, bit
    for bit; so is a tracking episode without a surprise."""
    assert_one_option_apart("SemReloc-v15", "SemReloc-v14", audit_after_surprise_once=True)
    for options in (START, {**START, "tracking": True}):
        a = assert_same_episode("SemReloc-v15", "SemReloc-v14", options)
        assert any("audit_log_ratio" in step[-1]["mcl"] for step in a) == ("tracking" not in options)


def test_v19_is_v18_with_wheel_odometry_a_looser_kld_bound_and_places_that_follow_the_odometry():
    """v19's relocalizer is v18's with ``kld_epsilon`` 0.15 and ``places_follow_odometry``; its odometry reads no slide
    along a wall; maps, worlds, observation spaces are v18's; its Vec id runs it."""
    a, b = make("SemReloc-v19", **FAST).unwrapped, make("SemReloc-v18", **FAST).unwrapped
    assert a.mcl_config == dataclasses.replace(b.mcl_config, kld_epsilon=0.15, places_follow_odometry=True)
    assert b.mcl_config.kld_epsilon == 0.05 and not b.mcl_config.places_follow_odometry
    assert not a.odometry.reads_slides and b.odometry.reads_slides
    assert a.mapping_run_version == b.mapping_run_version == "6"
    assert a.observation_space == b.observation_space and a.odometry.params == b.odometry.params
    assert make("SemSlam-v1", **SLAM_FAST).unwrapped.odometry.reads_slides  # SemSlam keeps its episodes
    venv = gym.make_vec("SemRelocVec-v19", num_envs=1, vectorization_mode="vector_entry_point", **FAST)
    assert not venv.envs[0].unwrapped.odometry.reads_slides and venv.envs[0].unwrapped.mcl_config.kld_epsilon == 0.15
    venv.close()


def test_v20_is_v19_whose_belief_between_updates_is_carried_by_the_odometry():
    """v20's relocalizer is v19's with ``belief_between_updates="odometry"``: the same observations, particles and
    updates bit for bit; the belief (info, reward) differs on the steps without an update only; its Vec id runs it."""
    assert_one_option_apart("SemReloc-v20", "SemReloc-v19", belief_between_updates="odometry")
    actions = ACTIONS + [1] * 20 + [0] * 10
    a = rollout(make("SemReloc-v20", **FAST), options=START, actions=actions)
    b = rollout(make("SemReloc-v19", **FAST), options=START, actions=actions)
    skipped, entropy = 0, [0.0, 0.0]
    for (obs, _, term, trunc, info), (obs2, _, term2, trunc2, info2) in zip(a[1:], b[1:]):
        np.testing.assert_equal(obs, obs2)
        np.testing.assert_equal(info["mcl"], info2["mcl"])
        assert (term, trunc) == (term2, trunc2)
        terms, terms2 = dict(info["rewards"]), dict(info2["rewards"])
        entropy[0] += terms.pop("entropy")
        entropy[1] += terms2.pop("entropy")
        assert terms == terms2  # time, collision, success, wrong convergence
        if info["mcl"]["updated"]:
            np.testing.assert_equal(info["belief"], info2["belief"])
            # the entropy terms telescope: summed up to an update, both are that update's drop from the start
            assert entropy[0] == pytest.approx(entropy[1], abs=1e-9)
        else:
            skipped += 1
            assert info["rewards"]["entropy"] == 0.0  # the carried belief keeps the update's entropy
    assert skipped >= 5 and len(a) == len(b)


def test_v21_is_v20_whose_relocalizer_does_less_work():
    """v21's relocalizer is v20's with half the particles per m^2 at a global start and no noise drawn for a still
    step; the world, sensors and observations are v20's for the same actions (their draws come from other
    generators), the filter's differ from the reset on (its own still predict, the smaller draw); its Vec id runs it."""
    assert_one_option_apart("SemReloc-v21", "SemReloc-v20", global_particles_per_m2=25.0, predict_when_still=False)
    new = make("SemReloc-v21", map_source="perfect").unwrapped
    old = make("SemReloc-v20", map_source="perfect").unwrapped
    new.reset(seed=3)
    old.reset(seed=3)
    n_new, n_old = new.mcl.global_particle_count(), old.mcl.global_particle_count()
    assert abs(n_new - n_old / 2) <= 1 and n_new >= new.mcl_config.min_particles
    assert ACTIONS[0] == 3  # a stop: a zero odometry increment
    for env in (new, old):
        state = env.mcl.rng.bit_generator.state
        poses = env.mcl.poses.copy()
        env.mcl.predict([0.0, 0.0, 0.0])
        assert np.array_equal(env.mcl.poses, poses)
        assert (env.mcl.rng.bit_generator.state == state) == (env is new)
        env.step(0)  # forward: the particles move, with noise drawn
        assert env.mcl.poses.shape != poses.shape or not np.array_equal(env.mcl.poses, poses)
        assert env.mcl.rng.bit_generator.state != state
    a = rollout(make("SemReloc-v21", **FAST), options=START)
    b = rollout(make("SemReloc-v20", **FAST), options=START)
    for (obs, *_), (obs2, *_) in zip(a, b):
        np.testing.assert_equal(obs, obs2)
    assert any(not np.array_equal(x[-1]["belief"]["estimate"], y[-1]["belief"]["estimate"]) for x, y in zip(a, b))


def test_v22_is_v21_whose_small_steps_move_their_own_way_and_whose_kld_draws_one_sequence():
    """v22's relocalizer is v21's with ``exact_small_moves`` in its motion model and ``kld_one_sequence``; its simulated
    odometry's model moves a step under 1 cm in its own direction too; worlds, maps and spaces are v21's; its Vec id
    runs it, and it is the batched env's default. Backing slowly (30 steps of 5 mm) from a known pose, v21's odometry
    reads the steps forwards and its belief ends about 0.3 m off; v22's reads them backwards and stays on the truth.
    Discrete actions give the same observations in both (their only steps under 1 cm are turns on the spot)."""
    from semreloc_env.envs.batched import SINGLE_ENV_ID

    assert SINGLE_ENV_ID == "SemReloc-v22"
    a, b = make("SemReloc-v22", **FAST).unwrapped, make("SemReloc-v21", **FAST).unwrapped
    motion = dataclasses.replace(b.mcl_config.motion, exact_small_moves=True)
    assert a.mcl_config == dataclasses.replace(b.mcl_config, motion=motion, kld_one_sequence=True)
    assert not b.mcl_config.motion.exact_small_moves and not b.mcl_config.kld_one_sequence
    assert a.odometry.params == dataclasses.replace(b.odometry.params, exact_small_moves=True)
    assert a.odometry.reads_slides == b.odometry.reads_slides is False
    assert a.mapping_run_version == b.mapping_run_version == "6"
    assert a.observation_space == b.observation_space
    assert not make("SemSlam-v1", **SLAM_FAST).unwrapped.odometry.params.exact_small_moves  # SemSlam keeps its episodes
    assert (
        make("SemReloc-v22", **FAST, odometry={"exact_small_moves": False}).unwrapped.odometry.params
        == b.odometry.params
    )
    venv = gym.make_vec("SemRelocVec-v22", num_envs=1, vectorization_mode="vector_entry_point", **FAST)
    robot = venv.envs[0].unwrapped
    assert robot.odometry.params.exact_small_moves and robot.mcl_config.kld_one_sequence
    venv.close()
    back = np.array([-0.1, 0.0], np.float32)  # v = -0.05 m/s: 5 mm per step
    ends = {}
    for env_id in ("SemReloc-v22", "SemReloc-v21"):
        env = make(env_id, **FAST, action_type="continuous")
        env.reset(seed=4, options={**START, "tracking": True})
        read = sum(env.step(back)[0]["odometry"][0] for _ in range(30))
        ends[env_id] = (read, env.unwrapped.world.pose[0], env.unwrapped.pose_error()["position"])
    (read_new, x_new, err_new), (read_old, x_old, err_old) = ends["SemReloc-v22"], ends["SemReloc-v21"]
    assert x_new == x_old == pytest.approx(START["pose"][0] - 0.15, abs=1e-3)  # the same world: 15 cm back
    assert read_new == pytest.approx(-0.15, abs=0.01) and read_old == pytest.approx(0.15, abs=0.01)
    assert err_new < 0.05 and err_old > 0.2
    actions = ACTIONS + [1] * 20 + [0] * 10 + [2, 0] * 10  # discrete: no step under 1 cm but the turns on the spot
    a = rollout(make("SemReloc-v22", **FAST), options={**START, "tracking": True}, actions=actions)
    b = rollout(make("SemReloc-v21", **FAST), options={**START, "tracking": True}, actions=actions)
    assert len(a) == len(b) == len(actions) + 1
    for (obs, *_), (obs2, *_) in zip(a, b):
        np.testing.assert_equal(obs, obs2)  # the same world, sensors and odometry readings


def test_semslam_v2_is_v1_with_v22_s_odometry_and_association_within_the_gate():
    """SemSlam-v2 is v1 with SemReloc-v22's odometry (wheels: no slide along a wall; a step under 1 cm in its own
    direction, in the simulator and, through its noise config, the SLAM motion model) and ML association among the
    gated landmarks; the same world and spaces. Backing slowly, v1's SLAM estimate goes forwards, v2's back."""
    from filters.slam.association import AssociationConfig

    a, b = make("SemSlam-v2", **SLAM_FAST).unwrapped, make("SemSlam-v1", **SLAM_FAST).unwrapped
    assert not a.odometry.reads_slides and b.odometry.reads_slides
    assert a.odometry.params == dataclasses.replace(b.odometry.params, exact_small_moves=True)
    assert a.motion_model.config.exact_small_moves and not b.motion_model.config.exact_small_moves
    assert a.slam_params == dataclasses.replace(b.slam_params, gate_first=True)
    assert a.fastslam_config.association == dataclasses.replace(b.fastslam_config.association, gate_first=True)
    assert isinstance(a.fastslam_config.association, AssociationConfig)
    assert a.observation_space == b.observation_space
    assert make("SemSlam-v2", slam={"n_particles": 20, "gate_first": False}).unwrapped.slam_params == b.slam_params
    v0 = make("SemSlam-v0", **SLAM_FAST).unwrapped
    assert v0.slam_params == b.slam_params and v0.odometry.params == b.odometry.params and v0.odometry.reads_slides
    back = np.array([-0.1, 0.0], np.float32)  # 5 mm per step
    moved = {}
    for env_id in ("SemSlam-v2", "SemSlam-v1"):
        env = make(env_id, **SLAM_FAST, action_type="continuous")
        env.reset(seed=4, options=SLAM_START)
        for _ in range(30):
            _, _, _, _, info = env.step(back)
        u = env.unwrapped
        moved[env_id] = (u.world.pose[1] - SLAM_START["pose"][1], u.slam.estimate().pose[1] - SLAM_START["pose"][1])
    (true_new, est_new), (true_old, est_old) = moved["SemSlam-v2"], moved["SemSlam-v1"]
    assert true_new == true_old == pytest.approx(-0.15, abs=1e-3)  # heading pi/2: backing moves along -y
    assert est_new == pytest.approx(-0.15, abs=0.03) and est_old == pytest.approx(0.15, abs=0.03)


def test_wheel_odometry_reads_an_arc_as_it_is_and_no_sideways_slide():
    from semreloc_env.sensors import wheel_increment

    for v, w in [(0.05, 0.0), (0.05, 0.4), (-0.03, -0.7), (0.0, 0.5)]:  # arcs without slip (dt = 0.1 s)
        th = w * 0.1
        r = v / w if w else None
        arc = (r * np.sin(th), r * (1 - np.cos(th)), th) if w else (v * 0.1, 0.0, 0.0)
        np.testing.assert_allclose(wheel_increment(arc), arc, atol=1e-15)
    np.testing.assert_allclose(wheel_increment((0.0, 0.017, 0.0)), (0.0, 0.0, 0.0), atol=1e-18)  # a slide sideways
    np.testing.assert_allclose(wheel_increment((0.01, 0.017, 0.0)), (0.01, 0.0, 0.0), atol=1e-18)  # along + across
    chord = (0.05 * math.cos(0.04), 0.05 * math.sin(0.04), 0.1)  # 5 moves along headings 0, 0.02, ..., 0.08
    np.testing.assert_allclose(wheel_increment(chord, 5), chord, atol=1e-15)


def test_v18_is_v17_whose_audit_after_a_lost_hold_judges_only_the_scans_since_its_fade():
    """v18 differs from v17 only in its relocalizer's `MCLConfig.lost_hold_window` (its effect on a look-alike
    kidnapping: tests/test_audit.py). A global start's audit is on from its start, so no hold is lost with the audit
    off and its episode is v17's, bit for bit."""
    assert_one_option_apart("SemReloc-v18", "SemReloc-v17", lost_hold_window=5)
    assert make("SemReloc-v17", **FAST).unwrapped.mcl_config.lost_hold_window == 0
    assert_same_episode("SemReloc-v18", "SemReloc-v17")


def test_v17_is_v16_whose_tracking_start_holds_its_pose():
    """v17 differs from v16 only in its relocalizer's `MCLConfig.hold_init_pose` (its effect on a kidnapping:
    tests/test_audit.py). A global start holds nothing, so its episode is v16's, bit for bit; a tracking start is
    converged at once in v17."""
    assert_one_option_apart("SemReloc-v17", "SemReloc-v16", hold_init_pose=True)
    assert_same_episode("SemReloc-v17", "SemReloc-v16")
    # a tracking start whose cloud v16 does not call converged (91 % in the heaviest hypothesis): v17 holds it
    first = {}
    for env_id in ("SemReloc-v17", "SemReloc-v16"):
        steps = rollout(make(env_id, **FAST), seed=0, options={"tracking": True}, actions=[0] * 3)
        first[env_id] = [s[-1]["belief"]["converged"] for s in steps]
    assert first == {"SemReloc-v17": [True] * 4, "SemReloc-v16": [False] + first["SemReloc-v16"][1:]}


def test_v16_is_v15_whose_audit_also_follows_a_hold_lost_without_a_surprise():
    """v16 differs from v15 only in its relocalizer's `MCLConfig.audit_after_lost_hold` (its effect on a kidnapping
    no surprise test notices: tests/test_audit.py). A global start's audit is on from the start, so its episode is
    v15's, bit for bit, also when a hold is lost on the way; a tracking episode is v15's until a hold is lost."""
    assert_one_option_apart("SemReloc-v16", "SemReloc-v15", audit_after_lost_hold=True)
    a = assert_same_episode("SemReloc-v16", "SemReloc-v15")
    held = [step[-1]["belief"]["converged"] for step in a]
    assert any(was and not now for was, now in zip(held, held[1:]))  # a hold is lost on the way
    # a tracking episode whose hold fades (spinning in three_rooms' corridor): v16 audits from then on, v15 never
    kw = dict(FAST, layout="three_rooms")
    options = {"tracking": True, "pose": [7.5, 1.2, 0.0]}
    audited, lost = {}, {}
    for env_id in ("SemReloc-v16", "SemReloc-v15"):
        steps = rollout(make(env_id, **kw), seed=2, options=options, actions=[1] * 120)
        held = [s[-1]["belief"]["converged"] for s in steps]
        lost[env_id] = next((t for t in range(1, len(held)) if held[t - 1] and not held[t]), None)
        audited[env_id] = [t for t, s in enumerate(steps) if "audit_log_ratio" in s[-1]["mcl"]]
    assert lost["SemReloc-v16"] == lost["SemReloc-v15"] is not None  # the same episode up to the first loss
    assert audited["SemReloc-v15"] == [] and audited["SemReloc-v16"]
    assert min(audited["SemReloc-v16"]) > lost["SemReloc-v16"]
