"""The viewpoint planner: it reads the belief (never the truth), finds nothing to gain between
twins at a place where they look the same, and drives out to where they do not."""

import math

import gymnasium as gym
import numpy as np
import pytest

import semreloc_env  # noqa: F401
from agents.viewpoint import ViewpointPlanner
from semreloc_env.layouts import ProceduralParams, lookalike_layout

SEED = 3  # a lookalike layout seed of the training range


def _env(pol, **kw):
    kw = {"layout": "procedural_lookalike", "layout_seed": SEED, "map_source": "perfect", **kw}
    kw.setdefault("relocalizer", {"n_particles": 300})
    env = pol.wrap(gym.make("SemReloc-v2", max_episode_steps=60, **kw))
    pol.reset()
    return env


def _twins():
    """A pose in the middle of south room 0 and its image in room 1: they see the same room."""
    _, frames = lookalike_layout(np.random.default_rng(SEED), ProceduralParams(lookalike=True))
    u, v, phi = 1.2, 1.2, 0.3
    out = []
    for fx, fy, ft in frames[:2]:
        c, s = math.cos(ft), math.sin(ft)
        out.append([fx + c * u - s * v, fy + s * u + c * v, ft + phi])
    return np.array(out)


class _NoTruth:
    def __getattr__(self, name):
        raise AssertionError(f"the planner read the simulator's world ({name})")


def test_twins_look_alike_here_and_differ_at_the_goal(monkeypatch):
    pol = ViewpointPlanner(seed=0)
    env = _env(pol)
    twins = _twins()
    env.reset(seed=0, options={"pose": twins[0].tolist()})
    monkeypatch.setattr(pol, "hypotheses", lambda: (twins, np.array([0.5, 0.5])))
    base = env.unwrapped
    world, base.world = base.world, _NoTruth()
    try:
        assert pol.plan()
    finally:
        base.world = world
    plan = pol.last_plan
    assert plan["n_hypotheses"] == 2 and not plan["fallback"]
    # the twins are told apart at the goal, which lies out of the room (a path of metres) ...
    assert plan["score"] > 0.5 and plan["path_m"] > 1.0, plan
    assert np.hypot(*(np.array(plan["goal"][:2]) - twins[0, :2])) > 1.0
    # ... while where the robot stands, whichever way it looks, they look the same
    pm = pol._plan_map()
    here = pm.nearest_node(twins[0, :2], 0.3)
    score_here, _ = pol._gains(pm, twins, np.array([0.5, 0.5]), np.array([here]))
    assert score_here.max() < 0.1, score_here
    # the stored path starts near the robot and ends at the goal, in the robot's frame
    assert pol._path.shape[0] >= 2 and np.hypot(*pol._path[0]) < 0.5


def test_one_hypothesis_means_explore():
    pol = ViewpointPlanner(seed=0)
    env = _env(pol, relocalizer={"n_particles": 300, "proposal_frac": 0.0, "augmented": False})
    obs, _ = env.reset(seed=0, options={"pose": _twins()[0].tolist(), "tracking": True})
    assert not pol.plan() and pol.last_plan["fallback"]
    assert pol.act(obs) == pol.explorer(obs)  # the explorer's action (fresh explorer state: same)


def test_an_episode_reads_no_truth_and_repeats_bit_for_bit():
    def run():
        pol = ViewpointPlanner(seed=4)
        env = _env(pol)
        obs, _ = env.reset(seed=5, options={"pose": _twins()[0].tolist()})
        base = env.unwrapped
        actions = []
        for _ in range(40):
            world, base.world = base.world, _NoTruth()
            try:
                a = pol.act(obs)
            finally:
                base.world = world
            actions.append(int(a))
            obs, _, term, trunc, _ = env.step(a)
            if term or trunc:
                break
        return actions

    first = run()
    assert first == run() and set(first) <= {0, 1, 2}


@pytest.mark.parametrize(
    "kw, match",
    [
        ({"horizon_m": 0}, "horizon_m"),
        ({"n_rays": 0}, "n_rays"),
        ({"cost_per_m": -1.0}, "cost_per_m"),
        ({"plan_cell_m": float("nan")}, "plan_cell_m"),
        ({"n_headings": 2.5}, "n_headings"),
    ],
)
def test_bad_settings_are_refused(kw, match):
    with pytest.raises(ValueError, match=match):
        ViewpointPlanner(**kw)


def test_needs_a_semreloc_env():
    with pytest.raises(TypeError, match="SemReloc"):
        ViewpointPlanner().wrap(gym.make("CartPole-v1"))


def test_paths_run_every_way_from_every_room():
    """The planning graph holds each edge both ways: from the top right corner of the map a
    horizon of 100 m reaches its whole component (a one-way graph reached 95 cells from a north
    room, so the planner never planned out of one)."""
    from scipy.sparse import csgraph

    pol = ViewpointPlanner(seed=0)
    env = _env(pol)
    env.reset(seed=0)
    pm = pol._plan_map()
    assert (pm.graph != pm.graph.T).nnz == 0
    corner = int(np.argmax(pm.xy[:, 0] + pm.xy[:, 1]))
    _, comp = csgraph.connected_components(pm.graph, directed=False)
    dist = csgraph.dijkstra(pm.graph, indices=corner, limit=100.0)
    assert np.isfinite(dist).sum() == (comp == comp[corner]).sum() > 1000


def test_start_turn_charges_turning_onto_the_path():
    """A goal behind the robot costs the half turn onto its path (at its driving equivalent); a
    goal straight ahead costs no such turn."""
    from scipy.sparse import csgraph

    pol = ViewpointPlanner(seed=0)
    env = _env(pol)
    twin = _twins()[0]
    env.reset(seed=0, options={"pose": twin.tolist()})
    pm = pol._plan_map()
    s = pm.nearest_node(twin[:2], 0.3)
    dist, pred = csgraph.dijkstra(pm.graph, indices=s, limit=8.0, return_predecessors=True)
    heading = float(twin[2])
    way = np.array([math.cos(heading), math.sin(heading)])
    ahead = pm.nearest_node(pm.xy[s] + 1.5 * way, 0.3)  # over 1 m of path: the walk back runs
    behind = pm.nearest_node(pm.xy[s] - 0.8 * way, 0.3)
    cand = np.array([ahead, behind])
    assert (cand >= 0).all() and np.isfinite(dist[cand]).all() and dist[ahead] > 1.0
    goal_h = np.zeros(2)
    with_turn = pol._turn_cost_m(pm, pred, dist, s, cand, goal_h, heading)
    pol.start_turn = False
    without = pol._turn_cost_m(pm, pred, dist, s, cand, goal_h, heading)
    half_turn_m = math.pi / pol.step_rad * pol.step_m
    extra = with_turn - without
    assert extra[0] < 0.25 * half_turn_m and abs(extra[1] - half_turn_m) < 0.25 * half_turn_m, (extra, half_turn_m)


def test_forward_is_blocked_by_what_the_disc_would_touch():
    """The safety check covers the robot's width: a return beside the front (bearing -1.26 rad,
    0.22 m) blocks a forward step; one 0.5 m to the side or 0.5 m ahead does not."""
    pol = ViewpointPlanner(seed=0)
    env = _env(pol)
    env.reset(seed=0)
    angles = np.asarray(env.unwrapped.lidar.angles)

    def scan(bearing, r):
        ranges = np.full(angles.size, 8.0)
        ranges[int(np.argmin(np.abs(wrap(angles - bearing))))] = r
        return ranges

    def wrap(a):
        return (a + np.pi) % (2 * np.pi) - np.pi

    assert pol._blocked(scan(-1.26, 0.22))
    assert pol._blocked(scan(0.0, 0.25))
    assert not pol._blocked(scan(1.4, 0.5))
    assert not pol._blocked(scan(0.0, 0.5))
    assert not pol._blocked(scan(math.pi, 0.1))


def test_turning_on_the_spot_earns_no_lidar_gain_without_lidar_on_rotation():
    """With the camera off and the relocalizer leaving the lidar out of rotation-only updates
    (SemReloc-v2's default), turning where the robot stands cannot tell hypotheses apart: the
    planner predicts no gain for it, though driving to the same places would."""
    pol = ViewpointPlanner(seed=0)
    env = _env(pol, relocalizer={"n_particles": 300, "use_semantic": False})
    assert not env.unwrapped.mcl_config.lidar_on_rotation
    twins = _twins()
    env.reset(seed=0, options={"pose": twins[0].tolist()})
    pm = pol._plan_map()
    cand = np.nonzero(pm.rc[:, 0] % 4 == 0)[0][::7]
    w = np.array([0.5, 0.5])
    moving, _ = pol._gains(pm, twins, w, cand, stay=np.zeros(cand.size, bool))
    turning, _ = pol._gains(pm, twins, w, cand, stay=np.ones(cand.size, bool))
    # where both twins' images of a place are free: nothing rules either out, so no gain
    ref = twins[0]
    c0, s0 = math.cos(ref[2]), math.sin(ref[2])
    d = pm.xy[cand] - ref[:2]
    u = np.stack([c0 * d[:, 0] + s0 * d[:, 1], -s0 * d[:, 0] + c0 * d[:, 1]], axis=1)
    free = np.ones(cand.size, bool)
    for x, y, th in twins:
        img = np.stack(
            [x + math.cos(th) * u[:, 0] - math.sin(th) * u[:, 1], y + math.sin(th) * u[:, 0] + math.cos(th) * u[:, 1]],
            1,
        )
        free &= env.unwrapped.grid.is_free(img)
    assert free.sum() > 20 and moving[free].max() > 0.5
    assert np.all(turning[free] == 0.0)
