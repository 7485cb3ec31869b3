import math

import numpy as np
import pytest

from filters.localization.likelihood_field import (
    LikelihoodFieldConfig,
    LikelihoodFieldModel,
    count_detections,
    distance_field,
    log_likelihood_kernel,
    select_beams,
)
from filters.mapping.grid import GridMap
from filters.robot_data.scans import LaserScan, SemanticScan

RES = 0.1
CLASSES = ("door", "chair")


def tiny_grid() -> GridMap:
    """5x5 cells of 0.1 m, one occupied cell at (row 2, col 2); cell (0, 0) is a 'door' cell
    (semantic only, not occupied); no 'chair' cell."""
    occ = np.zeros((5, 5), np.float32)
    occ[2, 2] = 1.0
    sem = np.zeros((2, 5, 5), np.float32)
    sem[0, 0, 0] = 1.0
    return GridMap(occ, RES, (0.0, 0.0), sem, CLASSES)


CFG = LikelihoodFieldConfig(sigma_hit_m=0.1, z_hit=0.9, z_rand=0.1, max_dist_m=0.25, max_beams=0)
RMAX = 2.0


def hand_log_p(d: float, cfg: LikelihoodFieldConfig = CFG, rmax: float = RMAX) -> float:
    d = min(d, cfg.max_dist_m)
    return math.log(cfg.z_hit * math.exp(-d * d / (2 * cfg.sigma_hit_m**2)) + cfg.z_rand / rmax)


def test_distance_field_hand_values():
    d = distance_field(tiny_grid().occupied_mask(), RES)
    assert d[2, 2] == 0.0
    assert d[2, 4] == pytest.approx(0.2)
    assert d[0, 0] == pytest.approx(math.sqrt(8) * 0.1)
    assert d[3, 3] == pytest.approx(math.sqrt(2) * 0.1)
    assert np.all(np.isinf(distance_field(np.zeros((3, 3), bool), RES)))


def test_log_tables_hand_values_and_per_class_fields():
    m = LikelihoodFieldModel(tiny_grid(), CFG, CFG)
    tables, floors = m.log_tables(RMAX, RMAX)
    assert tables.shape == (3, 5, 5)
    # lidar field: distance to the occupied cell, capped at 0.25 m
    assert tables[0, 2, 2] == pytest.approx(math.log(0.9 + 0.1 / RMAX))
    assert tables[0, 2, 4] == pytest.approx(hand_log_p(0.2))
    assert tables[0, 0, 0] == pytest.approx(hand_log_p(0.25))  # sqrt(8)*0.1 = 0.283 > cap
    # door field: distance to the door cell (0, 0), not to the occupied cell
    assert tables[1, 0, 0] == pytest.approx(math.log(0.9 + 0.1 / RMAX))
    assert tables[1, 0, 1] == pytest.approx(hand_log_p(0.1))
    assert tables[1, 2, 2] == pytest.approx(hand_log_p(0.25))
    # chair has no cell: the field is the floor everywhere (carries no information)
    assert np.all(tables[2] == floors[2])
    assert floors[0] == pytest.approx(hand_log_p(0.25))
    assert floors[0] > math.log(0.1 / RMAX)
    # with the defaults (max_dist 2 m, sigma 0.2 m) the floor is the random-measurement floor
    d = LikelihoodFieldConfig()
    _, f_def = LikelihoodFieldModel(tiny_grid(), d, d).log_tables(RMAX, RMAX)
    assert f_def[0] == pytest.approx(math.log(d.z_rand / RMAX), abs=1e-9)


def test_single_beam_log_likelihood_hand_values():
    m = LikelihoodFieldModel(tiny_grid(), CFG, CFG)
    pose = np.array([[0.05, 0.25, 0.0]])  # centre of cell (2, 0), facing +x
    on_cell = LaserScan([0.2], [0.0], RMAX)  # ends in cell (2, 2)
    assert m.log_likelihood(pose, on_cell)[0] == pytest.approx(math.log(0.9 + 0.1 / RMAX))
    one_off = LaserScan([0.1], [0.0], RMAX)  # ends in cell (2, 1): 0.1 m from the obstacle
    assert m.log_likelihood(pose, one_off)[0] == pytest.approx(hand_log_p(0.1))
    up = LaserScan([0.2], [math.pi / 2], RMAX)  # ends at (0.05, 0.45): cell (4, 0)
    assert m.log_likelihood(pose, up)[0] == pytest.approx(hand_log_p(0.25))
    outside = LaserScan([1.0], [math.pi], RMAX)  # ends at x = -0.95: off the map
    _, floors = m.log_tables(RMAX, RMAX)
    assert m.log_likelihood(pose, outside)[0] == pytest.approx(floors[0])
    # beams at max range are skipped; several beams add up
    two = LaserScan([0.2, RMAX, 0.1], [0.0, 0.0, 0.0], RMAX)
    assert m.log_likelihood(pose, two)[0] == pytest.approx(math.log(0.9 + 0.1 / RMAX) + hand_log_p(0.1))
    assert m.log_likelihood(pose, LaserScan([RMAX, 5.0], [0.0, 1.0], RMAX))[0] == 0.0


def test_semantic_beams_use_their_class_field_and_unlabelled_beams_add_nothing():
    m = LikelihoodFieldModel(tiny_grid(), CFG, CFG)
    pose = np.array([[0.25, 0.05, math.pi]])  # centre of cell (0, 2), facing -x
    door = SemanticScan([0.2], [0.0], [1], RMAX)  # ends in the door cell (0, 0)
    ll_l, ll_s, beams = m.log_likelihood_terms(pose, None, door)
    assert ll_l[0] == 0.0 and beams.n_semantic == 1 and beams.n_lidar == 0
    assert ll_s[0] == pytest.approx(math.log(0.9 + 0.1 / RMAX))
    chair = SemanticScan([0.2], [0.0], [2], RMAX)  # same end point, but no chair anywhere
    assert m.log_likelihood(pose, None, chair)[0] == pytest.approx(hand_log_p(1.0))
    unlabelled = SemanticScan([0.2, 0.1], [0.0, 0.1], [0, 0], RMAX)
    assert m.log_likelihood(pose, None, unlabelled)[0] == 0.0
    with pytest.raises(ValueError, match="no class"):
        m.log_likelihood(pose, None, SemanticScan([0.2], [0.0], [3], RMAX))


def test_beam_selection_and_detection_count():
    valid = np.ones(10, bool)
    valid[3] = False
    assert select_beams(valid, 2, 0).tolist() == [0, 2, 4, 6, 8]
    assert select_beams(valid, 1, 3).tolist() == [0, 5, 9]
    assert select_beams(valid, 1, 0).tolist() == [0, 1, 2, 4, 5, 6, 7, 8, 9]
    s = SemanticScan(np.ones(9), np.zeros(9), [0, 1, 1, 2, 2, 0, 1, 0, 3], 5.0)
    assert count_detections(s) == 4
    s_far = SemanticScan([1.0, 9.0, 1.0], np.zeros(3), [1, 1, 1], 5.0)  # middle beam: no return
    assert count_detections(s_far) == 2


def test_config_validation_and_unknown_keys():
    with pytest.raises(ValueError):
        LikelihoodFieldConfig(sigma_hit_m=0.0)
    with pytest.raises(ValueError):
        LikelihoodFieldConfig(z_hit=0.0, z_rand=0.0)
    with pytest.raises(ValueError):
        LikelihoodFieldConfig(beam_stride=0)
    with pytest.raises(TypeError):
        LikelihoodFieldConfig(sigma=0.1)  # unknown key


def test_zero_z_rand_and_tiny_sigma_stay_finite():
    cfg = LikelihoodFieldConfig(sigma_hit_m=1e-3, z_hit=1.0, z_rand=0.0, max_dist_m=5.0)
    m = LikelihoodFieldModel(tiny_grid(), cfg, cfg)
    ll = m.log_likelihood(np.array([[0.05, 0.05, 0.0], [9.0, 9.0, 1.0]]), LaserScan([0.3, 0.3], [0.0, 1.0], RMAX))
    assert np.all(np.isfinite(ll))
    assert np.all(ll < -1e4)  # astronomically unlikely, but a number


def test_kernel_equals_reference_for_end_points_on_cell_faces():
    from filters.localization.likelihood_reference import log_likelihood_reference

    grid = GridMap(np.kron(np.eye(8), np.ones((2, 2))).astype(np.float32), 0.05, (-0.2, 0.1))
    model = LikelihoodFieldModel(grid, CFG, CFG)
    k = np.arange(-2, 20)
    # particles on cell corners, beams of whole cells along the axes: end points on cell faces
    poses = np.array([(-0.2 + 0.05 * i, 0.1 + 0.05 * j, th) for i in k for j in k for th in (0.0, np.pi / 2, -np.pi)])
    angles = np.array([0.0, np.pi / 2, np.pi, -np.pi / 2, np.pi / 4])
    scan = LaserScan(np.array([0.05, 0.1, 0.15, 0.35, 0.05 * np.sqrt(2)]), angles, RMAX)
    a = model.log_likelihood(poses, scan)
    b = log_likelihood_reference(model, poses, scan)
    np.testing.assert_allclose(a, b, rtol=0, atol=1e-9)
    assert np.ptp(a) > 1.0


def test_cached_model_is_shared_by_equal_maps_and_keyed_on_configs():
    from filters.localization import likelihood_field as lf

    grid = tiny_grid()
    twin = tiny_grid()  # another object, same content
    m = lf.cached_model(grid, CFG, CFG)
    assert lf.cached_model(twin, CFG, CFG) is m
    assert lf.cached_model(grid, CFG, lf.DEFAULT_SEMANTIC_FIELD) is not m
    assert lf.cached_model(grid, CFG, CFG, backend="numpy").backend == "numpy"
    changed = GridMap(
        np.where(np.eye(5, dtype=bool), 1.0, 0.0).astype(np.float32), RES, (0.0, 0.0), twin.semantic, CLASSES
    )
    assert lf.cached_model(changed, CFG, CFG) is not m
    np.testing.assert_array_equal(m.distance_fields_m, LikelihoodFieldModel(grid, CFG, CFG).distance_fields_m)
    for s in np.linspace(0.11, 0.5, lf.MODEL_CACHE_SIZE + 1):  # evicts m (least recently used)
        lf.cached_model(grid, CFG, LikelihoodFieldConfig(sigma_hit_m=float(s)))
    assert lf.cached_model(grid, CFG, CFG) is not m
    with pytest.raises(TypeError, match="grid"):
        lf.cached_model(np.zeros((5, 5)), CFG, CFG)
    with pytest.raises(ValueError, match="backend"):
        lf.cached_model(grid, CFG, CFG, backend="cuda")


def _fixed_order_sum(v: np.ndarray) -> float:
    """The kernel's documented summation order (`likelihood_field._gather_sum`), in Python."""
    n, r = v.size, 0.0
    m = (n // 16) * 16
    if m:
        acc = np.zeros(16)
        for j in range(0, m, 16):
            acc = acc + v[j : j + 16]
        s = (acc[0:4] + acc[4:8]) + (acc[8:12] + acc[12:16])
        r = float((s[0] + s[2]) + (s[1] + s[3]))
    e = m + ((n - m) // 4) * 4
    if e > m:
        b = np.array([r, 0.0, 0.0, 0.0])
        for j in range(m, e, 4):
            b = b + v[j : j + 4]
        r = float((b[0] + b[2]) + (b[1] + b[3]))
    for j in range(e, n):
        r += float(v[j])
    return r


def test_kernel_sums_beams_in_one_fixed_order_whatever_the_compilation():
    # Under fastmath, a freshly compiled kernel and the same kernel loaded from numba's cache
    # summed in different orders (the first process on a machine differed in the last bits).
    # The kernel now writes its order out; this pins it exactly, for every split and length.
    rng = np.random.default_rng(11)
    for _ in range(200):
        nb = int(rng.integers(1, 130))
        n_lidar = int(rng.integers(0, nb + 1))
        vals = rng.normal(-3.0, 2.0, nb)
        flat = vals.copy()
        flat.setflags(write=False)
        one = np.zeros(1)
        lu, lv = np.arange(nb) + 0.5, np.full(nb, 0.5)  # beam j ends in cell j of a 1-row map
        zeros = np.zeros(nb, np.int64)
        out_l, out_s = np.zeros(1), np.zeros(1)
        log_likelihood_kernel(
            one,
            one.copy(),
            np.ones(1),
            np.zeros(1),
            lu,
            lv,
            zeros,
            zeros,
            n_lidar,
            flat,
            0.0,
            0.0,
            1.0,
            nb,
            1,
            out_l,
            out_s,
        )
        assert out_l[0] == _fixed_order_sum(vals[:n_lidar])
        assert out_s[0] == _fixed_order_sum(vals[n_lidar:])


def test_tolerance_flattens_the_hit_score_near_the_cells_and_is_off_by_default():
    plain, tolerant = LikelihoodFieldConfig(), LikelihoodFieldConfig(tolerance_m=0.05)
    d = np.array([0.0, 0.02, 0.05, 0.1, 0.3, 5.0])
    lp, lt = plain.log_p(d, 8.0), tolerant.log_p(d, 8.0)
    assert lt[0] == lt[1] == lt[2] == lp[0]  # within 5 cm of a surface: as on it
    np.testing.assert_allclose(lt[3:5], plain.log_p(d[3:5] - 0.05, 8.0))  # beyond: shifted by the tolerance
    assert lt[5] == lp[5]  # far off: the random-measurement floor either way
    np.testing.assert_array_equal(LikelihoodFieldConfig(tolerance_m=0.0).log_p(d, 8.0), lp)
    for bad in (-0.1, math.nan, math.inf, True, "0.1"):
        with pytest.raises(ValueError, match="tolerance_m"):
            LikelihoodFieldConfig(tolerance_m=bad)
