"""`filters.unique_keys`: JSON and YAML that refuse a key given twice, and accept everything else as the parsers do."""

import json
import re

import pytest
import yaml

from filters.unique_keys import DuplicateKeyError, json_object_pairs, load_yaml

VALID = [
    "a: 1\nb: {c: 2, d: [1, 2]}\n",
    "base: &b {x: 1, y: 2}\nd:\n  <<: *b\n  x: 3\n",  # a merge key's keys may be overridden
    "a: &a {x: 1}\nb: &b {y: 2}\nd:\n  <<: [*a, *b]\n  z: 3\n",
    # a merging mapping inside a list, merged again later: PyYAML flattens it before it constructs it
    "base: &b {x: 1, y: 2}\nlist: [&c {<<: *b, x: 3}]\ne: {<<: *c, z: 5}\n",
    "a: &x [1, 2]\nb: *x\n",
]


@pytest.mark.parametrize("text", VALID)
def test_valid_yaml_loads_as_pyyaml_loads_it(text):
    assert load_yaml(text) == yaml.safe_load(text)


@pytest.mark.parametrize(
    "text, line, first",
    [("x: 1\ny: 2\nx: 3\n", 3, 1), ("a:\n  b: 1\n  b: 2\n", 3, 2), ("l:\n- {a: 1, a: 2}\n", 2, 2)],
)
def test_a_key_given_twice_is_refused_naming_both_lines(text, line, first):
    with pytest.raises(DuplicateKeyError, match=rf"line {line}: key '\w' given twice .*first on line {first}"):
        load_yaml(text)


def test_an_unhashable_key_is_the_loaders_own_error():
    with pytest.raises(yaml.YAMLError, match="unhashable"):  # not a bare TypeError
        load_yaml("? [1, 2]\n: x\n")


def test_json_objects():
    assert json.loads('{"a": {"b": 1}, "c": [{"d": 2}]}', object_pairs_hook=json_object_pairs) == {
        "a": {"b": 1},
        "c": [{"d": 2}],
    }
    with pytest.raises(DuplicateKeyError, match="key 'b' given twice in one object"):
        json.loads('{"a": {"b": 1, "b": 2}}', object_pairs_hook=json_object_pairs)


@pytest.mark.parametrize(
    "text, read_as",
    [("010", "8"), ("1:30", "90"), ("0x10", "16"), ("0b11", "3"), ("-012", "-10"), ("1:30.5", "90.5")],
)
def test_yaml_numbers_in_another_base_are_refused_not_misread(text, read_as):
    """An outside audit: `outer: [[0,0],[010,0],...]` put a corner at x = 8 without a word (YAML 1.1 octal), as
    `1:30` is 90 (base 60)."""
    from filters.unique_keys import YAMLNumberError

    with pytest.raises(YAMLNumberError, match=rf"line 2: '{re.escape(text)}' is read by YAML as {read_as}"):
        load_yaml(f"a: 1\nb: [0, {text}]\n")
    assert load_yaml("a: [0, 10, -0, 1_000, 0.5, '010', 010.5]") == {"a": [0, 10, 0, 1000, 0.5, "010", 10.5]}


def test_a_layout_file_with_an_octal_coordinate_is_a_layout_error(tmp_path):
    from semreloc_env.layouts import LayoutError, load_layout

    (tmp_path / "q.yaml").write_text("outer: [[0, 0], [010, 0], [010, 4], [0, 4]]\n")
    with pytest.raises(LayoutError, match=r"q.yaml: line 1: '010' is read by YAML as 8"):
        load_layout(tmp_path / "q.yaml")


def test_ros_map_files_read_numbers_as_ros_does(tmp_path):
    """A review: the layout files' refusal also refused a ROS map for a key the reader never uses (`saved: 12:30`);
    map files are read as ROS's YAML 1.2 reader reads them."""
    doc = load_yaml("a: 010\nsaved: 12:30\nc: 0x10\nd: 1:30.5\ne: 0.65\nf: 0\n", numbers="yaml1.2")
    assert doc == {"a": 10, "saved": "12:30", "c": 16, "d": "1:30.5", "e": 0.65, "f": 0}
    with pytest.raises(ValueError, match="numbers must be"):
        load_yaml("a: 1", numbers="yaml1.1")
