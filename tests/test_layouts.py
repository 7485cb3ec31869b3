import json
import math

import gymnasium as gym
import numpy as np
import pytest
import yaml

import semreloc_env  # noqa: F401
from semreloc_env.layouts import (
    CLASS_NAMES,
    LayoutError,
    ProceduralParams,
    get_layout,
    layout_from_dict,
    load_layout,
    procedural_layout,
)

SQUARE = [[0, 0], [4, 0], [4, 4], [0, 4]]


@pytest.mark.parametrize("name", ["lab", "twin_rooms"])
def test_builtin_layouts_have_every_class(name):
    assert {o.cls for o in get_layout(name).objects} == set(CLASS_NAMES)


@pytest.mark.parametrize("name", ["procedural", "procedural_sym"])
def test_procedural_layouts_keep_room_widths_in_range_for_many_seeds(name):
    lo, hi = ProceduralParams().room_width_m
    for seed in range(100):
        layout = get_layout(name, seed=seed)
        x0, x1, y0, y1 = layout.bounds()
        mid = (y0 + y1) / 2
        for north in (False, True):
            xs = sorted(
                w[0][0]
                for w in layout.walls
                if len(w) == 2 and w[0][0] == w[1][0] and ((w[0][1] + w[1][1]) / 2 > mid) == north
            )
            widths = np.diff([x0, *xs, x1])
            assert np.all(widths >= lo - 1e-9) and np.all(widths <= hi + 1e-9), (name, seed, north, widths)


def test_lab_size_and_counts():
    lab = get_layout("lab")
    assert lab.bounds() == (0.0, 15.0, 0.0, 10.0)
    counts = {c: sum(o.cls == c for o in lab.objects) for c in CLASS_NAMES}
    assert all(n >= 3 for n in counts.values()), counts


def _half_turn_invariant(layout) -> bool:
    x0, x1, y0, y1 = layout.bounds()
    c = np.array([(x0 + x1) / 2, (y0 + y1) / 2])

    def canon(segs):
        s = np.round(segs, 6)
        keep = (s[:, 0, 0] < s[:, 1, 0]) | ((s[:, 0, 0] == s[:, 1, 0]) & (s[:, 0, 1] <= s[:, 1, 1]))
        s = np.where(keep[:, None, None], s, s[:, ::-1])
        return sorted(map(lambda a: tuple(a.ravel()), s))

    walls = layout.wall_segments()
    obj, _ = layout.object_segments()
    segs = np.concatenate([walls, obj])
    return canon(segs) == canon(2 * c - segs)


def test_twin_rooms_geometry_is_symmetric_but_classes_differ():
    twin = get_layout("twin_rooms")
    assert _half_turn_invariant(twin)
    west = sorted(
        (round(o.centroid()[0], 3), round(o.centroid()[1], 3), o.cls) for o in twin.objects if o.centroid()[0] < 6
    )
    east = {
        (round(12 - o.centroid()[0], 3), round(6 - o.centroid()[1], 3)): o.cls
        for o in twin.objects
        if o.centroid()[0] > 6
    }
    assert len(west) == len(east) == 4
    for x, y, cls in west:
        assert east[(x, y)] != cls  # same footprint at the twin place, another class


def test_procedural_is_deterministic_and_symmetric_option_works():
    a = procedural_layout(np.random.default_rng(7))
    b = procedural_layout(np.random.default_rng(7))
    assert a == b
    assert procedural_layout(np.random.default_rng(8)) != a
    for seed in range(5):
        sym = layout_from_dict(procedural_layout(np.random.default_rng(seed), ProceduralParams(symmetric=True)))
        assert _half_turn_invariant(sym)
        plain = layout_from_dict(procedural_layout(np.random.default_rng(seed)))
        assert len(plain.objects) >= 2


def test_load_json_and_yaml_roundtrip(tmp_path):
    lab = get_layout("lab")
    (tmp_path / "lab.json").write_text(json.dumps(lab.to_dict()))
    (tmp_path / "lab.yaml").write_text(yaml.safe_dump(lab.to_dict()))
    for f in ("lab.json", "lab.yaml"):
        loaded = load_layout(tmp_path / f)
        assert loaded.to_dict() == lab.to_dict()
    assert get_layout(str(tmp_path / "lab.json")).to_dict() == lab.to_dict()


def _obj(cls="chair", poly=((1, 1), (2, 1), (2, 2), (1, 2)), **kw):
    return {"class": cls, "polygon": [list(p) for p in poly], **kw}


@pytest.mark.parametrize(
    "data, match",
    [
        ({"outer": SQUARE, "objects": [_obj(cls="sofa")]}, r"objects\[0\].*unknown class 'sofa'"),
        ({"outer": SQUARE, "objects": [{"polygon": [[1, 1], [2, 1], [2, 2]]}]}, r"objects\[0\].*no 'class' key"),
        ({"outer": SQUARE, "objects": [_obj(poly=((1, 1), (2, 2), (2, 1), (1, 2)))]}, "self-intersecting"),
        ({"outer": SQUARE, "objects": [_obj(poly=((1, 1), (2, 1)))]}, "at least 3"),
        ({"outer": SQUARE, "objects": [_obj(poly=((1, 1), (2, 1), (3, 1)))]}, "zero area"),
        (
            {"outer": SQUARE, "objects": [_obj(poly=((3, 3), (5, 3), (5, 5), (3, 5)), name="bad_bin")]},
            r"bad_bin.*outside",
        ),
        ({"outer": SQUARE, "objects": [_obj(poly=((1, 1), (math.nan, 1), (2, 2)))]}, "NaN"),
        ({"outer": SQUARE, "walls": [[[1, 1], [9, 1]]]}, r"walls\[0\].*outside"),
        ({"outer": SQUARE, "walls": [[[1, 1]]]}, r"walls\[0\].*at least 2"),
        ({"outer": [[0, 0], [4, 4], [4, 0], [0, 4]]}, "outer.*self-intersecting"),
        ({"outer": SQUARE, "furniture": []}, "unknown layout keys"),
        ({"outer": SQUARE, "objects": [{**_obj(), "colour": "red"}]}, "unknown keys"),
        ({"walls": []}, "no 'outer'"),
        ({"outer": "square"}, "outer"),
        (
            {
                "outer": SQUARE,
                "objects": [_obj(name="bin"), _obj(poly=((2.5, 1), (3, 1), (3, 1.5), (2.5, 1.5)), name="bin")],
            },
            r"objects\[1\] \(bin\): name 'bin' already used by objects\[0\]",
        ),
    ],
)
def test_malformed_layouts_name_the_entry(data, match):
    with pytest.raises(LayoutError, match=match):
        layout_from_dict(data)


@pytest.mark.parametrize(
    "obj, match",
    [  # a new user's trial: a number or bool where a polygon belongs gave a bare TypeError
        ({"class": "chair", "polygon": 0.5}, r"objects\[0\]: expected a list of \[x, y\] points, got float"),
        ({"class": "chair", "polygon": True}, r"objects\[0\]: expected a list of \[x, y\] points, got bool"),
        ({"class": "chair", "center": [1, 1], "size": 0.5}, r"objects\[0\]\.size: expected an \[x, y\] pair"),
        ({"class": "chair", "center": 1, "size": [1, 1]}, r"objects\[0\]\.center: expected an \[x, y\] pair"),
        ({"class": "chair", "center": [1, 1], "size": [1, 0.5, 2]}, r"objects\[0\]\.size: expected an \[x, y\]"),
        ({"class": "chair", "center": ["1e-3", 1], "size": [1, 1]}, r"center: .*str '1e-3'.*write 1\.0e-3"),
        ({"class": "chair", "center": ["1.0e0", 1], "size": [1, 1]}, r"'1.0e0' \(YAML .*signed exponent"),
        ({"class": "chair", "center": [1, 1], "size": [1, 1], "angle_rad": "1e-3"}, r"angle_rad.*'1e-3' \(YAML"),
        # an outside tester's YAML file: `angle_rad: no` read as False, and the message said only "got False"
        ({"class": "chair", "center": [1, 1], "size": [1, 1], "angle_rad": False}, r"got False \(a boolean; in a YAML"),
        ({"class": "chair", "center": [True, 1], "size": [1, 1]}, r"got bool True \(a boolean; in a YAML file yes/no"),
        # a polygon with angle_rad was told "not both" of polygon and center/size, which it did not give
        (
            {"class": "chair", "polygon": [[1, 1], [2, 1], [2, 2]], "angle_rad": 0.3},
            r"it has 'polygon' and \['angle_rad'\] \(a polygon's corners carry its turn\)",
        ),
        ({"class": "chair", "center": ["nan", 1], "size": [1, 1]}, r"got str 'nan'$"),
        ({"class": "chair", "polygon": np.array(0.5)}, r"objects\[0\]: expected a list of \[x, y\] points"),
        ({"class": "chair", "polygon": [[1, 1], [2, 1], [2]]}, r"objects\[0\]\[2\]: expected an \[x, y\] point"),
        ({"class": "chair", "center": [1, 1], "size": [1e-7, 1e-7]}, "zero area.*too close"),
    ],
)
def test_wrong_types_in_an_object_name_the_entry(obj, match):
    with pytest.raises(LayoutError, match=match):
        layout_from_dict({"outer": SQUARE, "objects": [obj]})


def test_a_numpy_polygon_is_taken_like_a_list():
    poly = np.array([[1, 1], [1.5, 1], [1.5, 1.5], [1, 1.5]])
    from_array = layout_from_dict({"outer": SQUARE, "objects": [{"class": "chair", "polygon": poly}]})
    from_list = layout_from_dict({"outer": SQUARE, "objects": [{"class": "chair", "polygon": poly.tolist()}]})
    assert from_array.to_dict() == from_list.to_dict()


def test_unnamed_objects_get_names_no_other_object_has():
    second = ((2.5, 1), (3, 1), (3, 1.5), (2.5, 1.5))
    layout = layout_from_dict({"outer": SQUARE, "objects": [_obj(name="chair_1"), _obj(poly=second)]})
    assert [o.name for o in layout.objects] == ["chair_1", "chair_1_2"]
    plain = layout_from_dict({"outer": SQUARE, "objects": [_obj(), _obj(poly=second)]})
    assert [o.name for o in plain.objects] == ["chair_0", "chair_1"]


def test_malformed_files(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    with pytest.raises(LayoutError, match="bad.json.*not valid JSON"):
        load_layout(bad)
    bad_yaml = tmp_path / "bad.yaml"
    bad_yaml.write_text("outer: [[0, 0], [1, 0]\n")
    with pytest.raises(LayoutError, match="bad.yaml"):
        load_layout(bad_yaml)
    sofa = tmp_path / "sofa.yaml"
    sofa.write_text(yaml.safe_dump({"outer": SQUARE, "objects": [_obj(cls="sofa")]}))
    with pytest.raises(LayoutError, match="sofa.yaml.*unknown class"):
        load_layout(sofa)
    with pytest.raises(LayoutError, match="not found"):
        load_layout(tmp_path / "missing.json")
    with pytest.raises(LayoutError, match="is a folder; give one layout file in it"):
        load_layout(tmp_path)
    with pytest.raises(LayoutError, match="unknown layout"):
        get_layout("hall")
    for empty in ("", "  "):  # was read as the current folder ("is a folder")
        with pytest.raises(LayoutError, match="the layout name is empty"):
            get_layout(empty)


def test_a_layout_path_may_start_with_a_tilde(tmp_path, monkeypatch):
    monkeypatch.setenv("HOME", str(tmp_path))
    d = get_layout("twin_rooms").to_dict()
    (tmp_path / "mine.json").write_text(json.dumps({**d, "name": "mine"}))
    assert get_layout("~/mine.json").name == "mine"
    assert load_layout("~/mine.json").name == "mine"


def test_a_ros_map_path_may_start_with_a_tilde(tmp_path, monkeypatch):
    import gymnasium as gym

    from filters.mapping.ros_map import save_map

    monkeypatch.setenv("HOME", str(tmp_path))
    env = gym.make("SemReloc-v22", layout="twin_rooms", map_source="perfect").unwrapped
    save_map(env.grid, tmp_path / "tw.yaml")
    assert gym.make("SemReloc-v22", layout="~/tw.yaml").unwrapped.layout.name == "tw"
    gym.make("SemReloc-v22", layout="twin_rooms", map_source="~/tw.yaml").reset(seed=0)
    import yaml

    (tmp_path / "tw_layout.yaml").write_text(yaml.safe_dump({**get_layout("twin_rooms").to_dict(), "name": "twl"}))
    gym.make("SemReloc-v22", layout="twin_rooms", map_source="~/tw_layout.yaml").reset(seed=0)  # a layout as the map


def test_a_layout_too_small_for_the_robot_is_a_layout_error(tmp_path):
    path = tmp_path / "tiny.json"
    path.write_text('{"outer": [[0, 0], [0.5, 0], [0.5, 0.5], [0, 0.5]]}')
    with pytest.raises(LayoutError, match="no free space"):
        gym.make("SemReloc-v22", layout=str(path))


def test_a_key_given_twice_in_a_layout_file_is_an_error_not_a_lost_entry(tmp_path):
    # a new user's trial: the parsers kept the last of two `objects:` keys (or of two "class" keys)
    (tmp_path / "d.yaml").write_text(
        "outer: [[0, 0], [5, 0], [5, 5], [0, 5]]\nobjects:\n  - {class: chair, center: [1, 1], size: [0.5, 0.5]}\n"
        "objects:\n  - {class: cabinet, center: [3, 1], size: [0.5, 0.5]}\n"
    )
    with pytest.raises(
        LayoutError, match=r"d.yaml: line 4: key 'objects' given twice in one mapping \(first on line 2\)"
    ):
        load_layout(tmp_path / "d.yaml")
    (tmp_path / "d.json").write_text(
        '{"outer": [[0, 0], [5, 0], [5, 5], [0, 5]], '
        '"objects": [{"class": "chair", "class": "door", "name": "c1", "center": [1, 1], "size": [0.5, 0.5]}]}'
    )
    with pytest.raises(LayoutError, match=r"d.json: key 'class' given twice in one object \(the one named 'c1'\)"):
        load_layout(tmp_path / "d.json")


def test_yaml_anchors_and_merge_keys_still_load(tmp_path):
    # the duplicate-key check must leave YAML's merge key alone (a review found it broke anchors)
    (tmp_path / "m.yaml").write_text(
        "outer: [[0, 0], [8, 0], [8, 8], [0, 8]]\nobjects:\n  - &c {class: chair, center: [1, 1], size: [0.5, 0.5]}\n"
        "  - {<<: *c, center: [5, 5]}\n"
    )
    layout = load_layout(tmp_path / "m.yaml")
    assert [o.cls for o in layout.objects] == ["chair", "chair"]
    assert layout.objects[1].centroid() == pytest.approx([5.0, 5.0])


def test_every_layout_file_the_docs_ship_loads():
    """The outside testers' layouts in docs/layouts are what the docs' commands evaluate: each must load."""
    from pathlib import Path

    files = sorted((Path(__file__).resolve().parents[1] / "docs" / "layouts").rglob("*.json"))
    assert len(files) >= 20
    for f in files:
        assert get_layout(str(f)).objects, f


@pytest.mark.parametrize("seed", [-1, 1.0, True, "3"])
def test_get_layout_checks_a_procedural_seed_as_the_env_does(seed):
    # an outside audit's: numpy's errors ("expected non-negative integer"), and True taken as seed 1
    from semreloc_env.layouts import get_layout

    with pytest.raises(ValueError, match="layout_seed must be an integer >= 0"):
        get_layout("procedural", seed=seed)
