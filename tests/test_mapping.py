"""Mapping-run grid builders (paper 004 §2) and map metrics, on exact scans of a known grid."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from filters.mapping.grid import GridMap
from filters.mapping.metrics import (
    check_same_raster,
    class_iou,
    free_iou,
    iou,
    occupancy_iou,
    surface_mask,
    tolerant_precision_recall,
)
from filters.mapping.occupancy import (
    OccupancyMapper,
    OccupancyParams,
    SemanticMapper,
    SemanticParams,
    beam_cells,
    build_grid_map,
)
from filters.robot_data.scans import LaserScan, SemanticScan
from filters.simulators.grid_raycast import simulate_lidar, simulate_semantic

RES = 0.05
SHAPE = (70, 90)  # 3.5 m x 4.5 m
CLASSES = ("cabinet", "chair")
CABINET_A = (slice(18, 26), slice(18, 30))  # rows, cols: 0.4 m x 0.6 m
CABINET_B = (slice(18, 26), slice(58, 70))
CHAIR = (slice(44, 50), slice(60, 66))
LIDAR_ANGLES = np.linspace(-np.pi, np.pi, 180, endpoint=False)
CAMERA_ANGLES = np.linspace(-0.6, 0.6, 41)  # ~70 deg field of view
LIDAR_MAX, CAMERA_MAX = 6.0, 4.0

# ------------------------------------------------------------------------------------------------- truth + data


def _truth(cabinet=CABINET_A) -> GridMap:
    """A walled room (1-cell walls at rows 5/64, cols 5/84) with a cabinet and a chair; outside unknown."""
    occ = np.full(SHAPE, 0.5, np.float32)
    occ[5:65, 5:85] = 1.0
    occ[6:64, 6:84] = 0.0
    sem = np.zeros((2,) + SHAPE, np.float32)
    for k, box in enumerate((cabinet, CHAIR)):
        occ[box] = 1.0
        sem[k][box] = 1.0
    return GridMap(occ, RES, (0.0, 0.0), sem, CLASSES)


def _poses() -> np.ndarray:
    """A deterministic lattice of positions in free space, four headings each, clear of both cabinet sites."""
    xs = np.linspace(0.55, 3.95, 6)
    ys = np.linspace(0.5, 2.9, 6)
    out = []
    for i, x in enumerate(xs):
        for j, y in enumerate(ys):
            for q in range(4):
                out.append((x, y, -np.pi + (q + 0.5 * ((i + j) % 2)) * np.pi / 2))
    poses = np.array(out)
    keep = np.ones(len(poses), bool)
    for box in (CABINET_A, CABINET_B, CHAIR):
        r, c = np.floor(poses[:, 1] / RES).astype(int), np.floor(poses[:, 0] / RES).astype(int)
        near = (r >= box[0].start - 2) & (r < box[0].stop + 2) & (c >= box[1].start - 2) & (c < box[1].stop + 2)
        keep &= ~near
    return poses[keep]


def _scans(truth: GridMap, poses: np.ndarray):
    lidar = [simulate_lidar(truth, p, LIDAR_ANGLES, LIDAR_MAX) for p in poses]
    camera = [simulate_semantic(truth, p, CAMERA_ANGLES, CAMERA_MAX) for p in poses]
    return lidar, camera


def _seen(mask: np.ndarray, free: np.ndarray) -> np.ndarray:
    """Cells of ``mask`` that a beam from free space can hit: 4-adjacent to a free cell."""
    return mask & ndimage.binary_dilation(free, structure=ndimage.generate_binary_structure(2, 1))


def _run(truth: GridMap, poses: np.ndarray, occ=None, sem=None):
    lidar, camera = _scans(truth, poses)
    occ = occ or OccupancyMapper.like(truth)
    sem = sem or SemanticMapper.like(truth)
    occ.update_many(poses, lidar)
    sem.update_many(poses, camera)
    return occ, sem


# --------------------------------------------------------------------------------------------- ray traversal
def test_beam_cells_is_the_exact_supercover_of_the_segment():
    rng = np.random.default_rng(7)
    for _ in range(200):
        p0, p1 = rng.uniform(-1.0, 1.0, 2), rng.uniform(-1.0, 1.0, 2)
        rows, cols, t = beam_cells(p0, p1, 0.1, (-0.3, 0.2))
        # starts in the start cell, ends in the end cell, unit 4-connected steps, no repeats
        assert (rows[0], cols[0]) == (np.floor((p0[1] - 0.2) / 0.1), np.floor((p0[0] + 0.3) / 0.1))
        assert (rows[-1], cols[-1]) == (np.floor((p1[1] - 0.2) / 0.1), np.floor((p1[0] + 0.3) / 0.1))
        steps = np.abs(np.diff(rows)) + np.abs(np.diff(cols))
        assert np.all(steps == 1)
        assert len(set(zip(rows.tolist(), cols.tolist(), strict=True))) == rows.size
        assert np.all(np.diff(t) >= 0) and t[0] == 0 and t[-1] <= np.hypot(*(p1 - p0)) + 1e-9
        # every cell a dense sampling of the segment touches is listed
        s = np.linspace(0.0, 1.0, 20001)[:, None]
        pts = p0 + s * (p1 - p0)
        sampled = set(zip(np.floor((pts[:, 1] - 0.2) / 0.1).astype(int).tolist(),
                          np.floor((pts[:, 0] + 0.3) / 0.1).astype(int).tolist(), strict=True))  # fmt: skip
        listed = set(zip(rows.tolist(), cols.tolist(), strict=True))
        assert sampled <= listed
        assert len(listed) <= len(sampled) + 1  # at most a corner-touching extra


def test_range_ending_on_a_cell_face_marks_the_entered_cell():
    rows, cols, _ = beam_cells((0.05, 0.05), (0.6, 0.05), 0.1)
    np.testing.assert_array_equal(cols, np.arange(7))  # x = 0.6 is where cell 6 begins
    np.testing.assert_array_equal(rows, 0)


# ------------------------------------------------------------------------------------------ exact increments
def test_occupancy_single_beam_increments_and_max_range_clearing():
    p = OccupancyParams()
    m = OccupancyMapper((3, 12), 0.1, (0.0, 0.0))
    # beam along +x from the centre of cell (1, 0) ending on the face of cell 6; a second one gets no return
    m.update(np.array([0.05, 0.15, 0.0]), LaserScan([0.55], [0.0], 2.0))
    np.testing.assert_allclose(m.logodds[1, :6], p.l_free)
    assert m.logodds[1, 6] == pytest.approx(p.l_occ)
    assert np.all(m.logodds[1, 7:] == 0) and np.all(m.logodds[[0, 2]] == 0)
    m2 = OccupancyMapper((3, 12), 0.1, (0.0, 0.0))
    m2.update(np.array([0.05, 0.15, 0.0]), LaserScan([5.0], [0.0], 0.72))  # no return: clear to x = 0.77
    np.testing.assert_allclose(m2.logodds[1, :8], p.l_free)
    assert np.all(m2.logodds[1, 8:] == 0) and m2.logodds.max() <= 0
    # clamping
    for _ in range(20):
        m.update(np.array([0.05, 0.15, 0.0]), LaserScan([0.55], [0.0], 2.0))
    assert m.logodds[1, 6] == pytest.approx(p.l_max) and m.logodds[1, 0] == pytest.approx(p.l_min)
    assert m.to_grid().occupied_mask()[1, 6] and m.to_grid().free_mask()[1, 0]


def test_occupancy_max_range_param_cuts_long_returns():
    m = OccupancyMapper((1, 40), 0.1, params=OccupancyParams(max_range_m=1.0))
    m.update(np.array([0.05, 0.05, 0.0]), LaserScan([2.5], [0.0], 10.0))
    assert m.logodds.max() <= 0  # the 2.5 m return is beyond 1.0 m: nothing is marked
    assert np.all(m.logodds[0, :10] < 0) and np.all(m.logodds[0, 11:] == 0)


def test_semantic_increments_dark_grey_lowers_more_than_light_grey():
    p = SemanticParams()
    m = SemanticMapper((4, 12), 0.1, (0.0, 0.0), CLASSES)
    pose = np.array([0.05, 0.15, 0.0])
    # one labelled beam (chair = label 2) along row 1, one unlabelled beam along row 2 (angle to reach it)
    m.update(pose, SemanticScan([0.55], [0.0], [2], 3.0))
    L = m.logodds
    np.testing.assert_allclose(L[:, 1, :6], p.l_free_inside)  # light grey, all classes
    assert L[1, 1, 6] == pytest.approx(p.l_hit) and L[0, 1, 6] == pytest.approx(p.l_other_hit)
    m2 = SemanticMapper((4, 12), 0.1, (0.0, 0.0), CLASSES)
    m2.update(pose, SemanticScan([0.55], [0.0], [0], 3.0))
    np.testing.assert_allclose(m2.logodds[:, 1, :6], p.l_free_outside)  # dark grey
    np.testing.assert_allclose(m2.logodds[:, 1, 6], p.l_unlabelled_end)
    assert p.l_free_outside < p.l_free_inside < 0
    assert np.all(m2.logodds[:, 1, :6] < m.logodds[:, 1, :6])
    # a hit of another class lowers this one
    for _ in range(3):
        m.update(pose, SemanticScan([0.55], [0.0], [2], 3.0))
    before = m.logodds[1, 1, 6]
    m.update(pose, SemanticScan([0.55], [0.0], [1], 3.0))
    assert m.logodds[1, 1, 6] == pytest.approx(before + p.l_other_hit)
    assert m.to_grid().class_mask(1)[1, 6] and not m.to_grid().class_mask(0)[1, 6]


def test_semantic_no_return_beams_clear_and_mark_nothing():
    m = SemanticMapper((1, 30), 0.1, (0.0, 0.0), CLASSES)
    m.update(np.array([0.05, 0.05, 0.0]), SemanticScan([9.0, 9.0], [0.0, 0.0], [0, 1], 1.02))
    assert m.logodds.max() <= 0
    np.testing.assert_allclose(m.logodds[:, 0, :11], SemanticParams().l_free_outside + SemanticParams().l_free_inside)
    assert np.all(m.logodds[:, 0, 11:] == 0)


def test_semantic_no_return_beams_update_nothing_without_clear_no_return():
    """``clear_no_return=False`` (the mapping run since version 3): a camera that reads a too-close object as
    no return must not clear that object; returned beams in the same scans update as before."""
    pose = np.array([0.05, 0.05, 0.0])
    scan = SemanticScan([9.0, 0.55, 9.0], [0.0, 0.0, 0.0], [0, 2, 1], 1.02)
    keep = SemanticMapper((1, 30), 0.1, (0.0, 0.0), CLASSES, SemanticParams(clear_no_return=False))
    keep.update(pose, scan)
    returned = SemanticMapper((1, 30), 0.1, (0.0, 0.0), CLASSES)
    returned.update(pose, SemanticScan([0.55], [0.0], [2], 1.02))
    np.testing.assert_array_equal(keep.logodds, returned.logodds)
    keep.update_arrays(pose[None], np.array([[9.0, 9.0]]), np.array([[0, 1]]), np.zeros(2), 1.02)
    np.testing.assert_array_equal(keep.logodds, returned.logodds)  # the array path drops them too


def test_semantic_beams_below_a_minimum_range_leave_their_labels_out_too():
    """A semantic scan type with a minimum range (``range_min_m``, as `LaserScan` has): beams below it update
    nothing, and the labels of the others stay with their beams (they were dropped from the beams only)."""
    import dataclasses

    @dataclasses.dataclass(frozen=True)
    class NearBlindScan(SemanticScan):
        range_min_m: float = 0.3

    pose = np.array([0.05, 0.05, 0.0])
    blind = SemanticMapper((1, 30), 0.1, (0.0, 0.0), CLASSES)
    blind.update(pose, NearBlindScan([0.1, 0.55], [0.0, 0.0], [1, 2], 3.0))  # the first beam is too short
    want = SemanticMapper((1, 30), 0.1, (0.0, 0.0), CLASSES)
    want.update(pose, SemanticScan([0.55], [0.0], [2], 3.0))
    np.testing.assert_array_equal(blind.logodds, want.logodds)


def test_bad_parameters_and_inputs_raise():
    with pytest.raises(ValueError, match="l_free_outside < l_free_inside"):
        SemanticParams(l_free_inside=-0.6, l_free_outside=-0.2)
    with pytest.raises(ValueError, match="l_occ"):
        OccupancyParams(l_occ=-1.0)
    with pytest.raises(ValueError, match="l_min < 0 < l_max"):
        OccupancyParams(l_min=1.0)
    m = SemanticMapper((4, 4), 0.1, class_names=CLASSES)
    with pytest.raises(ValueError, match="label 3"):
        m.update(np.zeros(3), SemanticScan([0.1], [0.0], [3], 1.0))
    with pytest.raises(TypeError):
        m.update(np.zeros(3), LaserScan([0.1], [0.0], 1.0))
    with pytest.raises(ValueError, match="poses"):
        OccupancyMapper((4, 4), 0.1).update_many(np.zeros((2, 3)), [LaserScan([0.1], [0.0], 1.0)])
    with pytest.raises(ValueError, match="differs from the semantic raster"):
        m.to_grid(OccupancyMapper((4, 5), 0.1))
    occ = np.zeros((3, 3))
    for kw, match in [
        ({"semantic_thresh": float("nan")}, "semantic_thresh"),
        ({"semantic_thresh": 5.0}, "semantic_thresh"),
        ({"origin_xy_m": 5}, "origin_xy_m"),
        ({"class_names": "cab"}, "class_names"),
        ({"free_thresh": "0.2"}, "free_thresh"),
        ({"resolution_m": "0.1"}, "resolution_m"),
    ]:
        with pytest.raises(ValueError, match=match):
            GridMap(**{"occupancy": occ, "resolution_m": 0.1, **kw})


# ------------------------------------------------------------------------------------------- room end to end
def test_square_room_walls_free_space_and_objects_are_recovered():
    truth = _truth()
    poses = _poses()
    assert 60 <= len(poses) <= 144
    occ, sem = _run(truth, poses)
    grid = occ.to_grid(sem)
    check_same_raster(grid, truth)
    free_truth = truth.free_mask()
    seen_occupied = _seen(truth.occupied_mask(), free_truth)
    # walls and object faces seen from the room: recovered with IoU > 0.9 (corner cells cannot be hit)
    assert iou(grid.occupied_mask(), seen_occupied) > 0.9
    # nothing outside the room is marked, and the free interior is free
    assert not np.any(grid.occupied_mask() & (truth.occupancy == 0.5))
    assert np.count_nonzero(grid.occupied_mask() & free_truth) <= 0.002 * free_truth.sum()
    assert np.mean(grid.free_mask()[free_truth]) > 0.97
    assert free_iou(grid, truth) > 0.95
    # semantic: the faces of the cabinet and of the chair, IoU > 0.8 each, nothing elsewhere
    seen_truth = GridMap(
        truth.occupancy, RES, (0.0, 0.0), np.stack([_seen(truth.class_mask(k), free_truth) for k in range(2)]), CLASSES
    )
    scores = class_iou(grid, seen_truth)
    assert set(scores) == set(CLASSES)
    assert scores["cabinet"] > 0.8 and scores["chair"] > 0.8, scores
    for k in range(2):
        assert not np.any(grid.class_mask(k) & ~ndimage.binary_dilation(truth.class_mask(k), iterations=1))
    # a poorer map scores lower: the metric can fail
    assert occupancy_iou(OccupancyMapper.like(truth).to_grid(), truth) == 0.0


def test_noisy_ranges_give_surfaces_within_one_cell():
    """2 cm range noise (0.4 cell) on surfaces that lie exactly on cell faces: about half the returns
    land in the cell in front, so compare within one cell (8-neighbourhood) instead of exactly."""
    rng = np.random.default_rng(1)
    truth = _truth()
    poses = _poses()
    lidar = [simulate_lidar(truth, p, LIDAR_ANGLES, LIDAR_MAX, 0.02, rng) for p in poses]
    camera = [simulate_semantic(truth, p, CAMERA_ANGLES, CAMERA_MAX, 0.02, rng) for p in poses]
    grid = build_grid_map(SHAPE, RES, (0.0, 0.0), poses, lidar, semantic_scans=camera, class_names=CLASSES)

    def near(m):
        return ndimage.binary_dilation(m, structure=ndimage.generate_binary_structure(2, 2))

    free_truth = truth.free_mask()
    seen = _seen(truth.occupied_mask(), free_truth)
    mapped = grid.occupied_mask()
    assert np.mean(near(seen)[mapped]) > 0.98  # precision within one cell
    assert np.mean(near(mapped)[seen]) > 0.98  # recall within one cell
    assert np.mean(grid.free_mask()[free_truth & ~near(seen)]) > 0.98
    assert iou(mapped, seen) < 0.95  # the noise does show: the exact IoU is not perfect here
    for k in range(2):
        seen_k, mapped_k = _seen(truth.class_mask(k), free_truth), grid.class_mask(k)
        assert np.mean(near(seen_k)[mapped_k]) > 0.95 and np.mean(near(mapped_k)[seen_k]) > 0.95


def test_moved_object_is_erased_where_beams_now_pass_and_mapped_where_it_went():
    before, after = _truth(CABINET_A), _truth(CABINET_B)
    poses = _poses()
    occ, sem = _run(before, poses)
    was = before.class_mask(0)
    assert np.count_nonzero(sem.to_grid().class_mask(0) & was) >= 20  # the cabinet at A is on the map
    occ, sem = _run(after, poses, occ, sem)  # the cabinet moved from A to B; map again from the same poses
    grid = occ.to_grid(sem)
    assert np.count_nonzero(grid.class_mask(0) & was) == 0  # erased by the beams that now pass through A
    assert np.count_nonzero(grid.occupied_mask() & was) <= 2
    seen_b = _seen(after.class_mask(0), after.free_mask())
    assert iou(grid.class_mask(0), seen_b) > 0.8
    assert iou(grid.class_mask(1), _seen(after.class_mask(1), after.free_mask())) > 0.8  # the chair stays


def test_mapping_is_deterministic_and_batch_equals_one_by_one():
    truth = _truth()
    poses = _poses()[:30]
    lidar, camera = _scans(truth, poses)
    g1 = build_grid_map(SHAPE, RES, (0.0, 0.0), poses, lidar, semantic_scans=camera, class_names=CLASSES)
    g2 = build_grid_map(SHAPE, RES, (0.0, 0.0), poses, lidar, semantic_scans=camera, class_names=CLASSES)
    np.testing.assert_array_equal(g1.occupancy, g2.occupancy)
    np.testing.assert_array_equal(g1.semantic, g2.semantic)
    occ, sem = OccupancyMapper.like(truth), SemanticMapper.like(truth)
    for p, ls, cs in zip(poses, lidar, camera, strict=True):
        occ.update(p, ls)
        sem.update(p, cs)
    np.testing.assert_array_equal(occ.to_grid(sem).occupancy, g1.occupancy)
    np.testing.assert_array_equal(sem.to_grid().semantic, g1.semantic)
    assert g1.class_names == CLASSES and np.any(g1.class_mask(0))


def test_lab_sized_run_keeps_the_grid_shape_and_frees_space():
    """15 m x 10 m at 0.05 m, 1000 poses x 60 beams (~10 m returns); its time is in scripts/bench.py
    (``mapping_lab_run``), not asserted here (a busy machine would make a timed test flaky)."""
    rng = np.random.default_rng(0)
    n, b = 1000, 60
    poses = np.column_stack([rng.uniform(0.5, 14.5, n), rng.uniform(0.5, 9.5, n), rng.uniform(-np.pi, np.pi, n)])
    angles = np.linspace(-np.pi, np.pi, b, endpoint=False)
    lidar = [LaserScan(rng.uniform(0.2, 12.0, b), angles, 10.0) for _ in range(n)]
    camera = [SemanticScan(rng.uniform(0.2, 5.0, b), angles, rng.integers(0, 5, b), 4.0) for _ in range(n)]
    occ, sem = OccupancyMapper((200, 300), 0.05), SemanticMapper((200, 300), 0.05)
    for p, s in zip(poses, lidar, strict=True):
        occ.update(p, s)
    sem.update_many(poses, camera)
    grid = occ.to_grid(sem)
    assert grid.shape == (200, 300) and np.any(grid.free_mask())


# ------------------------------------------------------------------------------------------------- metrics
def test_iou_values_and_raster_checks():
    a = np.zeros((4, 4), bool)
    b = np.zeros((4, 4), bool)
    assert iou(a, b) == 1.0  # both empty
    a[0, :2] = True
    b[0, 1:3] = True
    assert iou(a, b) == pytest.approx(1 / 3)
    where = np.zeros((4, 4), bool)
    where[0, :2] = True
    assert iou(a, b, where) == pytest.approx(1 / 2)
    with pytest.raises(ValueError, match="shapes differ"):
        iou(a, b[:3])
    with pytest.raises(ValueError, match="boolean"):
        iou(a.astype(int), b)
    g = _truth()
    shifted = GridMap(g.occupancy, RES, (0.05, 0.0), g.semantic, CLASSES)
    with pytest.raises(ValueError, match="different rasters"):
        class_iou(g, shifted)
    assert class_iou(g, g) == {"cabinet": 1.0, "chair": 1.0}
    with pytest.raises(KeyError):
        class_iou(g, g, classes=("door",))


def test_surface_mask_and_tolerant_precision_recall():
    g = _truth()
    seen = surface_mask(g.class_mask(0), g.free_mask())
    assert seen.sum() == 2 * (8 + 12) - 4  # the ring of the 8 x 12 cabinet
    assert not seen[20, 20] and seen[18, 20]
    shifted = np.roll(seen, 1, axis=1)
    p0, r0 = tolerant_precision_recall(shifted, seen, 0)
    assert p0 < 0.9 and r0 < 0.9
    assert tolerant_precision_recall(shifted, seen, 1) == (1.0, 1.0)
    p, r = tolerant_precision_recall(seen, np.zeros_like(seen), 1)
    assert p == 0.0 and r == 1.0
    with pytest.raises(ValueError):
        tolerant_precision_recall(seen, seen[:-1])


def test_drop_unsupported_class_cells_keeps_objects_and_drops_stray_cells():
    """A class cell stays if a cell of its class within the radius is confidently marked (itself included);
    a weakly marked cell with no such neighbour is set to the threshold (no longer that class)."""
    from filters.mapping.occupancy import drop_unsupported_class_cells

    sem = np.full((2, 20, 20), 0.2, np.float32)
    sem[0, 5:8, 5:8] = 0.97  # an object, confidently mapped ...
    sem[0, 4, 5:8] = 0.6  # ... with a weakly mapped rim one cell off
    sem[0, 15, 15] = 0.7  # a stray cell of class 0, far from any confident one
    sem[0, 5, 11] = 0.75  # weak, three cells from the object: farther than 0.1 m
    sem[1, 6, 6] = 0.7  # a stray cell of class 1 on the class-0 object
    sem[1, 10, 10] = 0.95  # a lone but confident cell: kept
    grid = GridMap(np.zeros((20, 20), np.float32), 0.05, semantic=sem, class_names=("a", "b"))
    out = drop_unsupported_class_cells(grid, 0.9, 0.1)
    kept0 = out.class_mask(0)
    assert kept0[5:8, 5:8].all() and kept0[4, 5:8].all()
    assert not kept0[15, 15] and not kept0[5, 11]
    assert not out.class_mask(1)[6, 6] and out.class_mask(1)[10, 10]
    assert out.semantic[0, 15, 15] == grid.semantic_thresh
    np.testing.assert_array_equal(out.occupancy, grid.occupancy)
    changed = out.semantic != grid.semantic
    assert changed.sum() == 3  # nothing else touched
    assert np.array_equal(grid.semantic, sem)  # the input map is unchanged
    # radius 0: only confident cells stay
    assert drop_unsupported_class_cells(grid, 0.9, 0.0).class_mask(0).sum() == 9
    for bad in ({"support_p": 0.5}, {"support_p": 1.5}, {"support_p": float("nan")}, {"radius_m": -0.1}):
        with pytest.raises(ValueError):
            drop_unsupported_class_cells(grid, **{"support_p": 0.9, "radius_m": 0.1, **bad})
    empty = GridMap(np.zeros((4, 4), np.float32), 0.05)
    assert drop_unsupported_class_cells(empty) is empty


def _corridor_mapper() -> OccupancyMapper:
    """A 0.1 m raster 10 m long whose wall at x = 3 m the returns marked, with the space before it seen once."""
    m = OccupancyMapper((5, 100), 0.1, params=OccupancyParams(clear_no_return=False))
    m.update(np.array([0.05, 0.25, 0.0]), LaserScan([2.9], [0.0], 8.0))  # return at x = 2.95 m, in the cell 2.9..3.0
    return m


def test_clear_unobserved_stops_at_a_marked_surface_and_clears_only_what_returns_left_unfree():
    m = _corridor_mapper()
    before = m.logodds.copy()
    dropout = LaserScan([8.0], [0.0], 8.0)  # no return although the wall is at 3 m
    m.clear_unobserved(np.array([[0.05, 0.25, 0.0]]), [dropout])
    after = m.logodds
    lo = OccupancyParams().l_free_unobserved
    # up to the cell before the wall's neighbour: at most l_free_unobserved; the wall and everything behind it untouched
    np.testing.assert_array_equal(after[2, :28], np.minimum(before[2, :28], lo))
    np.testing.assert_array_equal(after[2, 28:], before[2, 28:])
    assert after[2, 29] > 0 and (after[2, 31:] == 0).all()
    np.testing.assert_array_equal(np.delete(after, 2, axis=0), np.delete(before, 2, axis=0))  # other rows: not crossed

    # a beam with a return clears nothing in this pass; an open side (no surface) is cleared out to the range
    m.clear_unobserved(np.array([[0.05, 0.25, 0.0]]), [LaserScan([1.0], [0.0], 8.0)])
    np.testing.assert_array_equal(m.logodds, after)
    m2 = _corridor_mapper()
    m2.clear_unobserved(np.array([[2.55, 0.25, 0.0]]), [LaserScan([8.0], [np.pi / 2], 0.2)])  # up the 0.5 m strip
    assert (m2.logodds[2:, 25] == lo).all() and (m2.logodds[:2, 25] == 0).all()  # rows 2-4 (y 0.2-0.5 m), not below


def test_clear_unobserved_stops_at_a_surface_whose_cell_ended_free_leaning():
    # a reviewer's case: an object's face cell is crossed by more beams than end in it, so its log-odds is below
    # 0 and the cells behind it (inside the object) are unknown; a dropout must still stop at the face
    m = _corridor_mapper()
    for _ in range(3):  # beams through the wall's cell (x 2.9-3.0 m) to a return farther on
        m.update(np.array([0.05, 0.25, 0.0]), LaserScan([4.0], [0.0], 8.0))
    assert m.logodds[2, 29] < 0 and (m.logodds[2, 41:] == 0).all()
    before = m.logodds.copy()
    m.clear_unobserved(np.array([[0.05, 0.25, 0.0]]), [LaserScan([8.0], [0.0], 8.0)])
    np.testing.assert_array_equal(m.logodds[2, 28:], before[2, 28:])  # stopped next to the cell a return ended in
    assert (m.logodds[2, :28] == OccupancyParams().l_free_unobserved).all()


def test_clear_unobserved_enters_the_raster_from_outside_and_survives_pickling():
    import pickle

    m = _corridor_mapper()
    m.clear_unobserved(np.array([[-1.0, 0.15, 0.0]]), [LaserScan([8.0], [0.0], 8.0)])  # starts 1 m left of the raster
    assert (m.logodds[1, :28] == OccupancyParams().l_free_unobserved).all() and m.logodds[1, 28:].max() <= 0
    fresh, copied = _corridor_mapper(), pickle.loads(pickle.dumps(_corridor_mapper()))
    state = fresh.__getstate__()
    assert state["_blocked"] is None
    old = pickle.loads(pickle.dumps(fresh))
    del old.__dict__["_ended"]  # as pickled before returns were recorded
    old.__setstate__(old.__dict__.copy())
    beams = (np.array([[0.05, 0.25, 0.0]]), [LaserScan([8.0], [0.0], 8.0)])
    for other in (copied, old):
        fresh_copy = pickle.loads(pickle.dumps(fresh))
        fresh_copy.clear_unobserved(*beams)
        other.clear_unobserved(*beams)
        np.testing.assert_array_equal(other.logodds, fresh_copy.logodds)


def test_clear_unobserved_in_chunks_matches_one_call_and_the_array_form_and_stops_at_new_returns():
    rng = np.random.default_rng(3)
    poses = np.column_stack([rng.uniform(0.5, 2.5, 40), rng.uniform(0.1, 0.4, 40), rng.uniform(-np.pi, np.pi, 40)])
    angles = np.linspace(-np.pi, np.pi, 24, endpoint=False)
    ranges = np.where(rng.random((40, 24)) < 0.5, 8.0, rng.uniform(0.2, 3.0, (40, 24)))
    one, chunked, arrays = _corridor_mapper(), _corridor_mapper(), _corridor_mapper()
    one.clear_unobserved(poses, [LaserScan(r, angles, 8.0) for r in ranges])
    for lo in range(0, 40, 7):  # in chunks: the same (the pass adds no returns)
        chunked.clear_unobserved(poses[lo : lo + 7], [LaserScan(r, angles, 8.0) for r in ranges[lo : lo + 7]])
    arrays.clear_unobserved_arrays(poses, ranges, angles, 8.0)
    np.testing.assert_array_equal(chunked.logodds, one.logodds)
    np.testing.assert_array_equal(arrays.logodds, one.logodds)
    assert not np.array_equal(one.logodds, _corridor_mapper().logodds)
    # an update in between starts a new pass: its surface now stops the beams
    beam = (np.array([[0.05, 0.25, 0.0]]), [LaserScan([8.0], [0.0], 8.0)])
    m = _corridor_mapper()
    m.clear_unobserved(*beam)
    for _ in range(3):  # a surface at x = 1.05 m (cell 10), seen often enough to outweigh the first pass
        m.update(np.array([0.05, 0.25, 0.0]), LaserScan([1.0], [0.0], 8.0))
    before = m.logodds.copy()
    assert before[2, 10] > 0
    m.clear_unobserved(*beam)
    np.testing.assert_array_equal(m.logodds[2, 9:], before[2, 9:])  # stopped next to the new surface
    assert before[2, 15] == OccupancyParams().l_free_unobserved  # which the first pass had crossed


def test_clear_unobserved_rejects_bad_input():
    m = _corridor_mapper()
    with pytest.raises(TypeError, match="LaserScan"):
        m.clear_unobserved(np.zeros((1, 3)), [SemanticScan([1.0], [0.0], [1], 4.0)])
    with pytest.raises(ValueError, match="poses"):
        m.clear_unobserved_arrays(np.full((1, 3), np.nan), np.array([[8.0]]), np.array([0.0]), 8.0)
    with pytest.raises(ValueError, match="l_free_unobserved"):
        OccupancyParams(l_free_unobserved=0.0)
    with pytest.raises(ValueError, match="l_free_unobserved"):
        OccupancyParams(l_free_unobserved=-50.0)  # below l_min: the clamp would not hold
    before = m.logodds.copy()
    with pytest.raises(ValueError):
        m.clear_unobserved_arrays(np.zeros((1, 3)), np.array([[np.inf]]), np.array([0.0]), 8.0)
    np.testing.assert_array_equal(m.logodds, before)  # nothing lost
