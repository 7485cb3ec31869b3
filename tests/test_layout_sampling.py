import json
import math

import gymnasium as gym
import numpy as np
import pytest

import semreloc_env  # noqa: F401
from semreloc_env.layout_sampling import HELD_OUT_LAYOUT_SEEDS, LayoutSampler, RandomLayout, is_held_out
from semreloc_env.layouts import ProceduralParams, get_layout, half_turn_asymmetry, lookalike_layout
from semreloc_env.rasterize import rasterize
from semreloc_env.world import build_world


def _draws(sampler, seed, n):
    rng = np.random.default_rng(seed)
    return [(d.kind, d.seed) for d in (sampler.draw(rng) for _ in range(n))]


def test_sampler_is_deterministic_per_seed_and_covers_every_kind():
    s = LayoutSampler()
    a, b, c = _draws(s, 1, 60), _draws(s, 1, 60), _draws(s, 2, 60)
    assert a == b and a != c
    assert {k for k, _ in a} == {"procedural", "procedural_sym", "procedural_lookalike", "lab", "twin_rooms"}
    assert all(seed == 0 for k, seed in a if k in ("lab", "twin_rooms"))


def test_sampler_never_yields_a_held_out_seed():
    # a range straddling the held-out block, and a list made mostly of held-out seeds
    near = range(HELD_OUT_LAYOUT_SEEDS.start - 20, HELD_OUT_LAYOUT_SEEDS.stop + 20)
    listed = [*HELD_OUT_LAYOUT_SEEDS, 7]
    for seeds in (near, listed):
        got = _draws(LayoutSampler(kinds=("procedural",), seeds=seeds), 0, 3000)
        assert not any(is_held_out(s) for _, s in got)
        assert len({s for _, s in got}) > 1 or seeds is listed
    assert {s for _, s in _draws(LayoutSampler(kinds=("procedural",), seeds=listed), 0, 50)} == {7}
    assert len(HELD_OUT_LAYOUT_SEEDS) == 500 and HELD_OUT_LAYOUT_SEEDS.start == 1_000_000  # documented


def test_sampler_rejects_bad_input():
    with pytest.raises(ValueError, match="kinds"):
        LayoutSampler(kinds=("maze",))
    with pytest.raises(ValueError, match="held-out"):
        LayoutSampler(kinds=("procedural",), seeds=HELD_OUT_LAYOUT_SEEDS)
    with pytest.raises(ValueError, match="weights"):
        LayoutSampler(kinds=("lab", "twin_rooms"), weights=[1.0, -1.0])
    with pytest.raises(ValueError, match="nothing"):
        LayoutSampler(kinds=())
    for seeds in (range(-10, 0), range(5, 5), range(0, 2**70), [1.7], [True], [], [-3]):
        with pytest.raises(ValueError, match="seeds"):
            LayoutSampler(kinds=("procedural",), seeds=seeds)
    with pytest.raises(ValueError, match="seed"):
        RandomLayout(gym.make("SemReloc-v22", map_source="perfect"), seed=-1)


def test_sampler_draws_layout_files(tmp_path):
    path = tmp_path / "box.json"
    path.write_text(json.dumps({"name": "box", "outer": [[0, 0], [5, 0], [5, 4], [0, 4]], "walls": []}))
    s = LayoutSampler(kinds=("lab",), files=[path], weights=[0.0, 1.0])
    d = s.draw(np.random.default_rng(0))
    assert d.kind == str(path) and d.layout.name == "box"


def _rollout(env, seeds):
    out = []
    for s in seeds:
        obs, info = env.reset(seed=s)
        o2, *_, i2 = env.step(0)
        out.append((info["layout"], obs["lidar"].copy(), i2["belief"]["mean"]))
    return out


def test_random_layout_wrapper_is_deterministic_and_changes_layouts():
    def make():
        return RandomLayout(gym.make("SemReloc-v22", map_source="perfect", relocalizer={"n_particles": 200}))

    a, b = _rollout(make(), range(6)), _rollout(make(), range(6))
    for (la, oa, ma), (lb, ob, mb) in zip(a, b):
        assert la == lb
        np.testing.assert_array_equal(oa, ob)
        assert ma == mb
    assert len({(la["kind"], la["seed"]) for la, _, _ in a}) > 2
    env = make()
    env.reset(seed=3)
    assert env.unwrapped.layout is env.current.layout
    assert env.unwrapped.grid.shape == rasterize(env.current.layout).shape


@pytest.mark.parametrize(
    "sampler",
    [
        LayoutSampler(kinds=("procedural", "lab"), seeds=[3, 5, 1_000_001], weights=[2, 1]),
        LayoutSampler(kinds=("procedural_sym",), seeds=range(10, 20)),
        {"kinds": ["twin_rooms", "procedural"], "seeds": {"start": 7, "stop": 9}},
    ],
)
def test_random_layout_spec_round_trips_through_json(sampler):
    base = gym.make("SemReloc-v22", map_source="perfect", relocalizer={"n_particles": 200})
    env = RandomLayout(base, sampler, seed=4)
    spec = gym.envs.registration.EnvSpec.from_json(env.spec.to_json())
    again = gym.make(spec)
    assert again.sampler.config() == env.sampler.config()
    for seed in (1, 2, 3):
        (oa, ia), (ob, ib) = env.reset(seed=seed), again.reset(seed=seed)
        assert ia["layout"] == ib["layout"]
        for k in oa:
            np.testing.assert_array_equal(oa[k], ob[k])


def test_sampler_config_names_layout_files_from_anywhere(tmp_path, monkeypatch):
    (tmp_path / "a").mkdir()
    (tmp_path / "a" / "room.json").write_text(json.dumps(get_layout("twin_rooms").to_dict()))
    monkeypatch.chdir(tmp_path / "a")
    config = LayoutSampler(kinds=(), files=["room.json"]).config()
    assert config["files"] == [str((tmp_path / "a" / "room.json").resolve())]
    monkeypatch.chdir(tmp_path)
    draw = LayoutSampler.from_config(config).draw(np.random.default_rng(0))
    assert draw.layout.to_dict() == get_layout("twin_rooms").to_dict()


def test_sampler_config_names_a_search_path_layout_by_its_file(tmp_path, monkeypatch):
    """An outside audit: a name found on $SEMRELOC_LAYOUT_PATH became <cwd>/name in the config, so the env's spec no
    longer made the same env."""
    (tmp_path / "lib").mkdir()
    (tmp_path / "lib" / "hall.json").write_text(json.dumps(get_layout("twin_rooms").to_dict()))
    monkeypatch.setenv("SEMRELOC_LAYOUT_PATH", str(tmp_path / "lib"))
    monkeypatch.chdir(tmp_path)
    config = LayoutSampler(kinds=(), files=["hall"]).config()
    assert config["files"] == [str((tmp_path / "lib" / "hall.json").resolve())]
    base = gym.make("SemReloc-v22", map_source="perfect", relocalizer={"n_particles": 200})
    env = RandomLayout(base, LayoutSampler(kinds=(), files=["hall"]), seed=4)
    again = gym.make(gym.envs.registration.EnvSpec.from_json(env.spec.to_json()))
    (oa, ia), (ob, ib) = env.reset(seed=1), again.reset(seed=1)
    assert ia["layout"]["name"] == ib["layout"]["name"] and ia["layout"]["seed"] == ib["layout"]["seed"]
    for k in oa:
        np.testing.assert_array_equal(oa[k], ob[k])


def test_sampler_config_rejects_bad_input():
    with pytest.raises(ValueError, match="unknown keys"):
        LayoutSampler.from_config({"kinds": ["lab"], "seed": 3})
    with pytest.raises(ValueError, match="seed range"):
        LayoutSampler.from_config({"seeds": {"start": 0}})
    with pytest.raises(ValueError, match="must be a dict"):
        LayoutSampler.from_config([("kinds", ["lab"])])
    env = gym.make("SemReloc-v22", map_source="perfect")
    with pytest.raises(TypeError, match="LayoutSampler or its config"):
        RandomLayout(env, sampler="lab")
    with pytest.raises(ValueError, match="cache_size"):
        RandomLayout(env, cache_size=0)
    with pytest.raises(ValueError, match="unknown"):
        RandomLayout(env, sampler={"kinds": ["nowhere"]})


def test_random_layout_needs_a_layout_free_map(tmp_path):
    env = gym.make("SemReloc-v22", map_source="perfect")
    grid = env.unwrapped.grid
    fixed = gym.make("SemReloc-v22", map_source=grid)
    with pytest.raises(ValueError, match="map_source"):
        RandomLayout(fixed)
    with pytest.raises(ValueError, match="fixed"):
        fixed.unwrapped.set_layout("twin_rooms")


def test_lookalike_rooms_are_identical_and_only_the_corridor_tells_them_apart():
    layout_dict, frames = lookalike_layout(np.random.default_rng(3), ProceduralParams(lookalike=True))
    layout = get_layout(layout_dict)
    assert layout.name == "procedural_lookalike" and len(frames) >= 4
    world = build_world(layout)
    labels = np.array([o.label for o in layout.objects] + [0])  # owner -1 (a wall) -> label 0
    angles = np.linspace(-math.pi, math.pi, 360, endpoint=False)

    def scan(pose, rmax):
        r, hit = world.scene.cast(np.asarray(pose[:2]), pose[2] + angles, rmax)
        return r, labels[np.where(hit >= 0, world.scene.owner[np.maximum(hit, 0)], -1)] * (hit >= 0)

    # a pose in south room 0 and its images in every room see exactly the same all round out to
    # 2.5 m (beyond, rays through the doorway may reach the corridor)
    local = np.array([0.8, 0.8, 0.3])
    scans = []
    for fx, fy, ft in frames:
        c, s = math.cos(ft), math.sin(ft)
        pose = [fx + c * local[0] - s * local[1], fy + s * local[0] + c * local[1], ft + local[2]]
        assert world.is_free(np.array(pose[:2]))
        scans.append(scan(pose, 2.5))
    for r, lab in scans[1:]:
        np.testing.assert_allclose(r, scans[0][0], atol=1e-6)
        np.testing.assert_array_equal(lab, scans[0][1])
    # rooms identical in furniture classes: every room holds the same multiset of classes
    per_room = []
    for fx, fy, ft in frames:
        c, s = math.cos(-ft), math.sin(-ft)
        cls = []
        for o in layout.objects:
            dx, dy = o.centroid() - (fx, fy)
            u, v = c * dx - s * dy, s * dx + c * dy
            if -0.01 < v < 3.0 and 0 < u < frames[1][0] - frames[0][0]:
                cls.append((o.cls, round(u, 2), round(v, 2)))
        per_room.append(sorted(cls))
    assert all(r == per_room[0] for r in per_room)
    # the corridor holds objects outside every room: what tells the rooms apart
    depth = min(y for x, y in (p for w in layout.walls for p in w) if y > 0)
    corridor = [o for o in layout.objects if depth - 0.01 < o.centroid()[1] < layout.bounds()[3] - depth + 0.01]
    assert len(corridor) >= ProceduralParams().corridor_objects[0]
    with pytest.raises(ValueError, match="exclude"):
        ProceduralParams(symmetric=True, lookalike=True)


def _corridor(layout_dict):
    """The corridor objects of a lookalike layout dict (they follow the rooms' objects) and its size."""
    (x0, y0), (x1, _), (_, y1) = layout_dict["outer"][:3]
    depth = min(y for w in layout_dict["walls"] for _, y in w if y > 0)
    objs = [o for o in layout_dict["objects"] if depth - 0.01 < o["center"][1] < y1 - depth + 0.01]
    return objs, x1 - x0, y1 - y0


@pytest.mark.parametrize("seeds", [range(0, 40), range(1_000_000, 1_000_040)])
def test_lookalike_corridor_objects_break_the_half_turn(seeds):
    """Every lookalike layout tells a pose from its half-turned image (the rest of it is symmetric)."""
    default = ProceduralParams(lookalike=True)
    legacy = ProceduralParams(lookalike=True, min_asymmetry_m=0.0)
    changed = 0
    for seed in seeds:
        new, _ = lookalike_layout(np.random.default_rng(seed), default)
        old, _ = lookalike_layout(np.random.default_rng(seed), legacy)
        objs, length, height = _corridor(new)
        assert half_turn_asymmetry(objs, length, height) >= default.min_asymmetry_m
        assert half_turn_asymmetry(new["objects"], length, height) >= default.min_asymmetry_m
        old_asym = half_turn_asymmetry(_corridor(old)[0], length, height)
        if old_asym >= default.min_asymmetry_m:
            assert new == old  # a layout that passed is drawn as before
        else:
            changed += 1
            rooms = [[o for o in d["objects"] if o not in _corridor(d)[0]] for d in (new, old)]
            assert new["walls"] == old["walls"] and rooms[0] == rooms[1]  # only the corridor objects differ
        assert get_layout("procedural_lookalike", seed=seed, procedural_version=1) == get_layout(old)
    assert changed > 0  # version 1 drew symmetric layouts in both ranges


def test_half_turn_asymmetry():
    cab = {"class": "cabinet", "size": [0.35, 0.9]}
    # two cabinets, one the other's image in a 10 m x 6 m layout: symmetric
    pair = [{**cab, "center": [0.2, 3.3]}, {**cab, "center": [9.8, 2.7]}]
    assert half_turn_asymmetry(pair, 10.0, 6.0) == pytest.approx(0.0, abs=1e-12)
    moved = [pair[0], {**cab, "center": [9.8, 2.0]}]
    assert half_turn_asymmetry(moved, 10.0, 6.0) == pytest.approx(0.7)
    other = [pair[0], {**pair[1], "class": "door"}]  # same place, other class: the camera tells them apart
    assert half_turn_asymmetry(other, 10.0, 6.0) == pytest.approx(np.hypot(9.6, 0.6))
    assert half_turn_asymmetry([], 10.0, 6.0) == 0.0
    centre = [{**cab, "center": [5.0, 3.0]}]  # its own image
    assert half_turn_asymmetry(centre, 10.0, 6.0) == 0.0


@pytest.mark.parametrize(
    "kw, match",
    [
        ({"min_asymmetry_m": -1.0}, "min_asymmetry_m"),
        ({"min_asymmetry_m": float("nan")}, "min_asymmetry_m"),
        ({"min_asymmetry_m": True}, "min_asymmetry_m"),
        ({"corridor_objects": (0, 0)}, "symmetric under a half turn"),
    ],
)
def test_lookalike_params_refuse_what_cannot_break_the_half_turn(kw, match):
    with pytest.raises(ValueError, match=match):
        ProceduralParams(lookalike=True, **kw)
    with pytest.raises(ValueError, match="procedural_version"):
        get_layout("procedural_lookalike", seed=0, procedural_version=3)


def test_lookalike_layout_gives_up_with_a_clear_error():
    params = ProceduralParams(lookalike=True, min_asymmetry_m=1e6)
    with pytest.raises(ValueError, match="no draw of corridor objects"):
        lookalike_layout(np.random.default_rng(0), params)


def test_set_layout_changes_the_next_episode_only():
    env = gym.make("SemReloc-v22", layout="lab", map_source="perfect", relocalizer={"n_particles": 100})
    env.reset(seed=0)
    pose = env.unwrapped.world.pose.copy()
    env.unwrapped.set_layout("twin_rooms")
    np.testing.assert_array_equal(env.unwrapped.world.pose, pose)  # running episode untouched
    assert env.unwrapped.layout.name == "twin_rooms"
    _, info = env.reset(seed=0)
    assert env.unwrapped.world.layout.name == "twin_rooms"
    assert 0 <= info["pose"][0] <= 12


def test_a_rejected_random_layout_reset_changes_nothing():
    # The wrapper drew the next layout and swapped the env's map before the env rejected the reset,
    # so the running episode reported (and observed) another layout's map (found in an audit).
    def make():
        return RandomLayout(
            gym.make("SemReloc-v22", map_source="perfect", relocalizer={"n_particles": 200}),
            LayoutSampler(kinds=("lab", "twin_rooms", "procedural"), seeds=range(20)),
        )

    a, b = make(), make()
    for env in (a, b):
        env.reset(seed=3)
        env.step(0)
    base = a.unwrapped
    layout, grid = base.layout, base.grid
    for bad in ({"seed": 2.5}, {"seed": -1}, {"options": {"bogus": 1}}, {"options": {"pose": [np.nan, 0.0, 0.0]}}):
        with pytest.raises(ValueError):
            a.reset(**bad)
        assert base.layout is layout and base.grid is grid
    # a pose that fits one layout and not another names the layout drawn (a new user's trial)
    with pytest.raises(ValueError, match=r"is not free.*\(in the layout drawn for this reset: \w+, seed \d+\)"):
        a.reset(options={"pose": [0.01, 0.01, 0.0]})
    assert base.layout is layout and base.grid is grid
    _, _, _, _, info_a = a.step(0)
    _, _, _, _, info_b = b.step(0)
    assert info_a["layout"] == info_b["layout"]
    np.testing.assert_array_equal(info_a["pose"], info_b["pose"])
    (_, ia), (_, ib) = a.reset(), b.reset()  # the layout stream was not advanced by the failures
    assert ia["layout"] == ib["layout"]


def test_set_layout_rejects_a_map_of_another_place():
    env = gym.make("SemReloc-v22", layout="lab", map_source="perfect", relocalizer={"n_particles": 100})
    lab_grid = env.unwrapped.grid
    twin_grid = gym.make("SemReloc-v22", layout="twin_rooms", map_source="perfect").unwrapped.grid
    with pytest.raises(ValueError):
        env.unwrapped.set_layout("twin_rooms", grid=lab_grid)
    assert env.unwrapped.layout.name == "lab" and env.unwrapped.grid is lab_grid
    env.unwrapped.set_layout("twin_rooms", grid=twin_grid)  # the right map is taken
    assert env.unwrapped.grid is twin_grid
