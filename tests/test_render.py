"""Rendering: render_fps follows the control rate, the static layout is drawn once, RecordVideo, human mode."""

import gymnasium as gym
import numpy as np
import pytest

import semreloc_env  # noqa: F401
from semreloc_env import render

FAST = {"map_source": "perfect", "relocalizer": {"n_particles": 300}}


def test_render_fps_follows_the_control_rate_per_instance():
    fast = gym.make("SemReloc-v22", physics={"control_hz": 20.0}, **FAST)
    slow = gym.make("SemSlam-v2", physics={"control_hz": 5.0})
    assert fast.metadata["render_fps"] == 20.0 and fast.unwrapped.metadata["render_fps"] == 20.0
    assert slow.metadata["render_fps"] == 5.0
    assert gym.make("SemReloc-v22", **FAST).metadata["render_fps"] == 10.0
    assert type(fast.unwrapped).metadata["render_fps"] == 10  # the class default is untouched


def _frames(env, seed: int, actions) -> list[np.ndarray]:
    env.reset(seed=seed)
    out = [env.render()]
    for a in actions:
        env.step(a)
        out.append(env.render())
    return out


def test_static_layout_drawn_once_and_frames_carry_nothing_over():
    actions = [0, 0, 1, 0, 2, 0]
    env = gym.make("SemReloc-v22", render_mode="rgb_array", **FAST)
    many = _frames(env, 3, actions)
    renderer = env.unwrapped._renderer
    assert renderer.background_draws == 1
    assert not np.array_equal(many[0], many[-1])  # the robot, scans and particles moved
    # a renderer that drew only the last state gives the same pixels: no artist of earlier frames is left
    fresh = render.Renderer(env.unwrapped.layout)
    np.testing.assert_array_equal(fresh.draw(env.unwrapped._render_state()), many[-1])
    fresh.close()
    # new extra obstacles redraw the background
    state = {**env.unwrapped._render_state(), "extra_obstacles": [np.array([[1.0, 1.0], [2.0, 1.0], [2.0, 2.0]])]}
    with_box = renderer.draw(state)
    assert renderer.background_draws == 2 and not np.array_equal(with_box, renderer.draw(env.unwrapped._render_state()))
    env.close()


def test_record_video_writes_a_playable_mp4(tmp_path):
    pytest.importorskip("moviepy", reason="RecordVideo needs the 'video' extra (moviepy)")
    from moviepy import VideoFileClip

    env = gym.make("SemReloc-v22", render_mode="rgb_array", max_episode_steps=12, physics={"control_hz": 5.0}, **FAST)
    folder = tmp_path / "videos"
    env = gym.wrappers.RecordVideo(env, str(folder), episode_trigger=lambda ep: ep == 0, disable_logger=True)
    env.reset(seed=0)
    done, steps = False, 0
    while not done:
        *_, terminated, truncated, _ = env.step(steps % 4)
        done, steps = terminated or truncated, steps + 1
    env.close()
    videos = list(folder.glob("*.mp4"))
    assert len(videos) == 1 and videos[0].stat().st_size > 0
    clip = VideoFileClip(str(videos[0]))
    try:
        assert clip.fps == pytest.approx(5.0)
        frames = list(clip.iter_frames())
        # reset and every step at the env's control rate (the reader may drop the last frame)
        assert clip.duration == pytest.approx((steps + 1) / 5.0, abs=0.21)
        assert steps <= len(frames) <= steps + 1
        assert frames[0].ndim == 3 and frames[0].std() > 0
    finally:
        clip.close()


def test_human_mode_is_paced_to_render_fps_where_a_window_shows(monkeypatch):
    import matplotlib.pyplot as plt

    old = plt.get_backend()
    plt.switch_backend("Agg")  # no window in tests: the same drawing code on a non-interactive canvas
    monkeypatch.setattr(render, "backend_shows_windows", lambda: True)  # ... as if it showed one
    clock = {"t": 0.0}
    sleeps: list[float] = []
    monkeypatch.setattr(render.time, "monotonic", lambda: clock["t"])
    monkeypatch.setattr(render.time, "sleep", lambda s: sleeps.append(s))
    try:
        env = gym.make("SemReloc-v22", render_mode="human", physics={"control_hz": 4.0}, **FAST)
        env.reset(seed=0)  # first frame: nothing to wait for
        clock["t"] = 0.05
        _, _, _, _, info = env.step(0)
        assert env.render() is None and "pose" in info
        assert sleeps[0] == pytest.approx(0.25 - 0.05)  # 4 Hz: a frame every 0.25 s
        env.close()
        assert not plt.get_fignums()  # close() closes the window
    finally:
        plt.switch_backend(old)


def test_human_mode_without_a_window_warns_and_does_not_wait(monkeypatch):
    """On a machine without a display matplotlib falls back to Agg: no window shows, so human mode
    says so and does not slow every step to the control rate (it used to, silently)."""
    import matplotlib.pyplot as plt

    old = plt.get_backend()
    plt.switch_backend("Agg")
    sleeps: list[float] = []
    monkeypatch.setattr(render.time, "sleep", lambda s: sleeps.append(s))
    try:
        assert not render.backend_shows_windows()
        with pytest.warns(UserWarning, match="shows no window"):
            env = gym.make("SemReloc-v22", render_mode="human", physics={"control_hz": 4.0}, **FAST)
            env.reset(seed=0)
        for _ in range(3):
            env.step(0)
        assert sleeps == []
        env.close()
    finally:
        plt.switch_backend(old)


def test_frames_have_even_sizes_for_video_encoders():
    """4:2:0 video (what browsers and players decode) needs even widths and heights; RecordVideo fell
    back to 4:4:4 for most procedural layouts' odd heights."""
    from semreloc_env.layouts import get_layout

    shapes = set()
    for kind in ("procedural", "procedural_lookalike", "procedural_ring", "procedural_corridor"):
        for seed in range(4):
            env = gym.make("SemReloc-v22", layout=kind, layout_seed=seed, map_source="perfect", render_mode="rgb_array")
            env.reset(seed=0)
            shapes.add(env.render().shape[:2])
            env.close()
    for dpi in (37, 80, 101):
        r = render.Renderer(get_layout("lab"), dpi=dpi)
        r.draw({"layout": r.layout, "pose": np.array([7.0, 5.0, 0.0])})
        shapes.add(np.asarray(r.fig.canvas.buffer_rgba()).shape[:2])
    assert len(shapes) > 5 and all(h % 2 == 0 and w % 2 == 0 for h, w in shapes), shapes


def test_renderer_rejects_bad_fps():
    env = gym.make("SemReloc-v22", **FAST)
    with pytest.raises(ValueError, match="fps"):
        render.Renderer(env.unwrapped.layout, fps=0)


def test_an_env_that_has_rendered_pickles_and_deep_copies():
    # a new user's trial: the renderer's matplotlib canvas made both fail after the first render()
    import copy
    import pickle

    env = gym.make("SemReloc-v22", render_mode="rgb_array", **FAST)
    env.reset(seed=1)
    first = env.render()
    for twin in (pickle.loads(pickle.dumps(env)), copy.deepcopy(env)):
        assert twin.unwrapped._renderer is None  # a copy draws its own
        np.testing.assert_array_equal(twin.render(), first)
        a, b = env.step(1)[0], twin.step(1)[0]
        np.testing.assert_array_equal(a["lidar"], b["lidar"])
        env.reset(seed=1)


def test_title_calls_a_spread_belief_spread_not_a_hypothesis():
    """A global start's uniform cloud is one connected cluster; its title says the belief is spread, not that a
    hypothesis holds 100 %; a tracked belief's title names its heaviest hypothesis and its weight."""
    env = gym.make("SemReloc-v22")
    env.reset(seed=0)
    title = env.unwrapped._render_state()["title"]
    assert "belief spread (std" in title and "hypothesis" not in title
    env.reset(seed=0, options={"tracking": True})
    title = env.unwrapped._render_state()["title"]
    assert "best hypothesis" in title and "spread" not in title and title.endswith("converged")


def test_what_a_frame_draws_follows_the_running_episode():
    """A twenty-first tester's: the robot was drawn 0.2 m wide whatever its radius; after set_layout the frames
    drew the new layout's walls under the old episode's robot; a labelled camera beam clipped at range_max_m was
    not drawn; the title of a tall, narrow layout was cut."""
    from matplotlib.collections import LineCollection
    from matplotlib.patches import Circle

    from filters.robot_data.scans import SemanticScan

    env = gym.make("SemReloc-v22", layout="lab", robot={"radius_m": 0.45}, render_mode="rgb_array", **FAST)
    env.reset(seed=0)
    env.render()
    r = env.unwrapped._renderer
    assert {round(c.get_radius(), 6) for c in r._dynamic if isinstance(c, Circle)} == {0.45}
    env.unwrapped.set_layout("twin_rooms")
    env.step(0)
    env.render()
    drawn = env.unwrapped._renderer
    assert drawn.layout.name == "lab" and drawn.ax.title.get_text().startswith("lab")
    env.reset(seed=0)
    size = env.render().shape
    assert env.unwrapped._renderer.layout.name == "twin_rooms" and size[1] > size[0]  # twin_rooms' own frame

    labels = np.array([0, 2, 4])
    scan = SemanticScan(np.array([2.0, 3.0, 4.5]), np.array([-0.2, 0.0, 0.2]), labels, 4.5)
    rr = render.Renderer(env.unwrapped.layout)
    rr.draw({"layout": env.unwrapped.layout, "pose": np.array([3.0, 3.0, 0.0]), "semantic": scan})
    (beams,) = [a for a in rr._dynamic if isinstance(a, LineCollection)]
    assert len(beams.get_segments()) == 3  # the cabinet at 4.5 m too

    tall = {"name": "tall", "outer": [[0, 0], [5, 0], [5, 14], [0, 14]]}
    frame = gym.make("SemReloc-v22", layout=tall, render_mode="rgb_array", **FAST)
    frame.reset(seed=0)
    assert frame.render().shape[1] >= render.MIN_WIDTH_IN * 80


def test_human_mode_leaves_pyplot_as_it_found_it():
    import matplotlib
    import matplotlib.pyplot as plt

    old = plt.get_backend()
    plt.switch_backend("Agg")
    plt.ioff()
    try:
        env = gym.make("SemReloc-v22", render_mode="human", **FAST)
        env.reset(seed=0)
        assert matplotlib.is_interactive()
        env.close()
        assert not matplotlib.is_interactive()
    finally:
        plt.switch_backend(old)
