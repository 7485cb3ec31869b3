"""Caches that make resets and new envs cheap: the likelihood field per map, maps per layout."""

import gymnasium as gym
import numpy as np
import pytest

import semreloc_env  # noqa: F401


def test_envs_on_the_same_map_share_one_likelihood_model_across_resets():
    a = gym.make("SemReloc-v22", map_source="perfect").unwrapped
    b = gym.make("SemReloc-v22", map_source="perfect").unwrapped
    a.reset(seed=0)
    model = a.mcl.measurement_model
    a.reset(seed=1)
    b.reset(seed=2)
    assert a.mcl.measurement_model is model and b.mcl.measurement_model is model
    c = gym.make("SemReloc-v22", map_source="perfect", relocalizer={"lidar_field": {"sigma_hit_m": 0.3}}).unwrapped
    c.reset(seed=0)
    assert c.mcl.measurement_model is not model
    assert np.isclose(c.mcl.measurement_model.lidar_config.sigma_hit_m, 0.3)


def test_mapping_run_maps_are_cached_on_disk_and_reloaded_equal(tmp_path, monkeypatch):
    from semreloc_env import maps
    from semreloc_env.config import CameraParams, LidarParams
    from semreloc_env.layouts import get_layout

    monkeypatch.setenv("SEMRELOC_CACHE_DIR", str(tmp_path))
    layout = get_layout("procedural", seed=21)
    lidar, camera = LidarParams(), CameraParams()
    built = maps.mapped(layout, lidar, camera)
    files = list((tmp_path / "maps").glob("*.npz"))
    assert len(files) == 1 and files[0].stem == maps.map_key(layout, lidar, camera)
    assert maps.mapped(layout, lidar, camera) is built  # memory
    maps._memory.clear()
    loaded = maps.mapped(layout, lidar, camera)  # disk
    assert loaded is not built
    np.testing.assert_array_equal(loaded.occupancy, built.occupancy)
    np.testing.assert_array_equal(loaded.semantic, built.semantic)
    assert (loaded.resolution_m, loaded.origin_xy_m, loaded.class_names) == (
        built.resolution_m,
        built.origin_xy_m,
        built.class_names,
    )
    # other sensor parameters, another layout: other keys
    assert maps.map_key(layout, LidarParams(n_beams=90), camera) != files[0].stem
    assert maps.map_key(get_layout("procedural", seed=22), lidar, camera) != files[0].stem
    # another version of a library the mapping run depends on: another key (an upgrade rebuilds the map)
    with monkeypatch.context() as m:
        m.setattr(maps, "mapping_libraries", lambda: ("pymunk==0.0", "numpy==0.0", "numba==0.0"))
        assert maps.map_key(layout, lidar, camera) != files[0].stem
    # a corrupt file is rebuilt and replaced
    files[0].write_bytes(b"not a map")
    maps._memory.clear()
    again = maps.mapped(layout, lidar, camera)
    np.testing.assert_array_equal(again.occupancy, built.occupancy)
    assert files[0].stat().st_size > 1000


def test_disk_cache_can_be_switched_off(tmp_path, monkeypatch):
    from semreloc_env import maps

    monkeypatch.setenv("SEMRELOC_CACHE_DIR", "")
    assert maps.cache_dir() is None
    monkeypatch.setenv("SEMRELOC_CACHE_DIR", str(tmp_path))
    assert maps.cache_dir() == tmp_path / "maps"
    monkeypatch.delenv("SEMRELOC_CACHE_DIR")
    monkeypatch.delenv("XDG_CACHE_HOME", raising=False)
    assert maps.cache_dir().parts[-3:] == (".cache", "semreloc", "maps")


def test_the_cache_folder_in_odd_environments(tmp_path, monkeypatch):
    # a nineteenth tester's: "~/x" made a folder named "~" in the working directory; no HOME and no user entry
    # (a container under an arbitrary uid) crashed gym.make; an empty HOME wrote to /.cache
    from semreloc_env import maps

    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    monkeypatch.setenv("SEMRELOC_CACHE_DIR", "~/x")
    assert maps.cache_dir() == tmp_path / "home" / "x" / "maps"
    monkeypatch.setenv("SEMRELOC_CACHE_DIR", "rel")
    assert maps.cache_dir() == tmp_path / "rel" / "maps"
    monkeypatch.delenv("SEMRELOC_CACHE_DIR")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert maps.cache_dir() == tmp_path / "xdg" / "semreloc" / "maps"
    monkeypatch.setenv("XDG_CACHE_HOME", "relative")  # ignored, as the XDG spec says
    assert maps.cache_dir() == tmp_path / "home" / ".cache" / "semreloc" / "maps"
    monkeypatch.delenv("XDG_CACHE_HOME")

    def no_user():
        raise KeyError("getpwuid(): uid not found: 12345")

    monkeypatch.setattr(maps, "pwd_home", no_user)
    for home in (None, ""):
        if home is None:
            monkeypatch.delenv("HOME")
        else:
            monkeypatch.setenv("HOME", home)
        assert maps.cache_dir() is None


def test_a_tilde_without_a_home_folder_switches_the_disk_cache_off(monkeypatch):
    # a review's: SEMRELOC_CACHE_DIR="~/cache" (a Dockerfile's ENV does not expand "~") with no home folder
    # still crashed gym.make in Path.expanduser
    from semreloc_env import maps

    def no_home(self):
        raise RuntimeError("Could not determine home directory.")

    monkeypatch.setattr(maps.Path, "expanduser", no_home)
    for var in ("SEMRELOC_CACHE_DIR", "XDG_CACHE_HOME"):
        monkeypatch.delenv("SEMRELOC_CACHE_DIR", raising=False)
        monkeypatch.setenv(var, "~/cache")
        assert maps.cache_dir() is None


def test_cache_files_hold_their_key_keep_the_umask_and_stale_temporaries_go(tmp_path, monkeypatch):
    # a nineteenth tester's: another layout's valid file under a key was served (a 4.8 m error at reset), files
    # were 0600 whatever the umask, and a save killed before its rename left its .tmp for ever
    import os
    import time

    from semreloc_env import maps
    from semreloc_env.config import CameraParams, LidarParams
    from semreloc_env.layouts import get_layout

    monkeypatch.setenv("SEMRELOC_CACHE_DIR", str(tmp_path))
    maps._memory.clear()
    lidar, camera = LidarParams(), CameraParams()
    a, b = get_layout("twin_rooms"), get_layout("lab")
    old = os.umask(0o002)
    try:
        grid_a = maps.mapped(a, lidar, camera)
        grid_b = maps.mapped(b, lidar, camera)
    finally:
        os.umask(old)
    key_a, key_b = maps.map_key(a, lidar, camera), maps.map_key(b, lidar, camera)
    folder = tmp_path / "maps"
    assert (folder / f"{key_a}.npz").stat().st_mode & 0o777 == 0o664
    (folder / f"{key_a}.npz").write_bytes((folder / f"{key_b}.npz").read_bytes())
    stale, fresh = folder / f"{maps._TMP_PREFIX}old.tmp", folder / f"{maps._TMP_PREFIX}new.tmp"
    theirs = folder / "survey.tmp"  # not the package's: never deleted
    for f in (stale, fresh, theirs):
        f.write_bytes(b"x")
    for f in (stale, theirs):
        os.utime(f, (time.time() - 2 * maps.STALE_TMP_S,) * 2)
    maps._memory.clear()
    again = maps.mapped(a, lidar, camera)  # the lab's map under twin_rooms' key is rebuilt, not served
    assert again.occupancy.shape == grid_a.occupancy.shape != grid_b.occupancy.shape
    np.testing.assert_array_equal(again.occupancy, grid_a.occupancy)
    assert not stale.exists() and fresh.exists() and theirs.exists()  # a save under way may own a new one


def test_an_unwritable_cache_warns_once_and_the_env_still_works(tmp_path, monkeypatch):
    import warnings

    from semreloc_env import maps
    from semreloc_env.config import CameraParams, LidarParams
    from semreloc_env.layouts import get_layout

    (tmp_path / "file").write_text("a file where the folder should be")
    monkeypatch.setenv("SEMRELOC_CACHE_DIR", str(tmp_path / "file"))
    monkeypatch.setattr(maps, "_unwritable", set())
    maps._memory.clear()
    with pytest.warns(UserWarning, match="could not be written"):
        maps.mapped(get_layout("twin_rooms"), LidarParams(), CameraParams())
    maps._memory.clear()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        maps.mapped(get_layout("twin_rooms"), LidarParams(), CameraParams())


def test_mapping_tour_visits_every_free_waypoint_without_all_pairs_paths():
    from semreloc_env.layouts import get_layout
    from semreloc_env.layouts.tiling import tiled_layout
    from semreloc_env.mapping_run import _lattice, mapping_drive

    layout = tiled_layout(get_layout("twin_rooms"), 2, 1)
    pts, indptr, indices = _lattice(layout, 0.6)
    poses, lidar_due = mapping_drive(layout)
    visited = {tuple(p) for p in np.round(poses[:, :2], 9).tolist()}
    assert all(tuple(p) in visited for p in np.round(pts, 9).tolist())
    # consecutive poses are a hop apart at most (or a jump to a new leg), the lidar runs at 1 in 4 turn headings
    steps = np.linalg.norm(np.diff(poses[:, :2], axis=0), axis=1)
    assert np.mean(steps <= 0.2 + 1e-9) > 0.99
    assert 0.2 < lidar_due.mean() < 0.6


def test_the_narrow_drive_enters_a_corridor_between_the_lattices_rows():
    """Two rooms joined by a 1 m corridor whose free band (0.3 m clearance) lies between the 0.6 m lattice's rows
    2.1 and 2.7 m: the plain drive has no waypoint in it, the narrow drive (mapping run version 6) does, keeps
    every lattice waypoint first and in order, and adds only feasible waypoints, none within the lattice's
    spacing of another's."""
    from semreloc_env.layouts import get_layout
    from semreloc_env.mapping_run import _lattice, mapping_drive
    from semreloc_env.world import build_world

    outer = [[0, 0], [4, 0], [4, 1.9], [10, 1.9], [10, 0], [14, 0], [14, 4], [10, 4], [10, 2.9], [4, 2.9]]
    outer += [[4, 4], [0, 4]]
    layout = get_layout({"name": "corridor", "outer": outer})
    world = build_world(layout)
    plain, _, _ = _lattice(layout, 0.6)
    pts, indptr, indices = _lattice(layout, 0.6, narrow=True)
    np.testing.assert_array_equal(pts[: len(plain)], plain)
    extra = pts[len(plain) :]
    in_corridor = (extra[:, 0] > 4.3) & (extra[:, 0] < 9.7)
    assert in_corridor.sum() >= 6  # one every 0.75 m along 5.4 m (0.15 m lattice points more than 0.6 m apart)
    assert not ((plain[:, 0] > 4.3) & (plain[:, 0] < 9.7)).any()
    assert world.free_points(extra, margin_m=0.1).all()
    d = np.linalg.norm(extra[:, None] - extra[None], axis=2) + np.eye(len(extra)) * 9
    assert d.min() > 0.6
    # the corridor's waypoints are joined: one drive, no jump between the rooms
    from semreloc_env.mapping_run import _greedy_tour

    _, driven = _greedy_tour(indptr, indices, len(pts))
    assert driven[1:].all()
    for narrow in (False, True):
        poses, _ = mapping_drive(layout, narrow=narrow)
        inside = (poses[:, 0] > 4.5) & (poses[:, 0] < 9.5)
        assert inside.any() == narrow
        a, b = mapping_drive(layout, narrow=narrow)[0], mapping_drive(layout, narrow=narrow)[0]
        np.testing.assert_array_equal(a, b)
    # a layout that is only such a corridor: version 5's drive found no waypoint, version 6's drives it
    import pytest

    from semreloc_env.layouts import LayoutError

    only = get_layout({"name": "only_corridor", "outer": [[0, 1.9], [8, 1.9], [8, 2.9], [0, 2.9]]})
    with pytest.raises(LayoutError, match="0.6 m waypoint lattice.*version 6 also looks"):
        mapping_drive(only)
    poses, _ = mapping_drive(only, narrow=True)
    assert poses[:, 0].min() < 1.0 and poses[:, 0].max() > 7.0
    tiny = get_layout({"name": "tiny", "outer": [[0, 0], [0.5, 0], [0.5, 0.5], [0, 0.5]]})  # the robot's disc only
    with pytest.raises(LayoutError, match="0.15 m waypoint lattice has the robot's disc 0.1 m clear"):
        mapping_drive(tiny, narrow=True)


def test_greedy_cover_keeps_what_the_pairwise_definition_keeps():
    """`_greedy_cover` files kept points in cells (a review measured the first, pairwise version at 55 s on a
    300 m x 300 m maze of 0.9 m corridors); it must keep exactly the points the definition keeps."""
    from semreloc_env.mapping_run import _greedy_cover

    def pairwise(xy, r):
        kept = []
        for i, p in enumerate(xy):
            if all((p[0] - xy[j][0]) ** 2 + (p[1] - xy[j][1]) ** 2 > r * r for j in kept):
                kept.append(i)
        return kept

    rng = np.random.default_rng(5)
    for n, side, r in ((0, 1.0, 0.6), (1, 1.0, 0.6), (400, 6.0, 0.6), (400, 3.0, 0.25), (300, 40.0, 0.6)):
        xy = rng.uniform(-side, side, (n, 2))
        xy[: n // 4] = np.round(xy[: n // 4] / r) * r  # points on the cells' edges, exactly r apart
        assert np.flatnonzero(_greedy_cover(xy, r)).tolist() == pairwise(xy, r)


def test_tiled_layout_repeats_the_base_and_checks_its_arguments():
    import pytest

    from semreloc_env.layouts import get_layout
    from semreloc_env.layouts.tiling import tiled_layout
    from semreloc_env.world import build_world

    lab = get_layout("lab")
    big = tiled_layout(lab, 3, 2)
    assert big.bounds() == (0.0, 45.0, 0.0, 20.0)
    assert len(big.objects) == 6 * len(lab.objects)
    world = build_world(big)
    # the tiles are joined: a pose in the far tile is free, and the doorway between tiles is open
    assert world.is_free([15.0 + 7.5, 10.0 + 2.0])
    from semreloc_env.layouts.tiling import _gap_centre

    gy, gx = _gap_centre(lab, False, 0.8), _gap_centre(lab, True, 0.8)
    assert world.is_free([15.0, gy]) and world.is_free([gx, 10.0])  # doorways in the shared walls
    assert not world.is_free([15.0, gy + 0.5]) and not world.is_free([gx + 0.5, 10.0])
    from semreloc_env.mapping_run import _greedy_tour, _lattice

    _, indptr, indices = _lattice(big, 0.6)
    _, driven = _greedy_tour(indptr, indices, len(indptr) - 1)
    assert np.sum(~driven) <= 3  # (nearly) one connected drive: the tiles are joined
    with pytest.raises(ValueError, match="nx"):
        tiled_layout(lab, 0, 1)
    with pytest.raises(ValueError, match="rectangle"):
        tiled_layout(get_layout({"outer": [[0, 0], [4, 0], [2, 3]]}), 2, 2)


def test_array_level_mapper_updates_equal_the_scan_object_path():
    from filters.mapping.occupancy import OccupancyMapper, OccupancyParams, SemanticMapper
    from filters.robot_data.scans import LaserScan, SemanticScan

    rng = np.random.default_rng(3)
    n, b = 40, 30
    poses = np.column_stack([rng.uniform(1, 4, n), rng.uniform(1, 4, n), rng.uniform(-np.pi, np.pi, n)])
    angles = np.linspace(-1.0, 1.0, b)
    ranges = rng.uniform(0.0, 6.0, (n, b))  # some beyond the 5 m range: no return
    labels = rng.integers(0, 5, (n, b))
    for params in (OccupancyParams(), OccupancyParams(clear_no_return=False)):
        a, c = OccupancyMapper((100, 100), 0.05, params=params), OccupancyMapper((100, 100), 0.05, params=params)
        a.update_many(poses, [LaserScan(r, angles, 5.0) for r in ranges])
        c.update_arrays(poses, ranges, angles, 5.0)
        np.testing.assert_array_equal(a.logodds, c.logodds)
    a, c = SemanticMapper((100, 100), 0.05), SemanticMapper((100, 100), 0.05)
    a.update_many(poses, [SemanticScan(r, angles, lab, 5.0) for r, lab in zip(ranges, labels)])
    c.update_arrays(poses, ranges, labels, angles, 5.0)
    np.testing.assert_array_equal(a.logodds, c.logodds)
    import pytest

    with pytest.raises(ValueError, match="labels"):
        c.update_arrays(poses, ranges, labels + 5, angles, 5.0)
    with pytest.raises(ValueError, match="ranges"):
        c.update_arrays(poses, ranges[:3], labels[:3], angles, 5.0)
