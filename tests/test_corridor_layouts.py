"""procedural_corridor: a long corridor whose furniture repeats at one period, told apart by a few objects."""

import math

import numpy as np
import pytest

from semreloc_env.layout_sampling import HELD_OUT_LAYOUT_SEEDS, LayoutSampler
from semreloc_env.layouts import CorridorParams, corridor_layout, get_layout, period_shift_distance
from semreloc_env.world import build_world


def _period(d):
    """The period, recovered independently of the generator: of the x distances (within
    `CorridorParams.period_m`) between two pieces of one class on one wall, the one that most pieces have."""
    objs = d["objects"]
    lo, hi = CorridorParams().period_m
    gaps = [
        round(b["center"][0] - a["center"][0], 6)
        for a in objs
        for b in objs
        if a["class"] == b["class"]
        and a["center"][1] == b["center"][1]
        and lo - 1e-6 <= b["center"][0] - a["center"][0] <= hi + 1e-6
    ]
    return max(sorted(set(gaps)), key=gaps.count) if gaps else None


@pytest.mark.parametrize("seed", [3, 11, 1_000_004])
def test_same_seed_same_layout_and_a_valid_open_corridor(seed):
    a, b = corridor_layout(np.random.default_rng(seed)), corridor_layout(np.random.default_rng(seed))
    assert a == b
    assert corridor_layout(np.random.default_rng(seed + 1)) != a
    layout = get_layout("procedural_corridor", seed=seed)
    assert layout.name == "procedural_corridor" and not layout.walls and not layout.blocks
    x0, x1, y0, y1 = layout.bounds()
    p = CorridorParams()
    assert p.length_m[0] <= x1 - x0 <= p.length_m[1] and p.width_m[0] <= y1 - y0 <= p.width_m[1]
    world = build_world(layout)
    # passable end to end: no two pieces overlap along the corridor, so a line of free points runs through
    spans = sorted((o["center"][0] - o["size"][0] / 2, o["center"][0] + o["size"][0] / 2) for o in a["objects"])
    assert all(s1[1] + 0.3 <= s2[0] + 1e-9 for s1, s2 in zip(spans, spans[1:]))
    for x in np.linspace(x0 + 0.5, x1 - 0.5, 60):
        assert any(world.is_free(np.array([x, y]), margin_m=0.25) for y in np.linspace(y0 + 0.3, y1 - 0.3, 12))


@pytest.mark.parametrize("seed", range(40))
def test_furniture_repeats_and_a_telling_object_breaks_every_shift(seed):
    d = corridor_layout(np.random.default_rng(seed))
    get_layout("procedural_corridor", seed=seed)  # validates: inside, no overlaps
    objs = d["objects"]
    period = _period(d)
    assert period is not None and CorridorParams().period_m[0] - 1e-9 <= period <= CorridorParams().period_m[1]

    # a piece is furniture if a piece of its class and wall lies a whole number of periods away
    def shifted_twin(o):
        def whole_periods(dx):
            return abs(round(dx / period) * period - dx) < 1e-6

        return any(
            p is not o
            and p["class"] == o["class"]
            and p["center"][1] == o["center"][1]
            and whole_periods(p["center"][0] - o["center"][0])
            for p in objs
        )

    lone = [o for o in objs if not shifted_twin(o)]
    assert 1 <= len(lone) <= CorridorParams().telling_objects[1]

    # independently of period_shift_distance: each lone object keeps 1 m from every whole-period shift of its class
    def far(o):
        x, y = o["center"]
        for p in objs:
            if p is o or p["class"] != o["class"]:
                continue
            for k in range(-20, 21):
                if math.hypot(x - p["center"][0] - k * period, y - p["center"][1]) < 1.0 - 1e-9:
                    return False
        return True

    assert all(far(o) for o in lone)


def test_period_shift_distance_by_hand_and_a_bad_period():
    chairs = [{"class": "chair", "center": [1.0 + 4.0 * k, 0.5]} for k in range(5)]
    assert period_shift_distance({"class": "chair", "center": [9.0, 0.5]}, chairs, 4.0) == pytest.approx(0.0, abs=1e-12)
    # 1.5 m past a chair and 2.5 m before the next: 1.5; beyond the last chair the shifts go on
    assert period_shift_distance({"class": "chair", "center": [6.5, 0.5]}, chairs, 4.0) == pytest.approx(1.5)
    far_off = {"class": "chair", "center": [40.0, 1.5]}
    assert period_shift_distance(far_off, chairs, 4.0) == pytest.approx(math.hypot(1.0, 1.0))
    assert period_shift_distance({"class": "door", "center": [9.0, 0.5]}, chairs, 4.0) == math.inf
    for bad in (0.0, -4.0, math.nan, math.inf, "4"):
        with pytest.raises(ValueError, match="period must be a finite number > 0"):
            period_shift_distance(far_off, chairs, bad)


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"width_m": (1.5, 2.5)}, "at least 2 m wide"),
        ({"period_m": (1.0, 2.0)}, "at least 1.5 m"),
        ({"length_m": (8.0, 30.0)}, "two of the longest periods"),
        ({"length_m": (20.0, math.inf)}, "two finite numbers"),
        ({"length_m": ("20", "30")}, "two finite numbers"),
        ({"width_m": (3.0, 2.5)}, "0 < lo <= hi"),
        ({"telling_objects": (0, 1)}, "at least one telling object"),
        ({"objects_per_period": (2, 1)}, "objects_per_period"),
        ({"objects_per_period": (True, True)}, "objects_per_period"),
        ({"objects_per_period": (1, 2, 3)}, "objects_per_period must be two integers"),
        ({"objects_per_period": 3}, "objects_per_period must be two integers"),
        ({"telling_objects": None}, "telling_objects must be two integers"),
        ({"telling_objects": (1, 10**9)}, "hi <= 20"),
        ({"length_m": (20.0, 1e300)}, "at most 1000.0 m long"),
        ({"min_asymmetry_m": float("nan")}, "min_asymmetry_m"),
    ],
)
def test_bad_corridor_params(kwargs, message):
    with pytest.raises(ValueError, match=message):
        CorridorParams(**kwargs)


def test_crowded_periods_still_get_a_telling_object_or_an_honest_error():
    crowded = CorridorParams(period_m=(2.0, 2.2), objects_per_period=(3, 3), length_m=(18.0, 20.0))
    made = 0
    for seed in range(20):  # a telling object may take the place of a piece of furniture
        try:
            d = corridor_layout(np.random.default_rng(seed), crowded)
        except ValueError as e:
            assert "no telling object found room" in str(e)
            continue
        get_layout(d)
        made += 1
        period = _period(d)  # the telling object(s) keep their distance in crowded periods too
        telling = [
            o for o in d["objects"] if period_shift_distance(o, [q for q in d["objects"] if q is not o], period) > 0.5
        ]
        assert telling and all(
            period_shift_distance(o, [q for q in d["objects"] if q is not o], period) >= 1.0 - 1e-9 for o in telling
        )
    assert 10 <= made < 20  # seed 4 draws a period too crowded for one


def test_no_furniture_left_is_not_a_crash():
    # every telling object may take a piece's place until none is left, or there is none to begin with
    for params in (
        CorridorParams(telling_objects=(20, 20)),
        CorridorParams(objects_per_period=(0, 0), telling_objects=(5, 5), min_asymmetry_m=50.0),
    ):
        for seed in range(5):
            d = corridor_layout(np.random.default_rng(seed), params)
            get_layout(d)


def test_sampler_draws_corridors_but_never_a_held_out_seed():
    s = LayoutSampler(kinds=["procedural_corridor"], seeds=range(999_990, 1_000_010))
    rng = np.random.default_rng(0)
    draws = [s.draw(rng) for _ in range(100)]
    assert {d.kind for d in draws} == {"procedural_corridor"}
    assert not {d.seed for d in draws} & set(HELD_OUT_LAYOUT_SEEDS)


def test_evaluate_active_corridor_layouts_argument():
    from agents.experiments.evaluate_active import Args, build_cases

    for kwargs, match in [
        ({"corridor_layouts": -1}, "corridor_layouts must be >= 0"),
        ({"corridor_layouts": 501}, "corridor_layouts: at most 500 held-out seeds"),
        ({"seed_set": "tuning", "layouts_per_kind": 0}, "corridor_layouts"),
        ({"layouts_per_kind": 0, "builtin_layouts": False}, "--corridor-layouts"),
    ]:
        with pytest.raises(ValueError, match=match):
            Args(**kwargs)
    tuning = build_cases(Args(seed_set="tuning", layouts_per_kind=0, corridor_layouts=2, starts=1))
    assert [c["layout_seed"] for c in tuning] == [0, 1] and {c["kind"] for c in tuning} == {"procedural_corridor"}
    held = build_cases(Args(layouts_per_kind=0, builtin_layouts=False, corridor_layouts=2, starts=1))
    assert [c["layout_seed"] for c in held] == list(HELD_OUT_LAYOUT_SEEDS[:2])


def test_evaluate_active_adds_corridor_cases_last_and_flags_starts_a_shift_sees_alike():
    from agents.experiments.evaluate_active import Args, _view, build_cases
    from semreloc_env.config import CameraParams, LidarParams

    base = build_cases(Args(layouts_per_kind=1, starts=2, ring_layouts=1))
    more = build_cases(Args(layouts_per_kind=1, starts=2, ring_layouts=1, corridor_layouts=3))
    assert more[: len(base)] == base
    corr = more[len(base) :]
    assert {c["kind"] for c in corr} == {"procedural_corridor"} and len(corr) == 6
    flagged = [c for c in corr if c["uninformative"]]
    assert flagged
    angles = np.linspace(-math.pi, math.pi, 360, endpoint=False)
    lmax, cmax = LidarParams().range_max_m, CameraParams().range_max_m
    for c in flagged:  # some shift of the start along the corridor sees exactly what the start sees
        world = build_world(get_layout("procedural_corridor", seed=c["layout_seed"]))
        pose = np.array(c["start"])
        r0, l0 = _view(world, pose, lmax, cmax, angles)
        period = _period(corridor_layout(np.random.default_rng(c["layout_seed"])))
        same = False
        for k in [*range(-12, 0), *range(1, 13)]:
            q = pose + (k * period, 0.0, 0.0)
            if not world.is_free(q[:2], 0.3):
                continue
            r1, l1 = _view(world, q, lmax, cmax, angles)
            if np.allclose(r0, r1, atol=1e-6) and np.array_equal(l0, l1):
                same = True
                break
        assert same


def test_a_corridor_env_runs_the_same_episode_from_the_same_seeds():
    import gymnasium as gym

    def episode():
        env = gym.make("SemReloc-v22", layout="procedural_corridor", layout_seed=7, relocalizer={"n_particles": 300})
        obs, info = env.reset(seed=3)
        out = [info["pose"].tolist(), env.unwrapped.mcl.poses.tobytes()]
        for a in [0] * 10 + [1] * 5:
            obs, r, term, trunc, info = env.step(a)
            out.append((r, info["pose"].tolist(), obs["lidar"].tobytes(), env.unwrapped.mcl.poses.tobytes()))
        env.close()
        return out

    assert episode() == episode()
