"""Plain ROS maps (no semantic sidecar, .yml, PNG) as the env's map_source."""

import dataclasses

import gymnasium as gym
import numpy as np
import pytest
from PIL import Image

import semreloc_env  # noqa: F401
from filters.mapping.ros_map import save_map
from semreloc_env.layouts import get_layout
from semreloc_env.rasterize import rasterize


def _plain_map(tmp_path, suffix=".yaml"):
    grid = rasterize(get_layout("twin_rooms"))
    plain = dataclasses.replace(grid, semantic=np.zeros((0, 0, 0), np.float32), class_names=())
    return grid, save_map(plain, tmp_path / f"plain{suffix}")


@pytest.mark.parametrize("suffix", [".yaml", ".yml"])
def test_plain_ros_map_runs_lidar_only(tmp_path, suffix):
    grid, path = _plain_map(tmp_path, suffix)
    assert not (tmp_path / "plain.semantic.yaml").exists()
    env = gym.make("SemReloc-v22", layout="twin_rooms", map_source=str(path), semantic=False,
                   relocalizer={"n_particles": 200})  # fmt: skip
    env.reset(seed=0)
    for _ in range(3):
        _, _, _, _, info = env.step(0)
    assert np.isfinite(info["pose_error"]["position"])
    np.testing.assert_array_equal(env.unwrapped.grid.occupied_mask(), grid.occupied_mask())
    env.close()


def test_a_lidar_only_env_on_a_plain_map_carries_the_env_classes(tmp_path):
    # a review: the plain map kept no class layers, so ActiveObservation's images left its own space
    from semreloc_env.observations import ActiveObservation

    _, path = _plain_map(tmp_path)
    env = gym.make("SemReloc-v22", map_source=str(path), semantic=False, relocalizer={"n_particles": 200})
    assert env.unwrapped.grid.class_names == ("door", "chair", "trash_bin", "cabinet")
    assert not env.unwrapped.grid.semantic.any()
    wrapped = ActiveObservation(env)
    obs, _ = wrapped.reset(seed=0)
    assert wrapped.observation_space.contains(obs)


def test_plain_ros_map_with_semantic_on_says_what_to_do(tmp_path):
    _, path = _plain_map(tmp_path)
    with pytest.raises(ValueError, match="has no semantic classes.*semantic=False"):
        gym.make("SemReloc-v22", layout="twin_rooms", map_source=str(path))


def test_png_map_in_the_env(tmp_path):
    _, path = _plain_map(tmp_path)
    Image.open(tmp_path / "plain.pgm").save(tmp_path / "plain.png")
    (tmp_path / "png.yml").write_text(path.read_text().replace("plain.pgm", "plain.png").replace("negate: 0\n", ""))
    env = gym.make("SemReloc-v22", layout="twin_rooms", map_source=str(tmp_path / "png.yml"), semantic=False,
                   relocalizer={"n_particles": 100})  # fmt: skip
    pgm = gym.make("SemReloc-v22", layout="twin_rooms", map_source=str(path), semantic=False,
                   relocalizer={"n_particles": 100})  # fmt: skip
    a, b = env.unwrapped.grid, pgm.unwrapped.grid  # the PNG holds the PGM's pixels: the same map
    np.testing.assert_array_equal(a.occupied_mask(), b.occupied_mask())
    np.testing.assert_array_equal(a.free_mask(), b.free_mask())
    env.reset(seed=0)
    env.close()


def test_a_broken_yaml_file_is_a_layout_error_unless_it_is_a_ros_map(tmp_path):
    # a new user's trial: a layout file with a YAML syntax error raised MapFormatError (it was taken
    # for a ROS map), so code catching the README's LayoutError missed it
    from filters.mapping.ros_map import MapFormatError
    from semreloc_env.layouts import LayoutError

    (tmp_path / "office.yaml").write_text("outer: [[0, 0], [4, 0]\nwalls: []\n")
    with pytest.raises(LayoutError, match="office.yaml: not valid YAML"):
        gym.make("SemReloc-v22", layout=str(tmp_path / "office.yaml"))
    (tmp_path / "map.yaml").write_text("image: plain.pgm\nresolution: [0.05\n")
    with pytest.raises(MapFormatError, match="map.yaml"):
        gym.make("SemReloc-v22", layout="twin_rooms", map_source=str(tmp_path / "map.yaml"), semantic=False)


def test_a_sidecar_with_some_classes_or_another_order(tmp_path):
    # a new user's trial: docs/maps.md allows any class list, the env refused all but its own four in order
    grid = rasterize(get_layout("twin_rooms"))
    door = dataclasses.replace(grid, semantic=grid.semantic[:1], class_names=grid.class_names[:1])
    order = [3, 2, 1, 0]
    turned = dataclasses.replace(
        grid, semantic=grid.semantic[order], class_names=tuple(grid.class_names[i] for i in order)
    )
    kw = dict(layout="twin_rooms", relocalizer={"n_particles": 200})
    with pytest.raises(
        ValueError, match=r"door.*has no layer for the classes \['chair', 'trash_bin', 'cabinet'\].*semantic=False"
    ):
        gym.make("SemReloc-v22", map_source=str(save_map(door, tmp_path / "door" / "door.yaml")), **kw)
    lidar_only = gym.make("SemReloc-v22", map_source=str(tmp_path / "door" / "door.yaml"), semantic=False, **kw)
    g = lidar_only.unwrapped.grid
    assert g.class_names == grid.class_names
    np.testing.assert_array_equal(g.class_mask(0), grid.class_mask(0))
    assert not any(g.class_mask(k).any() for k in (1, 2, 3))
    lidar_only.reset(seed=0)
    lidar_only.step(0)
    same = gym.make("SemReloc-v22", map_source=str(save_map(turned, tmp_path / "turned" / "t.yaml")), **kw)
    plain = gym.make("SemReloc-v22", map_source=str(save_map(grid, tmp_path / "full" / "f.yaml")), **kw)
    assert same.unwrapped.grid.class_names == grid.class_names
    np.testing.assert_array_equal(same.unwrapped.grid.semantic, plain.unwrapped.grid.semantic)
    unknown = dataclasses.replace(grid, class_names=("door", "chair", "sofa", "cabinet"))
    with pytest.raises(ValueError, match=r"classes \['sofa'\] are not among the env's"):
        gym.make("SemReloc-v22", map_source=str(save_map(unknown, tmp_path / "sofa" / "s.yaml")), semantic=False, **kw)
    with pytest.raises(ValueError, match=r"map 's': classes \['sofa'\] are not among the env's"):  # the world from it
        gym.make("SemReloc-v22", map_source=str(tmp_path / "sofa" / "s.yaml"), semantic=False)


def test_a_folder_as_map_source_says_to_give_a_file_in_it(tmp_path, monkeypatch):
    _plain_map(tmp_path)
    for src in (tmp_path, str(tmp_path)):
        with pytest.raises(ValueError, match="is a folder; give one map file in it"):
            gym.make("SemReloc-v22", map_source=src)
    # a folder in the working directory that shares a map source's name does not shadow it
    monkeypatch.chdir(tmp_path)
    for name in ("mapping", "perfect", "twin_rooms"):
        (tmp_path / name).mkdir()
        env = gym.make("SemReloc-v22", layout="twin_rooms", map_source=name, relocalizer={"n_particles": 100})
        assert env.unwrapped.map_source == name


def test_a_start_on_an_unknown_cell_of_a_map_world_says_so(tmp_path):
    """A world built from a map: a pose on an unknown cell is refused as one (an outside tester got "would overlap
    a wall, object or block", which the unknown cell is not)."""
    grid = rasterize(get_layout("twin_rooms"))
    occ = np.array(grid.occupancy, copy=True)
    row, col = grid.world_to_cell(np.array([[3.0, 3.0]]))
    occ[row[0] - 10 : row[0] + 10, col[0] - 10 : col[0] + 10] = 0.5  # unknown around (3, 3)
    plain = dataclasses.replace(grid, occupancy=occ, semantic=np.zeros((0, 0, 0), np.float32), class_names=())
    path = save_map(plain, tmp_path / "unknown.yaml")
    env = gym.make("SemReloc-v22", map_source=str(path), semantic=False, relocalizer={"n_particles": 100})
    with pytest.raises(ValueError, match=r"is not free: it lies on a map cell that is not known free"):
        env.reset(seed=0, options={"pose": (3.0, 3.0, 0.0)})
    with pytest.raises(ValueError, match=r"kidnap_pose .* is not free: it lies on a map cell that is not known free"):
        env.reset(seed=0, options={"kidnap_at_step": 5, "kidnap_pose": (3.0, 3.0, 0.0)})
    with pytest.raises(ValueError, match=r"is not free: the robot \(radius 0.2 m\) would overlap a wall"):
        env.reset(seed=0, options={"pose": (0.05, 3.0, 0.0)})  # in the outer wall's cells: occupied, not unknown
    env.reset(seed=0, options={"pose": (1.0, 1.0, 0.0)})


def test_a_ros_map_yaml_without_its_image_key_gets_the_map_loaders_error(tmp_path):
    # an outside trial: "imag:" made the file a layout, and the error listed a layout's keys
    from filters.mapping.ros_map import MapFormatError

    (tmp_path / "typo.yaml").write_text(
        "imag: room.pgm\nresolution: 0.05\norigin: [-1.0, 2.0, 0.0]\nnegate: 0\n"
        "occupied_thresh: 0.65\nfree_thresh: 0.196\n"
    )
    with pytest.raises(MapFormatError, match=r"typo.yaml: missing key 'image'"):
        gym.make("SemReloc-v22", layout="twin_rooms", map_source=str(tmp_path / "typo.yaml"), semantic=False)
    (tmp_path / "broken.yaml").write_text("resolution: 0.05\norigin: [-1.0, 2.0\n")
    with pytest.raises(MapFormatError, match="broken.yaml"):
        gym.make("SemReloc-v22", layout="twin_rooms", map_source=str(tmp_path / "broken.yaml"), semantic=False)


def test_the_envs_read_a_map_file_as_they_always_have_and_warn_where_load_map_reads_it_otherwise(tmp_path):
    """A review's: nothing held the envs to their old reading of map files, on which "no episode changes" rests.
    Unknown cells under thresholds 0.1 / 0.4 stay occupied (walls of the world), and a class region whose outline
    touches itself stays out of the world; `load_map` and `layout_from_map` on their own read both otherwise."""
    import warnings

    from filters.mapping.grid import GridMap
    from filters.mapping.ros_map import MapFormatWarning, load_map
    from semreloc_env.map_world import MapWorldWarning, layout_from_map

    occ = np.zeros((60, 60), np.float32)
    occ[[0, -1], :] = occ[:, [0, -1]] = 1.0
    occ[10:14, 40:50] = 0.25  # an unknown block (between the thresholds below)
    cab = np.zeros((60, 60), bool)
    cab[30:36, 20:26] = True
    cab[31:35, 21:25] = False
    cab[30, 20] = False  # the pinch
    occ[cab] = 1.0
    sem = np.zeros((4, 60, 60), np.float32)
    sem[3][cab] = 1.0
    names = ("door", "chair", "trash_bin", "cabinet")
    path = save_map(
        GridMap(occ, 0.05, (0.0, 0.0), sem, names, occupied_thresh=0.4, free_thresh=0.1), tmp_path / "m.yaml"
    )
    assert load_map(path).occupied_mask()[10:14, 40:50].sum() == 0  # unknown, read on its own
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", MapWorldWarning)
        assert len(layout_from_map(load_map(path)).walls) > 2  # the room's two rings, and the cabinet as walls
    with pytest.warns(MapFormatWarning, match="read as occupied"), pytest.warns(MapWorldWarning, match="left out"):
        env = gym.make("SemReloc-v22", map_source=str(path), semantic=True, relocalizer={"n_particles": 100})
    base = env.unwrapped
    assert base.grid.occupied_mask()[10:14, 40:50].all()  # as the envs have always read it
    assert not base.layout.objects
    assert len(base.layout.walls) == 3  # the room's two rings and the unknown block: no cabinet
    env.close()
