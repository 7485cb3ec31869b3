"""Layout blocks: solid polygons of no class (pillars, sealed cores)."""

import gymnasium as gym
import numpy as np
import pytest

import semreloc_env  # noqa: F401
from semreloc_env.layouts import LayoutError, get_layout, layout_from_dict
from semreloc_env.layouts.tiling import tiled_layout
from semreloc_env.maps import map_key
from semreloc_env.rasterize import rasterize
from semreloc_env.render import draw_layout
from semreloc_env.sensors import CameraParams, LidarParams
from semreloc_env.world import build_world

HALL = {
    "name": "hall",
    "outer": [[0, 0], [10, 0], [10, 10], [0, 10]],
    "objects": [{"class": "chair", "center": [1.5, 1.5], "size": [0.5, 0.5]}],
    "blocks": [[[4, 4], [6, 4], [6, 6], [4, 6]], {"center": [8.0, 2.0], "size": [1.0, 0.6], "angle_rad": 0.3}],
}


def test_blocks_parse_round_trip_and_edges_are_walls():
    layout = layout_from_dict(HALL)
    assert len(layout.blocks) == 2
    assert layout_from_dict(layout.to_dict()) == layout
    # the outer ring's 4 edges, then 4 + 4 block edges
    assert layout.wall_segments().shape == (12, 2, 2)
    assert "blocks" not in get_layout("lab").to_dict()


def test_inside_a_block_is_not_free_and_never_a_start():
    world = build_world(layout_from_dict(HALL))
    assert not world.is_free(np.array([5.0, 5.0]))
    assert world.is_free(np.array([2.5, 7.5]))
    pts = np.random.default_rng(0).uniform(0, 10, (4000, 2))
    assert np.array_equal(world.free_points(pts), world.free_points_reference(pts))
    rng = np.random.default_rng(1)
    starts = np.array([world.sample_free_pose(rng)[:2] for _ in range(500)])
    assert not np.any((np.abs(starts[:, 0] - 5) < 1) & (np.abs(starts[:, 1] - 5) < 1))
    with pytest.raises(ValueError, match="not free"):
        world.set_pose([5.0, 5.0, 0.0])


def test_blocks_are_occupied_without_a_class_and_seen_as_walls():
    layout = layout_from_dict(HALL)
    grid = rasterize(layout)
    r, c = grid.world_to_cell(np.array([[5.0, 5.0], [2.5, 7.5]]))
    assert grid.occupancy[r[0], c[0]] == 1.0 and grid.occupancy[r[1], c[1]] == 0.0
    assert np.all(grid.semantic[:, r[0], c[0]] == 0.0)
    env = gym.make("SemReloc-v22", layout=HALL, map_source="perfect")
    obs, info = env.reset(seed=0, options={"pose": [2.0, 5.0, 0.0]})
    ahead = np.argmin(np.abs(env.unwrapped.lidar.angles))
    assert obs["lidar"][ahead] == pytest.approx(2.0, abs=0.05)  # the block's west face at x = 4
    cam = env.unwrapped.camera
    mid = np.argmin(np.abs(np.asarray(cam.angles)))
    assert obs["semantic_class"][mid] == 0  # an edge of no class
    env.close()


def test_map_keys_of_layouts_without_blocks_are_unchanged():
    layout = get_layout("lab")
    assert map_key(layout, LidarParams(), CameraParams()) != map_key(
        layout_from_dict({**layout.to_dict(), "blocks": [[[7, 4.5], [7.5, 4.5], [7.5, 5], [7, 5]]]}),
        LidarParams(),
        CameraParams(),
    )
    # the key text is what it was before layouts had blocks: the four fields, in order
    old = ";".join(["Layout"] + [f"{f}={getattr(layout, f)!r}" for f in ("name", "outer", "walls", "objects")])
    assert semreloc_env.maps._layout_text(layout) == old


def test_tiling_and_drawing_keep_blocks():
    tiled = tiled_layout(layout_from_dict(HALL), 2, 1)
    assert len(tiled.blocks) == 4
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots()
    draw_layout(ax, layout_from_dict(HALL))
    assert len(ax.patches) == 3  # two blocks, one object
    plt.close(fig)


@pytest.mark.parametrize(
    "blocks, message",
    [
        ([[[4, 4], [6, 4]]], r"blocks\[0\]: needs at least 3 points"),
        ([[[1, 1], [2, 1], [2, 2], [1, 2]]], r"overlaps objects\[0\]|blocks\[0\]: overlaps"),
        ([[[9, 9], [11, 9], [11, 11], [9, 11]]], r"blocks\[0\]: lies partly outside"),
        ([{"center": [5, 5]}], r"blocks\[0\]: needs 'polygon' or both 'center' and 'size'"),
        ([{"center": [5, 5], "size": [1, 1], "class": "chair"}], r"blocks\[0\]: unknown keys \['class'\]"),
        ([[[4, 4], [6, 6], [6, 4], [4, 6]]], r"blocks\[0\]: polygon is self-intersecting"),
        ("square", r"'blocks': expected a list"),
    ],
)
def test_bad_blocks_are_named(blocks, message):
    with pytest.raises(LayoutError, match=message):
        layout_from_dict({**HALL, "blocks": blocks})


def test_blocks_that_fill_the_outer_wall_are_refused_when_parsed():
    # before, a block equal to the outer wall passed validation and failed only at reset
    full = {"name": "full", "outer": HALL["outer"], "blocks": [HALL["outer"]]}
    with pytest.raises(LayoutError, match=r"blocks\[0\]: objects and blocks fill the outer wall"):
        layout_from_dict(full)
    halves = [[[0, 0], [5, 0], [5, 10], [0, 10]], [[5, 0], [10, 0], [10, 10], [5, 10]]]
    with pytest.raises(LayoutError, match="fill the outer wall"):
        layout_from_dict({**full, "blocks": halves})
    layout_from_dict({**full, "blocks": [[[0, 0], [9.8, 0], [9.8, 10], [0, 10]]]})  # a 0.2 m strip is floor


def test_a_wall_through_a_block_is_refused():
    with pytest.raises(LayoutError, match=r"walls\[0\]: passes through blocks\[0\]"):
        layout_from_dict({**HALL, "walls": [[[3, 5], [7, 5]]]})


def test_box_blocks_count_toward_the_vertex_limit(monkeypatch):
    import semreloc_env.layouts.layout as layout_module

    monkeypatch.setattr(layout_module, "MAX_VERTICES", 20)
    boxes = [{"center": [1.0 + 1.5 * i, 5.0], "size": [0.5, 0.5]} for i in range(5)]  # 4 + 5 x 4 = 24
    with pytest.raises(LayoutError, match="24 vertices, more than the limit of 20"):
        layout_from_dict({"outer": HALL["outer"], "blocks": boxes})
