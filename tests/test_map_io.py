"""Map files: map_server YAML + PGM (P5 / P2) and semreloc's semantic sidecar."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from filters.mapping.grid import GridMap
from filters.mapping.ros_map import MapFormatError, load_map, read_pgm, save_map, semantic_yaml_path, write_pgm

# A 4 x 3 map as map_saver would draw it; first row = TOP of the map.
PIXELS_TOP_FIRST = np.array(
    [
        [0, 254, 205, 255],
        [254, 254, 0, 100],
        [0, 0, 0, 254],
    ],
    dtype=np.uint8,
)

MAP_YAML = """\
image: {image}
resolution: 0.1
origin: [-1.0, 2.0, 0.0]
negate: {negate}
occupied_thresh: 0.65
free_thresh: 0.196
{mode}
"""


def _write_map(folder: Path, *, image="lab.pgm", negate=0, mode="", yaml_text=None, fmt="P5") -> Path:
    if fmt == "P5":
        write_pgm(folder / "lab.pgm", PIXELS_TOP_FIRST)
    else:
        body = "\n".join(" ".join(str(v) for v in row) for row in PIXELS_TOP_FIRST)
        (folder / "lab.pgm").write_text(f"P2\n# written by hand\n4 3\n# maxval next\n255\n{body}\n")
    path = folder / "lab.yaml"
    path.write_text(yaml_text if yaml_text is not None else MAP_YAML.format(image=image, negate=negate, mode=mode))
    return path


# ------------------------------------------------------------------------------------------- hand-written files
@pytest.mark.parametrize("fmt", ["P5", "P2"])
def test_load_hand_written_map_server_map(tmp_path, fmt):
    grid = load_map(_write_map(tmp_path, fmt=fmt))
    assert grid.shape == (3, 4)
    assert grid.resolution_m == pytest.approx(0.1)
    assert grid.origin_xy_m == (-1.0, 2.0)
    assert grid.occupied_thresh == pytest.approx(0.65) and grid.free_thresh == pytest.approx(0.196)
    assert grid.class_names == () and grid.semantic.shape == (0, 3, 4)
    # row 0 of the grid is the BOTTOM image row; trinary gives 1 / 0 / 0.5
    expected_bottom_first = np.array(
        [
            [1.0, 1.0, 1.0, 0.0],
            [0.0, 0.0, 1.0, 0.5],  # 100 -> p = 155/255 = 0.61: unknown
            [1.0, 0.0, 0.5, 0.0],  # 205 -> p = 0.19608 > 0.196: unknown (the map_saver grey)
        ]
    )
    np.testing.assert_array_equal(grid.occupancy, expected_bottom_first)
    # origin: lower-left corner of the bottom-left pixel
    np.testing.assert_allclose(grid.cell_centers(np.array(0), np.array(0)), [-0.95, 2.05])
    row, col = grid.world_to_cell(np.array([[-0.95, 2.25], [-0.75, 2.05], [-0.61, 2.11]]))
    np.testing.assert_array_equal(row, [2, 0, 1])
    np.testing.assert_array_equal(col, [0, 2, 3])
    assert grid.occupied_mask()[2, 0] and grid.free_mask()[2, 1] and not grid.free_mask()[2, 2]


def test_negate_and_scale_mode(tmp_path):
    neg = load_map(_write_map(tmp_path, negate=1))
    # negate: p = v / 255, so black is free and white is occupied
    np.testing.assert_array_equal(neg.occupancy[2], [0.0, 1.0, 1.0, 1.0])
    np.testing.assert_array_equal(neg.occupancy[1], [1.0, 1.0, 0.0, 0.5])  # 100 -> 0.39: unknown

    scale = load_map(_write_map(tmp_path, mode="mode: scale"))
    np.testing.assert_allclose(scale.occupancy, (255.0 - np.flipud(PIXELS_TOP_FIRST)) / 255.0, atol=1e-6)
    # classification under the YAML thresholds is the same as trinary's
    tri = load_map(_write_map(tmp_path, mode="mode: trinary"))
    np.testing.assert_array_equal(scale.occupied_mask(), tri.occupied_mask())
    np.testing.assert_array_equal(scale.free_mask(), tri.free_mask())


def test_pgm_maxval_below_255_is_rescaled(tmp_path):
    (tmp_path / "small.pgm").write_text("P2 2 1 100\n0 100\n")
    np.testing.assert_array_equal(read_pgm(tmp_path / "small.pgm"), [[0, 255]])


# ------------------------------------------------------------------------------------------------ round trip
def _example_grid(rng: np.random.Generator) -> GridMap:
    h, w = 23, 31
    occ = rng.random((h, w)).astype(np.float32)
    occ[:, 3] = 0.0
    occ[5, :] = 1.0
    occ[10:12, 10:20] = 0.5
    sem = np.zeros((3, h, w), np.float32)
    sem[0, 2:6, 4:9] = 0.9
    sem[1] = rng.random((h, w))
    sem[2, 20:, 25:] = 1.0
    sem[2, :4, :4] = 0.5  # unobserved: exactly at the class threshold of the mapper's default 0.5 ...
    sem[0, :3, 20:] = 0.4  # ... and at this grid's threshold (0.4): neither is that class
    return GridMap(
        occupancy=occ,
        resolution_m=0.05,
        origin_xy_m=(-3.25, 1.5),
        semantic=sem,
        class_names=("door", "trash bin", "cabinet"),
        semantic_thresh=0.4,
    )


@pytest.mark.parametrize("mode", ["trinary", "scale"])
def test_round_trip_occupancy_and_semantic(tmp_path, mode):
    grid = _example_grid(np.random.default_rng(3))
    path = save_map(grid, tmp_path / "maps" / "lab.yaml", mode=mode)
    # the image's first row is the top of the map
    if mode == "trinary":
        assert (tmp_path / "maps" / "lab.pgm").read_bytes()[:2] == b"P5"
        img = read_pgm(tmp_path / "maps" / "lab.pgm")
    else:  # grey and alpha: unknown cells transparent, as nav2's map_saver writes them
        la = np.asarray(Image.open(tmp_path / "maps" / "lab.png"))
        img = la[..., 0]
        np.testing.assert_array_equal(la[..., 1] == 0, np.flipud(grid.occupancy == 0.5))
    assert img.shape == grid.shape
    assert np.all(img[-1 - 5] == 0)  # grid row 5 (all occupied) is image row H-1-5, black
    back = load_map(path)
    assert back.shape == grid.shape
    assert back.resolution_m == grid.resolution_m and back.origin_xy_m == grid.origin_xy_m
    assert back.class_names == grid.class_names and back.semantic_thresh == pytest.approx(0.4)
    np.testing.assert_array_equal(back.occupied_mask(), grid.occupied_mask())
    np.testing.assert_array_equal(back.free_mask(), grid.free_mask())
    if mode == "scale":
        np.testing.assert_allclose(back.occupancy, grid.occupancy, atol=1 / 255 + 1e-6)
    else:
        assert set(np.unique(back.occupancy).tolist()) <= {0.0, 0.5, 1.0}
    np.testing.assert_allclose(back.semantic, grid.semantic, atol=1 / 255 + 1e-6)
    for k in range(3):
        np.testing.assert_array_equal(back.class_mask(k), grid.class_mask(k))
    assert not back.class_mask(0)[:3, 20:].any()


def test_unobserved_semantic_cells_stay_below_the_default_threshold(tmp_path):
    occ = np.full((5, 6), 0.5, np.float32)
    sem = np.full((1, 5, 6), 0.5, np.float32)  # what a mapper reports for never-observed cells
    sem[0, 2, 3] = 0.7
    grid = GridMap(occ, 0.1, (0.0, 0.0), sem, ("door",))
    back = load_map(save_map(grid, tmp_path / "u.yaml"))
    assert back.class_mask(0).sum() == 1 and back.class_mask(0)[2, 3]
    np.testing.assert_allclose(back.semantic, grid.semantic, atol=1 / 255 + 1e-6)


def test_saving_a_map_without_classes_drops_a_stale_sidecar(tmp_path):
    grid = _example_grid(np.random.default_rng(0))
    save_map(grid, tmp_path / "m.yaml")
    assert semantic_yaml_path(tmp_path / "m.yaml").exists()
    plain = GridMap(occupancy=grid.occupancy, resolution_m=0.05)
    save_map(plain, tmp_path / "m.yaml")
    assert not semantic_yaml_path(tmp_path / "m.yaml").exists()
    assert load_map(tmp_path / "m.yaml").class_names == ()


def test_missing_yaml_is_file_not_found(tmp_path):
    with pytest.raises(FileNotFoundError):
        load_map(tmp_path / "nope.yaml")


# ------------------------------------------------------------------------------------------------- malformed
GOOD_KEYS = {
    "image": "image: lab.pgm",
    "resolution": "resolution: 0.1",
    "origin": "origin: [-1.0, 2.0, 0.0]",
    "occupied_thresh": "occupied_thresh: 0.65",
    "free_thresh": "free_thresh: 0.196",
}  # negate and mode are optional (map_server defaults 0 and trinary)


def _yaml_with(**override: str | None) -> str:
    lines = []
    for key, line in GOOD_KEYS.items():
        if key in override:
            if override[key] is None:
                continue
            line = override[key]
        lines.append(line)
    return "\n".join(lines) + "\n" + override.get("extra", "") + "\n"


YAML_CASES = {
    **{f"missing {k}": (_yaml_with(**{k: None}), f"missing key '{k}'") for k in GOOD_KEYS},
    "non-numeric resolution": (_yaml_with(resolution="resolution: fine"), "resolution must be a number"),
    "negative resolution in exponent form": (_yaml_with(resolution="resolution: -5e-2"), "resolution must be positive"),
    "negative resolution": (_yaml_with(resolution="resolution: -0.05"), "resolution must be positive"),
    "nonzero yaw": (_yaml_with(origin="origin: [0.0, 0.0, 0.3]"), "origin yaw is 0.3 rad; rotated maps are not"),
    "short origin": (_yaml_with(origin="origin: [0.0, 0.0]"), "origin must be a list"),
    "bad negate": (_yaml_with(extra="negate: 2"), "negate must be 0 or 1"),
    "thresholds swapped": (
        _yaml_with(occupied_thresh="occupied_thresh: 0.1", free_thresh="free_thresh: 0.9"),
        "free_thresh",
    ),
    "unknown mode": (_yaml_with(extra="mode: fancy"), "mode 'fancy' is not supported"),
    "not yaml": ("image: [unclosed\n", "not valid YAML"),
    "not a mapping": ("- 1\n- 2\n", "expected a YAML mapping"),
    "image file missing": (_yaml_with(image="image: elsewhere.pgm"), "image file not found"),
}


@pytest.mark.parametrize("case", sorted(YAML_CASES))
def test_malformed_yaml_raises_naming_the_file(tmp_path, case):
    text, problem = YAML_CASES[case]
    path = _write_map(tmp_path, yaml_text=text)
    with pytest.raises(MapFormatError) as err:
        load_map(path)
    named = "elsewhere.pgm" if case == "image file missing" else "lab.yaml"
    assert named in str(err.value) and err.value.path.endswith(named)
    assert problem in str(err.value)
    assert isinstance(err.value, ValueError)


PGM_CASES = {
    "bad magic": (b"Q5\n4 3\n255\n" + bytes(36), "magic number"),
    "not a pgm at all": (b"\x89PNG\r\n\x1a\n", "magic number"),
    "non-integer size": (b"P5\nfour 3\n255\n" + bytes(12), "not integers"),
    "truncated header": (b"P5\n4 3", "ends inside the header"),
    "zero width": (b"P5\n0 3\n255\n", "image size"),
    "maxval above 16 bit": (b"P5\n4 3\n70000\n" + bytes(24), "maxval 70000"),
    "16-bit too few bytes": (b"P5\n4 3\n65535\n" + bytes(12), "wrong size"),
    "too few pixels": (b"P5\n4 3\n255\n" + bytes(11), "wrong size"),
    "too many pixels": (b"P5\n4 3\n255\n" + bytes(13), "wrong size"),
    "P2 too few pixels": (b"P2\n4 3\n255\n" + b"0 " * 11, "wrong size"),
    "P2 value above maxval": (b"P2\n2 1\n10\n3 11\n", "outside 0..10"),
}


@pytest.mark.parametrize("case", sorted(PGM_CASES))
def test_malformed_image_raises_naming_the_image(tmp_path, case):
    data, problem = PGM_CASES[case]
    path = _write_map(tmp_path)
    (tmp_path / "lab.pgm").write_bytes(data)
    with pytest.raises(MapFormatError) as err:
        load_map(path)
    assert "lab.pgm" in str(err.value) and problem in str(err.value)


def _saved_with_semantic(tmp_path: Path) -> Path:
    return save_map(_example_grid(np.random.default_rng(1)), tmp_path / "lab.yaml")


def _edit_semantic(tmp_path: Path, old: str, new: str) -> Path:
    sem = tmp_path / "lab.semantic.yaml"
    text = sem.read_text()
    assert old in text, text
    sem.write_text(text.replace(old, new))
    return sem


SEMANTIC_CASES = {
    "resolution differs": (("resolution: 0.05", "resolution: 0.1"), "lab.semantic.yaml", "resolution 0.1 differs"),
    "origin differs": (("origin: [-3.25, 1.5, 0.0]", "origin: [0.0, 1.5, 0.0]"), "lab.semantic.yaml", "origin"),
    "yaw": (("origin: [-3.25, 1.5, 0.0]", "origin: [-3.25, 1.5, 1.0]"), "lab.semantic.yaml", "rotated"),
    "width differs": (("width: 31", "width: 30"), "lab.semantic.yaml", "width is 30"),
    "no classes key": (("classes:", "klasses:"), "lab.semantic.yaml", "missing key 'classes'"),
    "wrong format tag": (("semreloc-semantic/1", "something/9"), "lab.semantic.yaml", "format is"),
    "class image missing": (("lab.semantic.door.pgm", "gone.pgm"), "gone.pgm", "image file not found"),
    "bad threshold": (("semantic_thresh: 0.4", "semantic_thresh: high"), "lab.semantic.yaml", "must be a number"),
}


@pytest.mark.parametrize("case", sorted(SEMANTIC_CASES))
def test_malformed_semantic_sidecar_raises_naming_the_file(tmp_path, case):
    (old, new), named, problem = SEMANTIC_CASES[case]
    path = _saved_with_semantic(tmp_path)
    _edit_semantic(tmp_path, old, new)
    with pytest.raises(MapFormatError) as err:
        load_map(path)
    assert named in str(err.value) and problem in str(err.value)


def test_mismatched_semantic_raster_raises(tmp_path):
    path = _saved_with_semantic(tmp_path)
    write_pgm(tmp_path / "lab.semantic.cabinet.pgm", np.zeros((23, 30), np.uint8))
    with pytest.raises(MapFormatError, match=r"lab\.semantic\.cabinet\.pgm: semantic raster .* expected 31 x 23"):
        load_map(path)


def test_explicit_semantic_yaml_must_exist(tmp_path):
    path = _saved_with_semantic(tmp_path)
    with pytest.raises(FileNotFoundError):
        load_map(path, semantic_yaml=tmp_path / "other.semantic.yaml")


def test_derived_masks_are_computed_once_read_only_and_match_the_thresholds():
    from filters.mapping.grid import DEFAULT_CLASS_NAMES

    rng = np.random.default_rng(0)
    occ = rng.random((30, 40)).astype(np.float32)
    sem = (rng.random((len(DEFAULT_CLASS_NAMES), 30, 40)) < 0.1).astype(np.float32)
    grid = GridMap(occ, 0.05, (1.0, -2.0), sem, DEFAULT_CLASS_NAMES)
    assert grid.free_mask() is grid.free_mask() and not grid.free_mask().flags.writeable
    np.testing.assert_array_equal(grid.free_mask(), occ < grid.free_thresh)
    np.testing.assert_array_equal(grid.occupied_mask(), occ > grid.occupied_thresh)
    np.testing.assert_array_equal(grid.free_cells(), np.flatnonzero(occ < grid.free_thresh))
    for k in range(len(DEFAULT_CLASS_NAMES)):
        np.testing.assert_array_equal(grid.class_mask(k), sem[k] > 0.5)
        np.testing.assert_array_equal(grid.class_cells(k), np.flatnonzero(sem[k] > 0.5))
    assert grid.class_mask(-1) is grid.class_mask(len(DEFAULT_CLASS_NAMES) - 1)
    with pytest.raises(IndexError, match="class index"):
        grid.class_mask(len(DEFAULT_CLASS_NAMES))
    with pytest.raises(ValueError):
        grid.free_mask()[0, 0] = True
    with pytest.raises(TypeError, match="class index"):
        grid.class_mask(1.5)
    import copy
    import pickle

    for twin in (pickle.loads(pickle.dumps(grid)), copy.deepcopy(grid)):
        assert "_derived_arrays" not in twin.__dict__  # the cache is not carried along
        assert not twin.occupancy.flags.writeable and not twin.semantic.flags.writeable
        assert not twin.free_mask().flags.writeable
        np.testing.assert_array_equal(twin.free_mask(), grid.free_mask())


def test_build_maps_command_names_both_maps_after_the_layout(tmp_path, capsys):
    """``build_maps --perfect`` wrote ``cabinet.perfect.*`` for every layout (a loop variable shadowed
    the layout's name), so two layouts built into one folder overwrote each other's perfect map."""
    from semreloc_env.tools.build_maps import main

    assert main(["--layout", "twin_rooms", "--perfect", "--out", str(tmp_path)]) == 0
    names = sorted(p.name for p in tmp_path.glob("*.yaml"))
    assert "twin_rooms.yaml" in names and "twin_rooms.perfect.yaml" in names, names
    assert not any(n.startswith(("door", "chair", "trash_bin", "cabinet")) for n in names), names


def test_build_maps_refuses_a_seed_a_file_ignores_and_names_files_by_their_own_name(tmp_path, capsys):
    """An outside audit: `--layout my.yaml --layout-seed 3` was taken and the seed ignored (gym.make refuses it),
    and a file named `procedural_office` wrote `procedural_office_0.*`, a file named `procedural` the real procedural
    seed 0's names."""
    import json

    from semreloc_env.layouts import get_layout
    from semreloc_env.tools.build_maps import main

    office = tmp_path / "procedural_office.json"
    office.write_text(json.dumps(get_layout("twin_rooms").to_dict() | {"name": "procedural_office"}))
    with pytest.raises(SystemExit) as e:
        main(["--layout", str(office), "--layout-seed", "3", "--out", str(tmp_path / "m")])
    assert e.value.code == 2 and "layout_seed=3 seeds only the procedural layouts" in capsys.readouterr().err
    assert main(["--layout", str(office), "--out", str(tmp_path / "m")]) == 0
    assert sorted(p.name for p in (tmp_path / "m").glob("*.yaml")) == [
        "procedural_office.semantic.yaml", "procedural_office.yaml",
    ]  # fmt: skip


def test_a_yml_map_finds_its_sidecar_under_either_spelling(tmp_path):
    # a new user's trial: name.semantic.yml beside name.yml was silently ignored
    grid = _example_grid(np.random.default_rng(1))
    path = save_map(grid, tmp_path / "b.yml")
    assert semantic_yaml_path(path).name == "b.semantic.yml" and semantic_yaml_path(path).exists()
    assert load_map(path).class_names == grid.class_names
    semantic_yaml_path(path).rename(tmp_path / "b.semantic.yaml")  # the other spelling
    assert semantic_yaml_path(path).name == "b.semantic.yaml"
    assert load_map(path).class_names == grid.class_names


def test_a_16_bit_class_image_says_class_images_are_8_bit(tmp_path):
    path = tmp_path / "c.pgm"
    path.write_bytes(b"P5 2 1 65535\n" + bytes(4))
    with pytest.raises(MapFormatError, match="maxval 65535: an 8-bit greymap .* semantic class image"):
        read_pgm(path)


def test_a_map_yaml_takes_numbers_in_exponent_form_as_ros_does(tmp_path):
    """PyYAML reads ``5e-2`` as a string; ROS's map_server reads map YAMLs with yaml-cpp, which takes it for a
    number, so a map ROS loads loads here too (an outside tester's hand-edited origin)."""
    path = _write_map(tmp_path, yaml_text=_yaml_with(resolution="resolution: 5e-2", origin="origin: [-1e2, 5.7E1, 0]"))
    grid = load_map(path)
    assert grid.resolution_m == 0.05 and grid.origin_xy_m == (-100.0, 57.0)


def test_save_refuses_thresholds_that_cannot_keep_the_unknown_cells(tmp_path):
    # a twentieth tester's: equal thresholds wrote unknown cells as 128, which read back as free
    grid = GridMap(np.array([[0.5, 0.0], [1.0, 0.5]], np.float32), 0.1, occupied_thresh=0.5, free_thresh=0.5)
    for mode in ("trinary", "scale"):
        with pytest.raises(ValueError, match="no grey level reads back"):
            save_map(grid, tmp_path / f"{mode}.yaml", mode=mode)
        assert not list(tmp_path.iterdir())  # nothing written
    known = GridMap(np.array([[0.0, 1.0]], np.float32), 0.1, occupied_thresh=0.5, free_thresh=0.5)
    np.testing.assert_array_equal(load_map(save_map(known, tmp_path / "k.yaml")).occupancy, known.occupancy)


@pytest.mark.parametrize("name", ["../escaped", "", "sub/dir"])
def test_build_maps_refuses_a_layout_name_that_is_not_a_plain_file_name(tmp_path, name):
    # an outside audit's: '../escaped' wrote the maps beside --out, '' failed after the whole mapping run
    from semreloc_env.tools.build_maps import Args

    f = tmp_path / "lay.json"
    f.write_text(json.dumps({"name": name, "outer": [[0, 0], [3, 0], [3, 3], [0, 3]]}))
    with pytest.raises(ValueError, match="cannot name the map files in --out"):
        Args(layout=str(f), out=str(tmp_path / "out"))
