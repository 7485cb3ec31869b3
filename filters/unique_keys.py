"""Reading JSON and YAML files that refuse a key given twice in one mapping.

Both parsers keep the last of two equal keys without a word, so a file that says ``resolution``
twice would load with whichever came last. Layout files (`semreloc_env.layouts.layout`) and map
sidecars (`filters.mapping.ros_map`) read through these functions instead and report the key (and,
in YAML, its lines).
"""

from __future__ import annotations


class FileTextError(ValueError):
    """A JSON or YAML text these readers refuse: a key given twice, or a YAML number read otherwise than written."""


class DuplicateKeyError(FileTextError):
    """A key given twice in one mapping of a JSON or YAML text."""


class YAMLNumberError(FileTextError):
    """A YAML 1.1 integer in octal (``010``), sexagesimal (``1:30``), hexadecimal or binary form: PyYAML reads ``010``
    as 8 and ``1:30`` as 90, without a word."""


def json_object_pairs(pairs: list) -> dict:
    """``object_pairs_hook`` for `json.loads` that raises `DuplicateKeyError` for a key given twice in one
    object (naming the object by its ``name`` entry, if it has one)."""
    keys = [k for k, _ in pairs]
    twice = sorted({k for k in keys if keys.count(k) > 1})
    if twice:
        name = dict(pairs).get("name")
        where = f" (the one named {name!r:.40})" if isinstance(name, str) else ""
        raise DuplicateKeyError(f"key {twice[0]!r} given twice in one object{where}; a parser would keep the last")
    return dict(pairs)


def load_yaml(text: str, numbers: str = "refuse"):
    """``yaml.safe_load(text)``, but a key given twice in one mapping raises `DuplicateKeyError` naming
    both lines, and an integer YAML 1.1 reads in another base (``010`` is 8, ``1:30`` is 90, ``0x10`` is 16)
    raises `YAMLNumberError` naming its line (``numbers="refuse"``, the layout files'); with ``numbers="yaml1.2"``
    such scalars are read as a YAML 1.2 reader reads them (ROS's yaml-cpp, for map files): ``010`` as 10, ``1:30``
    as the string it is, ``0x10`` as 16. Merge keys (``<<: *anchor``) may still be overridden, as YAML
    intends. Other errors are ``yaml.YAMLError`` (an unhashable key, a list used as a key, is the loader's own
    error)."""
    import yaml

    if numbers not in ("refuse", "yaml1.2"):
        raise ValueError(f"numbers must be 'refuse' or 'yaml1.2', got {numbers!r}")
    merge_tag = "tag:yaml.org,2002:merge"

    class Loader(yaml.SafeLoader):
        def flatten_mapping(self, node):
            # every mapping passes here before PyYAML merges other mappings' keys into it (which it may do
            # to a node before constructing it, when a later mapping merges it): check its own keys once, first
            checked = self.__dict__.setdefault("_unique_keys_checked", set())
            if id(node) not in checked:
                checked.add(id(node))
                seen = {}
                for key_node, _ in node.value:
                    if key_node.tag == merge_tag:
                        continue
                    key = self.construct_object(key_node, deep=False)
                    try:
                        first = seen.get(key)
                    except TypeError:  # unhashable: construct_mapping raises the loader's own error
                        continue
                    if first is not None:
                        raise DuplicateKeyError(
                            f"line {key_node.start_mark.line + 1}: key {key!r} given twice in one mapping "
                            f"(first on line {first + 1})"
                        )
                    seen[key] = key_node.start_mark.line
            super().flatten_mapping(node)

        def construct_yaml_int(self, node):
            text = str(self.construct_scalar(node))
            body = text.replace("_", "").lstrip("+-").lower()
            if numbers == "yaml1.2":
                if ":" in body:
                    return text
                if len(body) > 1 and body.startswith("0") and body.isdigit():
                    return int(text.replace("_", ""), 10)
                return super().construct_yaml_int(node)
            if ":" in body or body.startswith(("0x", "0b", "0o")) or (len(body) > 1 and body.startswith("0")):
                value = super().construct_yaml_int(node)
                raise YAMLNumberError(
                    f"line {node.start_mark.line + 1}: {text!r} is read by YAML as {value} (an octal, base-60, "
                    "hexadecimal or binary number): write the number in decimal without leading zeros, or quote it"
                )
            return super().construct_yaml_int(node)

        def construct_yaml_float(self, node):
            text = str(self.construct_scalar(node))
            if ":" in text and numbers == "yaml1.2":
                return text
            if ":" in text:  # 1:30.5 is 90.5 to YAML 1.1
                value = super().construct_yaml_float(node)
                raise YAMLNumberError(
                    f"line {node.start_mark.line + 1}: {text!r} is read by YAML as {value} (a base-60 number): "
                    "write the number in decimal, or quote it"
                )
            return super().construct_yaml_float(node)

    Loader.add_constructor("tag:yaml.org,2002:int", Loader.construct_yaml_int)
    Loader.add_constructor("tag:yaml.org,2002:float", Loader.construct_yaml_float)
    return yaml.load(text, Loader=Loader)  # noqa: S506 - a SafeLoader subclass
