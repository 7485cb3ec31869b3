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
    env = pol.wrap(gym.make("SemReloc-v22", max_episode_steps=60, **kw))
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
    # with continuous actions, the explorer's steps are sent as (1, 0) / (0, +-1)
    pol = ViewpointPlanner(seed=0)
    quiet = {"n_particles": 300, "proposal_frac": 0.0, "augmented": False}
    env = _env(pol, relocalizer=quiet, action_type="continuous")
    obs, _ = env.reset(seed=0, options={"pose": _twins()[0].tolist(), "tracking": True})
    want = {0: [1.0, 0.0], 1: [0.0, 1.0], 2: [0.0, -1.0]}[pol.explorer(obs)]
    pol.explorer.reset()
    a = pol.act(obs)
    assert pol.last_plan["fallback"] and env.action_space.contains(a) and a.tolist() == want


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
        ({"arc_max_rad": 0}, "arc_max_rad"),
        ({"arc_final_m": -0.1}, "arc_final_m"),
        ({"reverse_rad": 1.5}, "reverse_rad"),
        ({"reverse_rad": 3.5}, "reverse_rad"),
        ({"reverse_rad": float("nan")}, "reverse_rad"),
        ({"reverse_max_m": 0.0}, "reverse_max_m"),
        ({"reverse_max_m": float("nan")}, "reverse_max_m"),
        ({"max_blocked_turns": -1}, "max_blocked_turns"),
        ({"max_blocked_turns": 2.5}, "max_blocked_turns"),
        ({"max_blocked_turns": True}, "max_blocked_turns"),
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


def test_safety_turns_on_one_spot_make_the_planner_explore():
    """A plan whose path the lidar keeps blocking: each safety turn plans again, and after
    ``max_blocked_turns`` of them within `STUCK_M` of the first the planner explores instead (a livelock
    traced on a held-out look-alike layout: 90 steps of turning on the spot). Turns farther apart start a
    new count; 0 turns the rule off."""
    from agents.viewpoint import STUCK_M

    pol = ViewpointPlanner(seed=0, max_blocked_turns=3)  # an option, off by default
    env = _env(pol)
    obs, _ = env.reset(seed=0)
    pol.act(obs)
    ahead = np.asarray(obs["lidar"], dtype=np.float64).copy()
    angles = np.asarray(env.unwrapped.lidar.angles)
    ahead[np.abs(angles) < 0.3] = 0.2  # something right in front of the robot
    blocked = dict(obs, lidar=ahead.astype(np.float32))
    pol._exploring, pol._since_plan = False, 0
    pol._path = np.array([[1.0, 0.0], [2.0, 0.0]])  # a path straight ahead, through it
    pol._goal_heading = 0.0
    for k in range(1, 3):
        pol._pose = np.zeros(3)
        pol._exploring, pol._since_plan = False, 0
        pol._decide(blocked, pol._follow)
        assert pol._blocked_turns == k and pol._since_plan == pol.replan_every
    pol._pose, pol._exploring, pol._since_plan = np.zeros(3), False, 0
    pol._decide(blocked, pol._follow)
    assert pol._exploring and pol._since_plan == 0 and pol._blocked_turns == 0
    # that exploration runs its course: a safety turn of the explorer's (a return beside the front, which its
    # own look ahead does not see) neither cuts it short nor counts
    beside = np.full(angles.size, 8.0)
    beside[int(np.argmin(np.abs(angles + 1.26)))] = 0.22
    beside_obs = dict(obs, lidar=beside.astype(np.float32))
    assert pol.explorer(beside_obs) == 0 and pol._blocked(beside)
    for k in range(1, pol.explore_steps):
        pol._since_plan = k
        assert pol._decide(beside_obs, pol._follow) in (1, 2)  # the safety turn
        assert pol._exploring and pol._since_plan == k and pol._blocked_turns == 0
    # a turn elsewhere starts a new count
    pol._count_blocked_turn()
    pol._odo = pol._odo + np.array([STUCK_M + 0.1, 0.0, 0.0])
    pol._count_blocked_turn()
    assert pol._blocked_turns == 1
    off = ViewpointPlanner(seed=0, max_blocked_turns=0)
    off._exploring = False
    for _ in range(10):
        off._count_blocked_turn()
    assert off._blocked_turns == 0 and not off._exploring


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
    (SemReloc-v22's default), turning where the robot stands cannot tell hypotheses apart: the
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


def _drive(pol, steps=60, **kw):
    """Actions of one episode from twin 0 (the world hidden while the planner acts)."""
    env = _env(pol, **kw)
    obs, _ = env.reset(seed=5, options={"pose": _twins()[0].tolist()})
    base = env.unwrapped
    actions = []
    for _ in range(steps):
        world, base.world = base.world, _NoTruth()
        try:
            a = pol.act(obs)
        finally:
            base.world = world
        assert env.action_space.contains(a), a
        actions.append(np.asarray(a).tolist())
        obs, _, term, trunc, _ = env.step(a)
        if term or trunc:
            break
    return actions


def test_continuous_actions_follow_the_path_with_arcs():
    """With continuous actions the planner drives and turns at once (arcs) and turns on the spot
    only when far off; every action lies in the Box, it reads no truth and repeats bit for bit."""
    first = _drive(ViewpointPlanner(seed=4), action_type="continuous")
    assert first == _drive(ViewpointPlanner(seed=4), action_type="continuous")
    a = np.array(first)
    assert a.shape == (len(first), 2) and np.all(np.abs(a) <= 1.0)
    arcs = (a[:, 0] > 0) & (a[:, 1] != 0)
    assert arcs.sum() >= 10, a  # driving while turning ...
    assert np.all(a[:, 0] >= 0)  # ... never backward
    assert np.any((a[:, 0] == 0) & (a[:, 1] != 0))  # the first turn onto the path is on the spot


def test_arc_controller_commands():
    """The arc rule: speed cos(error) and the error turned per step below ``arc_max_rad``; on the
    spot above it; at the path's end, the turn to the goal heading."""
    pol = ViewpointPlanner(seed=0, arc_final_m=0.0)
    _env(pol, action_type="continuous")
    pol._ref, pol._pose, pol._goal_heading = np.zeros(3), np.zeros(3), 0.0

    class _Open:
        def clear_segment(self, a, b):
            return True

    pol._map = _Open()
    for bearing, v, w in [(0.05, math.cos(0.05), 0.5), (0.5, math.cos(0.5), 1.0), (-1.5, 0.0, -1.0)]:
        pol._path = np.array([[1.5 * math.cos(bearing), 1.5 * math.sin(bearing)]])
        np.testing.assert_allclose(pol._arc(), [v, w], atol=1e-6)
    pol._path, pol._goal_heading = np.zeros((0, 2)), -0.5
    np.testing.assert_allclose(pol._arc(), [0.0, -1.0])
    pol._goal_heading = 0.05
    assert pol._arc() is None  # facing the goal heading (within a turn step): arrived
    # close to the goal, it turns toward the goal heading while closing in, and arrives facing it
    pol.arc_final_m = 0.3
    pol._path, pol._goal_heading = np.array([[0.2, 0.0]]), 1.0
    np.testing.assert_allclose(pol._arc(), [1.0, 1.0])
    pol._pose = np.array([0.0, 0.0, 0.95])
    assert pol._arc() is None and pol._path.shape[0] == 0


def test_arc_settings_leave_discrete_actions_alone():
    """The arc settings act only on continuous actions: the discrete episode is the same whatever they are."""
    ref = _drive(ViewpointPlanner(seed=4))
    assert ref == _drive(ViewpointPlanner(seed=4, arc_max_rad=0.2, arc_gain=0.3, arc_final_m=1.0))
    assert ref == _drive(ViewpointPlanner(seed=4, reverse_rad=2.0, reverse_max_m=1.0))
    assert set(map(int, ref)) <= {0, 1, 2}


class _Open:
    def clear_segment(self, a, b):
        return True


def _scan(env, bearing=None, r=8.0):
    """A lidar scan with nothing in range but, if ``bearing`` is given, one return there at ``r``."""
    angles = np.asarray(env.unwrapped.lidar.angles)
    ranges = np.full(angles.size, 8.0)
    if bearing is not None:
        ranges[int(np.argmin(np.abs((angles - bearing + np.pi) % (2 * np.pi) - np.pi)))] = r
    return ranges


def test_reverse_controller_commands():
    """With ``reverse_rad`` set, a look-ahead point behind the robot is backed up to (speed
    ``-cos`` of the back's error, the back turned toward it) unless a return behind lies within
    the clearance; off by default; only on paths no longer than ``reverse_max_m``."""
    pol = ViewpointPlanner(seed=0, arc_final_m=0.0, reverse_rad=2.3)
    env = _env(pol, action_type="continuous")
    pol._ref, pol._pose, pol._goal_heading, pol._map = np.zeros(3), np.zeros(3), 0.0, _Open()
    pol._ranges = _scan(env)
    assert pol._rear_seen  # the env's lidar is all round
    for bearing in (math.pi - 0.05, -(math.pi - 0.5)):
        pol._path, pol._reversing = np.array([[1.5 * math.cos(bearing), 1.5 * math.sin(bearing)]]), False
        rear = (bearing % (2 * math.pi)) - math.pi
        a = pol._arc()
        assert env.action_space.contains(a)
        np.testing.assert_allclose(a, [-math.cos(rear), np.clip(rear / pol.step_rad, -1, 1)], atol=1e-6)
    # once backing up it keeps on while the back is within arc_max_rad of the target ...
    pol._path = np.array([[1.5 * math.cos(2.2), 1.5 * math.sin(2.2)]])
    assert pol._arc()[0] < 0
    # ... but does not start to at that error: it turns on the spot as without reversing
    pol._reversing = False
    np.testing.assert_allclose(pol._arc(), [0.0, 1.0])
    # a wall 0.25 m behind: no backing up, the turn on the spot instead
    pol._path, pol._ranges = np.array([[-1.5, 0.05]]), _scan(env, math.pi, 0.25)
    np.testing.assert_allclose(pol._arc(), [0.0, 1.0])
    # ... one 0.5 m behind, or beside the robot, does not stop it
    for bearing, r in ((math.pi, 0.5), (math.pi / 2, 0.22)):
        pol._ranges = _scan(env, bearing, r)
        assert pol._arc()[0] < 0
    # a path longer than reverse_max_m is not backed along; reverse_rad = 0 (the default) never backs
    pol.reverse_max_m = 1.0
    assert pol._arc()[0] == 0.0
    pol.reverse_max_m, pol.reverse_rad = math.inf, 0.0
    assert pol._arc()[0] == 0.0


def test_no_reversing_without_a_lidar_behind():
    """A lidar that does not see all around (here 180 deg ahead) cannot clear the way back: never reverse."""
    pol = ViewpointPlanner(seed=0, arc_final_m=0.0, reverse_rad=2.3)
    env = _env(pol, action_type="continuous", lidar={"fov_rad": math.pi, "n_beams": 30})
    assert not pol._rear_seen
    pol._ref, pol._pose, pol._goal_heading, pol._map = np.zeros(3), np.zeros(3), 0.0, _Open()
    pol._ranges, pol._path = np.full(30, 8.0), np.array([[-1.5, 0.05]])
    assert env.action_space.contains(pol._arc()) and pol._arc()[0] == 0.0


def test_backing_up_never_touches_the_wall_behind():
    """Scripted: the robot faces away from a wall 0.6-1 m behind it and its path's next point lies
    beyond that wall. It backs up, stops backing within the clearance and turns instead; no step
    collides and the robot's disc stays clear of the wall."""
    pol = ViewpointPlanner(seed=0, reverse_rad=2.3, replan_every=10_000)
    env = _env(pol, action_type="continuous", relocalizer={"n_particles": 100})
    base = env.unwrapped
    env.reset(seed=0)
    rng = np.random.default_rng(1)
    angles = np.linspace(-math.pi, math.pi, 72, endpoint=False)
    for _ in range(500):  # a free pose with a wall 0.6-1 m away in some direction
        pose = base.world.sample_free_pose(rng, margin_m=0.3)
        r, _ = base.world.scene.cast(np.asarray(pose[:2]), angles, 8.0)
        j = int(np.argmin(np.abs(r - 0.8)))
        if abs(r[j] - 0.8) < 0.2 and base.world.clearance(pose[:2]) > 0.3:
            break
    else:
        pytest.fail("no pose with a wall behind")
    start = [float(pose[0]), float(pose[1]), float(angles[j] + math.pi)]  # the wall straight behind
    obs, _ = env.reset(seed=0, options={"pose": start})
    pol.act(obs)  # first plan; then the scripted path: a point 2 m straight back, beyond the wall
    pol._path, pol._pose, pol._ref = np.array([[-2.0, 0.0]]), np.zeros(3), np.zeros(3)
    pol._map, pol._exploring, pol._since_plan = _Open(), False, 0
    obs, *_ = env.step(np.zeros(2, np.float32))
    kinds = []
    for _ in range(40):
        a = pol.act(obs)
        assert env.action_space.contains(a)
        kinds.append("back" if a[0] < 0 else "turn" if a[0] == 0 else "fwd")
        obs, _, term, trunc, info = env.step(a)
        assert not info["collided"], kinds
        assert base.world.clearance(np.asarray(info["pose"][:2])) > base.robot_params.radius_m
        if kinds[-1] == "turn" or term or trunc:
            break
    assert kinds.count("back") >= 3 and kinds[-1] == "turn", kinds
    # it stopped backing close to the wall (the check, not something else, stopped it)
    assert base.world.clearance(np.asarray(info["pose"][:2])) < base.robot_params.radius_m + 0.2


def _cross_ll_reference(*args):
    """The planner's cross log-likelihoods written out ray by ray in plain Python (the kernel's contract)."""
    ranges, labels, xy, phi0, headings, angles, fov_half, lidar_max, cam_min, cam_max, flat, ox, oy, inv_res, w, h = (
        args
    )
    n_k, n_p, n_b = ranges.shape
    n_cells = w * h
    floor0 = (flat.shape[0] // (n_cells + 1)) * n_cells
    out_l = np.zeros((n_p, headings.size, n_k, n_k))
    out_s = np.zeros_like(out_l)
    cnt_l = np.zeros((n_p, headings.size, n_k))
    cnt_s = np.zeros_like(cnt_l)
    for p, i, k, m in np.ndindex(n_p, headings.size, n_k, n_k):
        bx, by = (xy[m, p, 0] - ox) * inv_res, (xy[m, p, 1] - oy) * inv_res
        lid, cam = [], []
        for j in range(n_b):
            r = ranges[k, p, j]
            beta = angles[j] - (phi0[k] + headings[i])  # the ray in hypothesis k's robot frame
            a = beta + (phi0[m] + headings[i])  # the same ray from hypothesis m's pose
            ex, ey = bx + r * math.cos(a) * inv_res, by + r * math.sin(a) * inv_res
            inside = 0 <= ex < w and 0 <= ey < h
            cell = int(ey) * w + int(ex) if inside else 0
            if r < lidar_max:
                lid.append(flat[cell] if inside else flat[floor0])
            t = labels[k, p, j]
            if t > 0 and cam_min <= r < cam_max and abs(math.remainder(beta, 2 * math.pi)) <= fov_half:
                cam.append(flat[t * n_cells + cell] if inside else flat[floor0 + t])
        out_l[p, i, k, m] = np.mean(lid) if lid else 0.0
        out_s[p, i, k, m] = np.mean(cam) if cam else 0.0
        cnt_l[p, i, k], cnt_s[p, i, k] = len(lid), len(cam)
    return out_l, out_s, cnt_l, cnt_s


def test_cross_likelihood_kernel_matches_a_plain_reference():
    from agents.viewpoint import _cross_ll

    rng = np.random.default_rng(3)
    n_k, n_p, n_b, w, h, n_t = 3, 6, 16, 40, 30, 4
    ranges = rng.uniform(0.0, 10.0, (n_k, n_p, n_b))
    ranges[rng.random(ranges.shape) < 0.2] = 8.0  # no return
    args = (
        ranges, rng.integers(0, n_t, ranges.shape), rng.uniform(-1.0, 5.0, (n_k, n_p, 2)), rng.uniform(-4, 4, n_k),
        2 * math.pi * np.arange(8) / 8, 2 * math.pi * np.arange(n_b) / n_b, math.radians(35), 8.0, 0.3, 4.5,
        rng.normal(size=n_t * w * h + n_t), -0.5, -0.3, 10.0, w, h,
    )  # fmt: skip
    want = _cross_ll_reference(*args)
    got = [np.empty((n_p, 8, n_k, n_k)), np.empty((n_p, 8, n_k, n_k)), np.zeros((n_p, 8, n_k)), np.zeros((n_p, 8, n_k))]
    _cross_ll(*args, *got)
    assert want[3].sum() > 0 and want[2].sum() > 0  # both kinds of ray were scored
    for g, r in zip(got, want):
        np.testing.assert_allclose(g, r, rtol=1e-12, atol=1e-12)


def test_negative_evidence_kernel_matches_a_plain_reference_with_the_filters_sampling():
    """`_cross_neg` against the filter's own rules written out: the rays `negative_beams` would pick
    (unlabelled returns, no labelled neighbour; here in the camera's view), the points
    `NegativeEvidenceConfig.sample_ranges` puts on them, the lowest table value per ray."""
    from agents.viewpoint import _cross_neg
    from filters.localization.likelihood_field import NegativeEvidenceConfig

    rng = np.random.default_rng(4)
    n_k, n_p, n_b, w, h = 3, 5, 24, 40, 30
    neg = NegativeEvidenceConfig(p_detect=0.8)
    ranges = rng.uniform(0.0, 6.0, (n_k, n_p, n_b))
    labels = np.where(rng.random(ranges.shape) < 0.25, rng.integers(1, 4, ranges.shape), 0)
    xy, phi0 = rng.uniform(-1.0, 5.0, (n_k, n_p, 2)), rng.uniform(-4, 4, n_k)
    headings, angles = 2 * math.pi * np.arange(4) / 4, 2 * math.pi * np.arange(n_b) / n_b
    fov_half, cam_min, cam_max, ox, oy, inv_res = math.radians(100), 0.5, 5.0, -0.5, -0.3, 10.0
    table = np.append(np.minimum(rng.normal(size=w * h), 0.0), 0.0)
    want_n, want_c = np.zeros((n_p, 4, n_k, n_k)), np.zeros((n_p, 4, n_k))
    for p, i, k in np.ndindex(n_p, 4, n_k):
        lab = labels[k, p]
        near = (lab > 0) | (np.roll(lab, 1) > 0) | (np.roll(lab, -1) > 0)
        rays = []
        for j in range(n_b):
            beta = angles[j] - (phi0[k] + headings[i])
            r = ranges[k, p, j]
            if near[j] or not cam_min <= r < cam_max or abs(math.remainder(beta, 2 * math.pi)) > fov_half:
                continue
            counts, pts = neg.sample_ranges(np.array([r]))
            if counts[0]:
                rays.append((j, pts))
        want_c[p, i, k] = len(rays)
        for m in range(n_k):
            lows = []
            for j, pts in rays:
                a = angles[j] - phi0[k] + phi0[m]  # the ray's absolute angle at m's pose (any heading i)
                ex = (xy[m, p, 0] - ox) * inv_res + pts * math.cos(a) * inv_res
                ey = (xy[m, p, 1] - oy) * inv_res + pts * math.sin(a) * inv_res
                inside = (ex >= 0) & (ex < w) & (ey >= 0) & (ey < h)
                cells = np.where(inside, ey.astype(int) * w + ex.astype(int), w * h)
                lows.append(min(0.0, table[cells].min()))
            want_n[p, i, k, m] = np.mean(lows) if lows else 0.0
    got_n, got_c = np.empty_like(want_n), np.zeros_like(want_c)
    args = (ranges, labels, xy, phi0, headings, angles, fov_half, cam_min, cam_max, table, neg.margin_m, neg.step_m)
    _cross_neg(*args, ox, oy, inv_res, w, h, got_n, got_c)
    assert want_c.min() >= 0 and want_c.sum() > 20 and (want_n < 0).sum() > 20  # rays were scored
    np.testing.assert_array_equal(got_c, want_c)
    np.testing.assert_allclose(got_n, want_n, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("views, margin", [(1.0, 0.02), (6.0, 0.05)])
def test_negative_evidence_values_a_place_where_only_one_twin_would_see_an_object(views, margin):
    """At a viewpoint where one twin's image sees an object and the other's a bare wall, the filter
    learns from either truth (the missing object counts against the other twin): the planner's
    score there rises with the negative evidence modelled, and its best is no worse. With the default
    one update per viewpoint the scores are smaller than with six, and so is the rise (80 of the 12,032
    (viewpoint, heading) pairs by more than 0.02, 2 by more than 0.05)."""
    scores = {}
    for on in (True, False):
        pol = ViewpointPlanner(seed=0, negative_evidence=on, views=views)
        env = _env(pol)
        twins = _twins()
        env.reset(seed=0, options={"pose": twins[0].tolist()})
        pm = pol._plan_map()
        scores[on], _ = pol._gains(pm, twins, np.array([0.5, 0.5]), np.arange(0, pm.xy.shape[0], 3))
    assert scores[True].shape == scores[False].shape
    assert (scores[True] > scores[False] + margin).sum() > 10  # viewpoints valued more ...
    assert scores[True].max() >= scores[False].max() - 1e-9  # ... and the best no worse


def test_clear_segment_matches_sampling_the_segment_with_numpy():
    env = gym.make("SemReloc-v22", layout="twin_rooms", map_source="perfect")
    from agents.viewpoint import _PlanMap

    pm = _PlanMap(env.unwrapped.grid, 0.2, 0.1, 0.15)
    ox, oy = pm.grid.origin_xy_m
    h, w = pm.shape

    def reference(a, b):
        t = np.linspace(0.0, 1.0, max(2, int(math.hypot(*(b - a)) / (pm.cell_m / 2)) + 1))
        col = np.floor((a[0] + t * (b[0] - a[0]) - ox) / pm.cell_m).astype(np.int64)
        row = np.floor((a[1] + t * (b[1] - a[1]) - oy) / pm.cell_m).astype(np.int64)
        if (row < 0).any() or (row >= h).any() or (col < 0).any() or (col >= w).any():
            return False
        return bool((pm.node[row, col] >= 0).all())

    rng = np.random.default_rng(0)
    lo = np.array([ox, oy]) - 1.0
    hi = np.array([ox, oy]) + np.array([w, h]) * pm.cell_m + 1.0
    outcomes = []
    for _ in range(3000):
        a = rng.uniform(lo, hi)
        b = a + rng.normal(0.0, 1.5, 2)
        if rng.random() < 0.3:  # on cell edges
            a, b = np.round(a / 0.075) * 0.075, np.round(b / 0.075) * 0.075
        outcomes.append(pm.clear_segment(a, b))
        assert outcomes[-1] == reference(a, b), (a, b)
    assert 0 < sum(outcomes) < len(outcomes)


def test_a_planner_wrapped_on_another_env_plans_as_a_fresh_one():
    # a review: envs of one layout share a grid, and the planner kept the first env's plan graph (its robot's
    # radius) and likelihood tables (its filter's model) when wrapped on a second
    kw = dict(layout="twin_rooms", map_source="perfect")
    a = gym.make("SemReloc-v22", **kw, relocalizer={"n_particles": 300})
    b = gym.make(
        "SemReloc-v22", **kw, robot={"radius_m": 0.3},
        relocalizer={"n_particles": 300, "lidar_field": {"sigma_hit_m": 0.6, "z_hit": 0.5}},
    )  # fmt: skip
    a.reset(seed=0)
    b.reset(seed=0)
    used = ViewpointPlanner(seed=0)
    used.wrap(a)
    used.reset()
    used.plan()
    used.wrap(b)
    used.reset()
    fresh = ViewpointPlanner(seed=0)
    fresh.wrap(b)
    fresh.reset()
    poses, w = fresh.hypotheses()
    assert used._plan_map().xy.shape == fresh._plan_map().xy.shape
    cand = np.arange(0, fresh._plan_map().xy.shape[0], 40)
    assert np.array_equal(
        used._gains(used._plan_map(), poses, w, cand)[0], fresh._gains(fresh._plan_map(), poses, w, cand)[0]
    )
