"""procedural_ring: a ring corridor round a solid core whose four quarters look alike."""

import math

import numpy as np
import pytest

from semreloc_env.layout_sampling import HELD_OUT_LAYOUT_SEEDS, LayoutSampler
from semreloc_env.layouts import RingParams, get_layout, quarter_turn_asymmetry, ring_layout
from semreloc_env.world import build_world


def _turn(xy, side):
    return np.array([side - xy[1], xy[0]])


def test_same_seed_same_layout_and_a_valid_ring():
    a, b = ring_layout(np.random.default_rng(5)), ring_layout(np.random.default_rng(5))
    assert a == b
    assert ring_layout(np.random.default_rng(6)) != a
    layout = get_layout("procedural_ring", seed=5)
    assert layout.name == "procedural_ring" and len(layout.blocks) == 1 and not layout.walls
    x0, x1, y0, y1 = layout.bounds()
    side = x1 - x0
    core = np.asarray(layout.blocks[0])
    corridor = core[:, 0].min()
    assert 2.5 <= corridor <= 3.5 and 10.0 <= side <= 14.0
    world = build_world(layout)
    assert not world.is_free(np.array([side / 2, side / 2]))
    # the corridor is a loop: one point in each quarter is free, at mid-corridor
    for k in range(4):
        p = np.array([side / 2, corridor / 2])
        for _ in range(k):
            p = _turn(p, side)
        assert world.is_free(p, margin_m=0.1)


@pytest.mark.parametrize("seed", range(40))
def test_furniture_is_quarter_turn_symmetric_but_the_telling_objects_break_every_turn(seed):
    d = ring_layout(np.random.default_rng(seed))
    side = d["outer"][1][0]
    objs = d["objects"]
    centres = np.array([o["center"] for o in objs])
    classes = [o["class"] for o in objs]
    # objects whose every quarter-turned image is an object of the same class: the furniture
    sym = []
    for o in objs:
        c = np.array(o["center"])
        ok = True
        for _ in range(3):
            c = _turn(c, side)
            d2 = np.hypot(*(centres - c).T)
            j = int(np.argmin(d2))
            ok &= d2[j] < 1e-9 and classes[j] == o["class"]
        sym.append(ok)
    assert sum(sym) % 4 == 0 and not all(sym)
    assert quarter_turn_asymmetry(objs, side) >= RingParams().min_asymmetry_m
    # independently: every turn moves some telling object 1 m or more from every object of its class
    for k in (1, 2, 3):
        far = []
        for o, is_sym in zip(objs, sym):
            if is_sym:
                continue
            c = np.array(o["center"])
            for _ in range(k):
                c = _turn(c, side)
            same = centres[[cl == o["class"] for cl in classes]]
            far.append(np.min(np.hypot(*(same - c).T)) >= 1.0)
        assert any(far)
    get_layout("procedural_ring", seed=seed)  # validates: no overlaps, all inside


def test_quarter_turn_asymmetry_by_hand():
    side = 10.0
    four = [{"class": "chair", "center": c} for c in ([2.0, 1.0], [9.0, 2.0], [8.0, 9.0], [1.0, 8.0])]
    assert quarter_turn_asymmetry(four, side) == pytest.approx(0.0, abs=1e-12)
    one = four + [{"class": "cabinet", "center": [5.0, 0.5]}]
    # the cabinet's images lie 4.5-9 m from it; the chairs map onto chairs
    assert quarter_turn_asymmetry(one, side) == pytest.approx(math.hypot(4.5, 4.5))
    assert quarter_turn_asymmetry([], side) == 0.0


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"corridor_m": (1.0, 2.0)}, "corridor_m"),
        ({"side_m": (6.0, 7.0)}, "core of at least 1 m"),
        ({"telling_objects": (0, 1)}, "at least one telling object"),
        ({"objects_per_quarter": (2, 1)}, "objects_per_quarter"),
        ({"objects_per_quarter": (1, 2, 3)}, "objects_per_quarter must be two integers"),
        ({"min_asymmetry_m": float("nan")}, "min_asymmetry_m"),
    ],
)
def test_bad_ring_params(kwargs, message):
    with pytest.raises(ValueError, match=message):
        RingParams(**kwargs)


def test_sampler_draws_rings_but_never_a_held_out_seed():
    s = LayoutSampler(kinds=["procedural_ring"], seeds=range(999_990, 1_000_010))
    rng = np.random.default_rng(0)
    draws = [s.draw(rng) for _ in range(200)]
    assert {d.kind for d in draws} == {"procedural_ring"}
    assert not {d.seed for d in draws} & set(HELD_OUT_LAYOUT_SEEDS)


def test_evaluate_active_adds_ring_cases_after_the_others_and_flags_lookalike_starts():
    from agents.experiments.evaluate_active import Args, _view, build_cases
    from semreloc_env.config import CameraParams, LidarParams

    base = build_cases(Args(layouts_per_kind=1, starts=2))
    more = build_cases(Args(layouts_per_kind=1, starts=2, ring_layouts=2))
    assert more[: len(base)] == base
    ring = more[len(base) :]
    assert {c["kind"] for c in ring} == {"procedural_ring"} and len(ring) == 4
    flagged = [c for c in ring if c["uninformative"]]
    assert flagged
    angles = np.linspace(-math.pi, math.pi, 360, endpoint=False)
    lmax, cmax = LidarParams().range_max_m, CameraParams().range_max_m
    for c in flagged:  # some quarter-turned image of the start sees exactly what the start sees
        world = build_world(get_layout("procedural_ring", seed=c["layout_seed"]))
        side = world.layout.bounds()[1]
        pose = np.array(c["start"])
        r0, l0 = _view(world, pose, lmax, cmax, angles)
        same = []
        q = pose.copy()
        for _ in range(3):
            q = np.array([*_turn(q[:2], side), q[2] + math.pi / 2])
            r1, l1 = _view(world, q, lmax, cmax, angles)
            same.append(np.allclose(r0, r1, atol=1e-6) and np.array_equal(l0, l1))
        assert any(same)


def test_ring_params_types_and_an_honest_error_when_nothing_fits():
    # a new user's trial: infinite or string ranges failed deep inside NumPy, numpy ints were refused
    for kwargs, match in [
        ({"side_m": (10.0, math.inf)}, "side_m must be two finite numbers"),
        ({"side_m": ("10", "12")}, "side_m must be two finite numbers"),
        ({"objects_per_quarter": (True, True)}, "objects_per_quarter"),
    ]:
        with pytest.raises(ValueError, match=match):
            RingParams(**kwargs)
    RingParams(objects_per_quarter=(np.int64(1), np.int64(2)), min_asymmetry_m=np.float32(1.0))
    tight = RingParams(side_m=(5.0, 5.0), corridor_m=(2.0, 2.0), objects_per_quarter=(3, 3))
    errors = []
    for seed in range(30):
        try:
            ring_layout(np.random.default_rng(seed), tight)
        except ValueError as e:
            errors.append(str(e))
    assert any("no room for a telling object" in e for e in errors)  # not "broke every quarter turn" then
    assert all("no room for a telling object" in e or "broke every quarter turn" in e for e in errors)
