"""Built-in layouts: ``lab``, ``twin_rooms``, ``three_rooms`` and ``open_hall``, as plain dicts.

Each builder returns the dict form (see `.layout`) so users can copy, edit
and save it; `semreloc_env.layouts.get_layout` validates it into a Layout.
"""

from __future__ import annotations


def _box(cls: str, cx: float, cy: float, w: float, h: float, name: str = "") -> dict:
    return {"class": cls, "center": [cx, cy], "size": [w, h], "name": name}


def lab() -> dict:
    """An indoor lab in the spirit of paper 004: 15 m x 10 m, five rooms on a corridor.

    A 2 m corridor runs east-west at ``y in [4, 6]``. Below it three identical
    5 m x 4 m rooms, above it two 7.5 m x 4 m rooms: the look-alike rooms make
    lidar-only relocalization ambiguous, the furniture (3 doors, 4 chairs,
    3 trash bins, 4 cabinets) tells them apart.
    """
    walls = [
        # corridor south wall with three doorways (x in [2,3], [7,8], [12,13])
        [[0, 4], [2, 4]],
        [[3, 4], [7, 4]],
        [[8, 4], [12, 4]],
        [[13, 4], [15, 4]],
        # corridor north wall with two doorways (x in [3,4], [11,12])
        [[0, 6], [3, 6]],
        [[4, 6], [11, 6]],
        [[12, 6], [15, 6]],
        # room dividers
        [[5, 0], [5, 4]],
        [[10, 0], [10, 4]],
        [[7.5, 6], [7.5, 10]],
    ]
    objects = [
        # doors: thin panels on the outer wall
        _box("door", 0.05, 5.0, 0.1, 1.0, "entrance_door"),
        _box("door", 15.0 - 0.05, 5.0, 0.1, 1.0, "fire_door"),
        _box("door", 11.0, 10.0 - 0.05, 1.0, 0.1, "store_door"),
        # south-west room
        _box("cabinet", 0.3, 2.0, 0.6, 1.2, "cabinet_sw"),
        _box("chair", 3.5, 1.2, 0.5, 0.5, "chair_sw"),
        # south-middle room
        _box("trash_bin", 9.6, 0.4, 0.4, 0.4, "bin_sm"),
        _box("chair", 6.2, 2.6, 0.5, 0.5, "chair_sm"),
        # south-east room
        _box("cabinet", 12.5, 0.3, 1.2, 0.6, "cabinet_se"),
        _box("trash_bin", 14.6, 3.5, 0.4, 0.4, "bin_se"),
        # north-west room
        _box("cabinet", 0.3, 8.0, 0.6, 1.4, "cabinet_nw"),
        _box("chair", 2.0, 8.5, 0.5, 0.5, "chair_nw"),
        _box("chair", 5.5, 7.0, 0.5, 0.5, "chair_nw2"),
        # north-east room
        _box("cabinet", 14.7, 8.0, 0.6, 1.2, "cabinet_ne"),
        _box("trash_bin", 8.0, 9.6, 0.4, 0.4, "bin_ne"),
    ]
    return {"name": "lab", "outer": [[0, 0], [15, 0], [15, 10], [0, 10]], "walls": walls, "objects": objects}


def twin_rooms() -> dict:
    """Two rooms with identical walls and identically shaped furniture of different classes.

    The layout (12 m x 6 m, a wall at ``x = 6`` with a doorway at ``y in [2.5, 3.5]``)
    is symmetric under a half turn about ``(6, 3)``: every lidar scan in the west
    room is repeated exactly at the mirrored pose in the east room. The objects
    sit at symmetric places with the same footprints, so they do not break the
    lidar symmetry either — only their classes differ. This is the case paper 004
    is about: lidar alone cannot tell the rooms apart, semantics can.
    """
    # (class in the west room, class of its twin in the east room, box in the west room)
    pairs = [
        ("cabinet", "door", (0.3, 4.5, 0.6, 1.2)),
        ("chair", "trash_bin", (2.0, 1.5, 0.5, 0.5)),
        ("trash_bin", "chair", (4.5, 5.0, 0.4, 0.4)),
        ("door", "cabinet", (3.0, 0.05, 1.0, 0.1)),
    ]
    objects = []
    for west_cls, east_cls, (cx, cy, w, h) in pairs:
        objects.append(_box(west_cls, cx, cy, w, h, f"{west_cls}_west"))
        objects.append(_box(east_cls, 12.0 - cx, 6.0 - cy, w, h, f"{east_cls}_east"))
    walls = [[[6, 0], [6, 2.5]], [[6, 3.5], [6, 6]]]
    return {"name": "twin_rooms", "outer": [[0, 0], [12, 0], [12, 6], [0, 6]], "walls": walls, "objects": objects}


def three_rooms() -> dict:
    """Three identical rooms off one corridor; only the classes of their furniture differ.

    18 m x 8 m. Rooms ``x in [6i, 6i + 6], y in [0, 5]`` (i = 0, 1, 2), each with a doorway
    at ``x in [6i + 2.5, 6i + 3.5]`` onto a 3 m corridor (``y in [5, 8]``). The furniture
    footprints are the same in every room (a 0.6 m x 1.2 m box on the west wall, a
    0.5 m box in the south-east corner, a 0.4 m box by the door); their classes are
    permuted from room to room, so inside a room lidar cannot tell which room it is,
    and the camera can only once it has looked at the furniture.
    """
    footprint = [(0.4, 2.5, 0.6, 1.2), (5.4, 0.5, 0.5, 0.5), (4.6, 4.5, 0.4, 0.4)]
    classes = [("cabinet", "chair", "trash_bin"), ("chair", "trash_bin", "cabinet"), ("trash_bin", "cabinet", "chair")]
    objects = []
    for i, room in enumerate(classes):
        for cls, (cx, cy, w, h) in zip(room, footprint):
            objects.append(_box(cls, 6.0 * i + cx, cy, w, h, f"{cls}_room{i}"))
    walls = [[[0, 5], [2.5, 5]], [[3.5, 5], [8.5, 5]], [[9.5, 5], [14.5, 5]], [[15.5, 5], [18, 5]]]
    walls += [[[6, 0], [6, 5]], [[12, 0], [12, 5]]]
    return {"name": "three_rooms", "outer": [[0, 0], [18, 0], [18, 8], [0, 8]], "walls": walls, "objects": objects}


def open_hall() -> dict:
    """A sparse open hall, 20 m x 15 m: few objects and two short partitions.

    From most of the floor the 8 m lidar sees one or two walls only, and few objects are in
    the camera's 4.5 m: the case where a filter with too few particles starves.
    """
    objects = [
        _box("door", 0.05, 7.5, 0.1, 1.0, "door_west"),
        _box("cabinet", 19.7, 3.0, 0.6, 1.2, "cabinet_east"),
        _box("cabinet", 6.0, 14.7, 1.2, 0.6, "cabinet_north"),
        _box("trash_bin", 10.0, 7.5, 0.4, 0.4, "bin_centre"),
        _box("chair", 15.0, 11.0, 0.5, 0.5, "chair_ne"),
        _box("chair", 4.0, 3.0, 0.5, 0.5, "chair_sw"),
    ]
    walls = [[[7, 5], [9, 5]], [[13, 10], [13, 12]]]
    return {"name": "open_hall", "outer": [[0, 0], [20, 0], [20, 15], [0, 15]], "walls": walls, "objects": objects}


BUILTIN_LAYOUTS = {"lab": lab, "twin_rooms": twin_rooms, "three_rooms": three_rooms, "open_hall": open_hall}
