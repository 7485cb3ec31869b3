"""Property-based tests (Hypothesis) of layout validation, the world and the sensors.

Random valid layouts are built valid by construction: a rectangular (or L-shaped) outer wall
cut into 2 m cells, interior walls along cell lines, at most one furniture polygon strictly
inside each cell (so nothing overlaps or crosses a wall). Runtime is kept to a few tens of
seconds; ``scripts/soak.py`` (`semreloc_env.tools.soak`) runs the same checks for millions of steps.
"""

import copy
import math

import gymnasium as gym
import numpy as np
import pytest
from helpers import assert_identical
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import semreloc_env  # noqa: F401
from semreloc_env.layouts import CLASS_NAMES, LayoutError, layout_from_dict
from semreloc_env.tools.soak import all_finite as _finite

CELL = 2.0
# derandomize: the suite stays deterministic; scripts/soak.py explores further
SETTINGS = settings(max_examples=20, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
ENVS = {
    "SemSlam-v2": {"slam": {"n_particles": 10}},
    "SemReloc-v22": {"map_source": "perfect", "relocalizer": {"n_particles": 100}},
}


@st.composite
def valid_layouts(draw) -> dict:
    """A valid layout dict: outer wall, walls on cell lines, one rotated polygon per chosen cell."""
    nx, ny = draw(st.integers(2, 5)), draw(st.integers(2, 4))
    w, h = nx * CELL, ny * CELL
    if draw(st.booleans()) and nx >= 3 and ny >= 3:  # L-shape: cut the north-east cell block
        cx, cy = draw(st.integers(2, nx - 1)), draw(st.integers(2, ny - 1))
        outer = [[0, 0], [w, 0], [w, cy * CELL], [cx * CELL, cy * CELL], [cx * CELL, h], [0, h]]
        cut = {(i, j) for i in range(cx, nx) for j in range(cy, ny)}
    else:
        outer = [[0, 0], [w, 0], [w, h], [0, h]]
        cut = set()
    cells = [(i, j) for i in range(nx) for j in range(ny) if (i, j) not in cut]
    walls = []
    for _ in range(draw(st.integers(0, 3))):  # a wall along an inner vertical cell line, one cell long
        i, j = draw(st.sampled_from(cells))
        if i >= 1 and (i - 1, j) in cells:
            walls.append([[i * CELL, j * CELL], [i * CELL, (j + 0.5) * CELL]])
    objects = []
    for i, j in draw(st.lists(st.sampled_from(cells), unique=True, max_size=6)):
        cls = draw(st.sampled_from(CLASS_NAMES))
        n = draw(st.integers(3, 6))
        radius = draw(st.floats(0.1, 0.45))
        phase = draw(st.floats(0, 2 * math.pi))
        ang = phase + 2 * math.pi * np.arange(n) / n
        c = ((i + 0.5) * CELL, (j + 0.5) * CELL)
        poly = [[c[0] + radius * math.cos(a), c[1] + radius * math.sin(a)] for a in ang]
        objects.append({"class": cls, "polygon": poly, "name": f"o{i}_{j}"})
    return {"name": "hyp", "outer": outer, "walls": walls, "objects": objects}


@SETTINGS
@given(data=valid_layouts(), env_id=st.sampled_from(sorted(ENVS)), seed=st.integers(0, 2**31 - 1), cont=st.booleans())
def test_valid_layouts_reset_and_step_with_the_robot_outside_every_shape(data, env_id, seed, cont):
    layout_from_dict(data)
    env = gym.make(env_id, layout=data, action_type="continuous" if cont else "discrete", **ENVS[env_id])
    obs, info = env.reset(seed=seed)
    world = env.unwrapped.world
    r = world.robot_params.radius_m
    rng = np.random.default_rng(seed)
    assert env.observation_space.contains(obs) and _finite(info)
    for _ in range(25):
        action = rng.uniform(-1, 1, 2).astype(np.float32) if cont else int(rng.integers(0, 4))
        obs, reward, term, trunc, info = env.step(action)
        assert env.observation_space.contains(obs), "observation outside its space"
        assert math.isfinite(reward) and _finite(info) and _finite(obs)
        assert world.clearance(world.pose[:2]) >= r - 1e-6, "robot closer to a shape than its radius"
        if term or trunc:
            break


def _mutations(data: dict) -> list:
    """(name, mutate(dict) -> entry named in the error) pairs that make ``data`` invalid."""
    muts = [
        ("outer string", lambda d: (d["outer"][1].__setitem__(0, "8"), "outer")[1]),
        ("outer nan", lambda d: (d["outer"][2].__setitem__(1, math.nan), "outer")[1]),
        ("outer bow-tie", lambda d: (d.__setitem__("outer", [[0, 0], [4, 4], [4, 0], [0, 4]]), "outer")[1]),
        ("top key", lambda d: (d.__setitem__("furniture", []), "furniture")[1]),
    ]
    for k, o in enumerate(data["objects"]):
        name = f"objects[{k}]"

        def out(d, k=k):
            d["objects"][k]["polygon"] = [[x + 1000.0, y] for x, y in d["objects"][k]["polygon"]]
            return f"objects[{k}]"

        def bowtie(d, k=k):  # convex polygon: swapping vertices 1 and 2 makes edges 0-2 and 1-3 cross
            p = d["objects"][k]["polygon"]
            p[1], p[2] = p[2], p[1]
            return f"objects[{k}]"

        def overlap(d, k=k):
            twin = copy.deepcopy(d["objects"][k])
            twin["polygon"] = [[x + 0.05, y] for x, y in twin["polygon"]]
            twin["name"] = "twin"
            d["objects"].append(twin)
            return "(twin)"

        def through(d, k=k):
            c = np.mean(d["objects"][k]["polygon"], axis=0)
            d["walls"].append([[c[0] - 0.6, c[1]], [c[0] + 0.6, c[1]]])
            return f"walls[{len(d['walls']) - 1}]"

        def cls(d, k=k):
            d["objects"][k]["class"] = "sofa"
            return f"objects[{k}]"

        def inf(d, k=k):
            d["objects"][k]["polygon"][0][1] = math.inf
            return f"objects[{k}]"

        muts += [(f"{name} bow-tie", bowtie)] if len(o["polygon"]) >= 4 else []
        muts += [
            (f"{name} outside", out),
            (f"{name} overlap", overlap),
            (f"{name} wall through", through),
            (f"{name} class", cls),
            (f"{name} inf", inf),
        ]
    return muts


@settings(max_examples=80, deadline=None, derandomize=True)
@given(data=valid_layouts(), pick=st.integers(0, 10**6))
def test_random_mutations_give_a_layout_error_naming_the_entry(data, pick):
    muts = _mutations(data)
    label, mutate = muts[pick % len(muts)]
    bad = copy.deepcopy(data)
    entry = mutate(bad)
    with pytest.raises(LayoutError) as e:
        layout_from_dict(bad)
    assert entry in str(e.value), f"{label}: {e.value}"
    layout_from_dict(data)  # the original is still valid: the mutation made the difference


REJECTED_CALLS = [
    ("step", "invalid action", lambda env: env.step(7)),
    ("step", "action outside box", lambda env: env.step(np.array([1.5, 0.0]))),
    ("reset", "pose in a wall", lambda env: env.reset(options={"pose": [-1.0, 1.0, 0.0]})),
    ("reset", "pose string", lambda env: env.reset(options={"pose": "0 0 0"})),
    ("reset", "unknown option", lambda env: env.reset(options={"poses": None})),
    ("reset", "bad seed", lambda env: env.reset(seed=-3)),
    ("reset", "options not a dict", lambda env: env.reset(options=3)),
]


@SETTINGS
@given(
    env_id=st.sampled_from(sorted(ENVS)),
    seed=st.integers(0, 2**31 - 1),
    before=st.integers(0, 8),
    call=st.sampled_from(REJECTED_CALLS),
)
def test_a_rejected_call_leaves_the_next_steps_bit_identical_to_a_twin(env_id, seed, before, call):
    kw = {"layout": "twin_rooms", "max_episode_steps": 10, **ENVS[env_id]}
    a, b = gym.make(env_id, **kw), gym.make(env_id, **kw)
    out_a, out_b = [a.reset(seed=seed)], [b.reset(seed=seed)]
    rng = np.random.default_rng(seed)
    actions = rng.integers(0, 4, before + 12)
    for act in actions[:before]:
        out_a.append(a.step(int(act)))
        out_b.append(b.step(int(act)))
    with pytest.raises(ValueError):
        call[2](a)
    for act in actions[before:]:  # including the time limit's truncation at step 10
        sa, sb = a.step(int(act)), b.step(int(act))
        out_a.append(sa)
        out_b.append(sb)
        if sa[2] or sa[3]:
            break
    assert_identical(out_a, out_b)
    assert out_a[-1][3] or out_a[-1][2], "the episode must end at the time limit, as in the twin"
