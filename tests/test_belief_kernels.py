"""The numba belief summary against the NumPy reference: equal bit for bit (labels, counts, floats)."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from filters.localization import belief_kernels as K
from filters.localization.belief import BeliefConfig, cluster_labels, cluster_stats, histogram_entropy, summarize
from filters.pose import wrap_angle


def same_bits(a, b) -> None:
    """Arrays or floats equal bit for bit (NaN == NaN, -0.0 != 0.0)."""
    a, b = np.asarray(a), np.asarray(b)
    assert a.shape == b.shape and a.dtype == b.dtype
    assert a.tobytes() == b.tobytes()


def clouds(seed: int):
    """Particle clouds that exercise every branch: blobs, haze, seam-straddling headings, poses on
    bin edges, a uniform map-wide cloud, zero-weight clusters, a single particle."""
    rng = np.random.default_rng(seed)
    out = []
    n = int(rng.integers(1, 4000))
    # several blobs plus haze
    k = int(rng.integers(1, 6))
    centres = rng.uniform([-5, -5, -np.pi], [15, 10, np.pi], (k, 3))
    idx = rng.integers(0, k, n)
    p = centres[idx] + rng.normal(0, 1, (n, 3)) * rng.uniform([0.02, 0.02, 0.01], [1.0, 1.0, 1.5])
    haze = rng.random(n) < 0.1
    p[haze] = rng.uniform([-5, -5, -4], [15, 10, 4], (int(haze.sum()), 3))
    p[:, 2] = wrap_angle(p[:, 2])
    w = rng.random(n) ** rng.uniform(1, 30)
    out.append((p, w))
    # headings exactly at +-pi and on bin edges, positions on bin edges
    m = 500
    q = np.empty((m, 3))
    q[:, 0] = rng.integers(-4, 4, m) * 0.5
    q[:, 1] = rng.integers(-4, 4, m) * 0.25
    edges = [-np.pi, np.nextafter(np.pi, 0.0), np.nextafter(-np.pi, -4.0), -np.pi / 4, np.pi / 8, 0.0, 3 * np.pi / 4]
    q[:, 2] = rng.choice(edges, m)  # nextafter(-pi, -inf) wraps to +pi itself: the last heading bin's clamp
    out.append((q, rng.random(m)))
    # uniform over a map, some weights exactly 0 (zero-weight clusters)
    u = rng.uniform([0, 0, -np.pi], [14, 9, np.pi], (3000, 3))
    wu = rng.random(3000)
    wu[u[:, 0] > 10] = 0.0
    out.append((u, wu))
    out.append((u[:1].copy(), np.ones(1)))
    return out


@pytest.mark.parametrize("seed", range(4))
def test_entropy_and_labels_match_reference(seed):
    for p, w in clouds(seed):
        wn = w / w.sum()
        for bxy, bth in ((0.5, math.pi / 8), (0.5, math.pi / 4), (0.3, math.pi / 2), (1.0, 2 * math.pi)):
            same_bits(histogram_entropy(p, wn, bxy, bth, "numba"), histogram_entropy(p, wn, bxy, bth, "numpy"))
            for weights, frac in ((wn, 0.05), (wn, 0.0), (None, 0.0), (wn, 0.5)):
                lab_a, n_a = cluster_labels(p, bxy, bth, weights, frac, backend="numba")
                lab_b, n_b = cluster_labels(p, bxy, bth, weights, frac, backend="numpy")
                assert n_a == n_b
                same_bits(lab_a, lab_b)
                for x, y in zip(cluster_stats(p, wn, lab_a, n_a, "numba"), cluster_stats(p, wn, lab_b, n_b, "numpy")):
                    same_bits(x, y)


@pytest.mark.parametrize("seed", range(4))
def test_summary_matches_reference(seed):
    for p, w in clouds(seed):
        for cfg in (BeliefConfig(), BeliefConfig(converged_rule="spread", cluster_min_weight=0.0)):
            a, b = summarize(p, w, cfg, "numba"), summarize(p, w, cfg, "numpy")
            assert repr(a.as_dict(10**6)) == repr(b.as_dict(10**6))
            same_bits(a.cov, b.cov)
            for ha, hb in zip(a.hypotheses, b.hypotheses, strict=True):
                same_bits(ha.cov, hb.cov)


def same_summary(p, w, cfg=None) -> None:
    """`summarize`'s two backends give the same Belief, bit for bit."""
    a, b = summarize(p, w, cfg, "numba"), summarize(p, w, cfg, "numpy")
    assert repr(a.as_dict(10**6)) == repr(b.as_dict(10**6))
    same_bits(a.cov, b.cov)
    for ha, hb in zip(a.hypotheses, b.hypotheses, strict=True):
        same_bits(ha.cov, hb.cov)


@pytest.mark.parametrize("e_bin, c_bin", [(0.3, 0.7), (1.0, 0.25), (0.25, 0.5)])
def test_summary_with_entropy_and_cluster_cells_of_different_sizes(e_bin, c_bin):
    """The fused raster kernel bins the positions once only when the two rasters' cells are the same size; here each
    raster is binned on its own (a wrong raster size there would write out of bounds)."""
    rng = np.random.default_rng(0)
    centres = rng.uniform([-5, -5, -np.pi], [15, 10, np.pi], (4, 3))
    p = centres[rng.integers(0, 4, 2000)] + rng.normal(0, 1, (2000, 3)) * [0.5, 0.5, 0.7]
    same_summary(p, rng.random(2000) ** 5, BeliefConfig(entropy_bin_xy_m=e_bin, cluster_bin_m=c_bin))


def test_a_heading_just_below_minus_pi_lands_in_the_last_heading_bin():
    """``nextafter(-pi, -inf)`` wraps to +pi itself, whose bin index is one past the last: both rasters clamp it."""
    p = np.array([[5.0, 0.0, np.nextafter(-np.pi, -4.0)], [0.0, 0.0, -3.0], [0.0, 1.0, -3.0]])
    same_summary(p, np.ones(3))
    assert summarize(p, np.ones(3)).n_clusters == 3


@pytest.mark.parametrize("e_bin, c_bin", [(0.5, 0.5), (0.25, 1.0), (1.0, 0.25), (0.5, 0.25), (0.25, 0.5)])
def test_a_cloud_too_wide_for_the_rasters_summarises_alike(e_bin, c_bin):
    """Half the particles in one place, half over 1500 m x 900 m: the entropy and cluster rasters do not fit, and
    `summarize` takes the reference's fallbacks (a sort for the entropy, 4x coarser cluster cells)."""
    rng = np.random.default_rng(5)
    p = rng.uniform([0, 0, -np.pi], [1500, 900, np.pi], (3000, 3))
    p[:1500] = [700.0, 400.0, 0.5] + rng.normal(0, 0.3, (1500, 3))
    same_summary(p, rng.random(3000) ** 8, BeliefConfig(entropy_bin_xy_m=e_bin, cluster_bin_m=c_bin))
    cfg = BeliefConfig(entropy_bin_xy_m=e_bin, cluster_bin_m=c_bin, cluster_min_weight=0.0)
    same_summary(p, np.ones(3000), cfg)


@pytest.mark.parametrize("backend", ["numba", "numpy"])
def test_bad_poses_are_refused_before_bad_weights(backend):
    nan = np.zeros((3, 3))
    nan[1, 0] = np.nan
    for weights in (np.ones(4), ["a", "b", "c"], np.ones(3) * (1 + 1j), np.array([1.0, -1.0, 1.0])):
        with pytest.raises(ValueError, match="NaN or inf"):
            summarize(nan, weights, backend=backend)
    far = np.zeros((3, 3))
    far[0, 0] = 2e15
    with pytest.raises(ValueError, match="from the origin"):
        summarize(far, np.ones(2), backend=backend)
    with pytest.raises(ValueError, match=r"weights must have shape \(3,\)"):
        summarize(np.zeros((3, 3)), np.ones(4), backend=backend)


def test_seam_joins_components_like_the_reference():
    """Two blobs that touch only across the +-pi heading seam are one cluster in both backends;
    components numbered by their first raster cell."""
    rng = np.random.default_rng(3)
    a = np.column_stack([rng.normal(1.0, 0.05, 200), rng.normal(1.0, 0.05, 200), np.full(200, np.pi - 0.05)])
    b = np.column_stack([rng.normal(1.0, 0.05, 200), rng.normal(1.0, 0.05, 200), np.full(200, -np.pi + 0.05)])
    c = np.column_stack([rng.normal(5.0, 0.05, 200), rng.normal(0.2, 0.05, 200), np.zeros(200)])
    p = np.vstack([a, b, c])
    for backend in ("numba", "numpy"):
        lab, n = cluster_labels(p, 0.5, math.pi / 4, backend=backend)
        assert n == 2
        assert len(set(lab[:400])) == 1 and lab[400] != lab[0]


def test_wrap_kernel_is_wrap_angle():
    rng = np.random.default_rng(0)
    a = np.concatenate([rng.uniform(-20, 20, 5000), [np.pi, -np.pi, 0.0, -0.0, 3 * np.pi, -3 * np.pi, 1e-300]])
    got = np.array([K._wrap(v) for v in a])
    same_bits(got, wrap_angle(a))


def test_bad_backend_is_an_error():
    p = np.zeros((3, 3))
    with pytest.raises(ValueError, match="backend"):
        summarize(p, np.ones(3), backend="cuda")
    with pytest.raises(ValueError, match="backend"):
        cluster_labels(p, 0.5, 0.5, backend="")


def test_absurdly_spread_cloud_takes_the_coarser_raster_in_both_backends():
    """More than 4M raster cells: both backends re-bin at 4x the cell size, with the same labels."""
    rng = np.random.default_rng(5)
    p = rng.uniform([0, 0, -np.pi], [1500, 900, np.pi], (3000, 3))
    p[:1500] = [700.0, 400.0, 0.5] + rng.normal(0, 0.3, (1500, 3))
    w = rng.random(3000)
    w /= w.sum()
    lab_a, n_a = cluster_labels(p, 0.5, math.pi / 4, w, 0.05, backend="numba")
    lab_b, n_b = cluster_labels(p, 0.5, math.pi / 4, w, 0.05, backend="numpy")
    assert n_a == n_b >= 1
    same_bits(lab_a, lab_b)
    same_bits(histogram_entropy(p, w, 0.5, math.pi / 8, "numba"), histogram_entropy(p, w, 0.5, math.pi / 8, "numpy"))


def _components_oracle(occupied: np.ndarray, ny: int, nx: int, nt: int, wrap_t: bool) -> tuple[np.ndarray, int]:
    """Connected components of the 26-neighbourhood graph (headings circular with ``wrap_t``), numbered by
    their first cell in C order: scipy's graph components, not a flood fill."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    cells = np.flatnonzero(occupied)
    y, x, t = np.unravel_index(cells, (ny, nx, nt))
    src, dst = [], []
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            for dt in (-1, 0, 1):
                yy, xx, tt = y + dy, x + dx, t + dt
                if wrap_t:
                    tt = tt % nt
                ok = (yy >= 0) & (yy < ny) & (xx >= 0) & (xx < nx) & (tt >= 0) & (tt < nt)
                nb = np.ravel_multi_index((yy[ok], xx[ok], tt[ok]), (ny, nx, nt))
                keep = occupied[nb]
                src.append(cells[ok][keep])
                dst.append(nb[keep])
    size = ny * nx * nt
    graph = coo_matrix((np.ones(sum(map(len, src))), (np.concatenate(src), np.concatenate(dst))), (size, size))
    _, comp = connected_components(graph, directed=False)
    lab = np.zeros(size, dtype=np.int64)
    first = {}
    for c in cells:
        lab[c] = first.setdefault(comp[c], len(first) + 1)
    return lab, len(first)


@pytest.mark.parametrize("seed", range(3))
def test_label_components_kernel_matches_a_graph_oracle(seed):
    """Random rasters of every shape from 1 x 1 x 1 on, sparse to full, with and without the heading wrap:
    both kernels, the run-based one and the flood fill it calls for ``nt > 64``."""
    rng = np.random.default_rng(seed)
    for _ in range(200):
        ny, nx = (int(v) for v in rng.integers(1, 8, 2))
        nt = int(rng.choice([1, 2, 3, 4, 5, 7, 8, 16, 63, 64, 65]))
        occupied = rng.random(ny * nx * nt) < rng.uniform(0.0, 1.0)
        for wrap_t in (False, True):
            want, n_want = _components_oracle(occupied, ny, nx, nt, wrap_t)
            for kernel in (K.label_components, K._label_components_flood):
                lab = np.zeros(ny * nx * nt, dtype=np.int64)
                n = kernel(occupied, ny, nx, nt, wrap_t, lab)
                assert n == n_want
                same_bits(lab, want)


def same_as_flood(occupied: np.ndarray, ny: int, nx: int, nt: int, wrap_t: bool) -> None:
    """`label_components` gives the flood fill's ``lab`` and ``n`` exactly, and writes no unoccupied cell."""
    lab = np.zeros(ny * nx * nt, dtype=np.int64)
    n = K.label_components(occupied, ny, nx, nt, wrap_t, lab)
    ref = np.zeros(ny * nx * nt, dtype=np.int64)
    n_ref = K._label_components_flood(occupied, ny, nx, nt, wrap_t, ref)
    assert n == n_ref, (ny, nx, nt, wrap_t)
    assert np.array_equal(lab, ref), (ny, nx, nt, wrap_t)
    marked = np.where(occupied, 0, -7).astype(np.int64)  # unoccupied cells keep what they hold
    assert K.label_components(occupied, ny, nx, nt, wrap_t, marked) == n
    assert np.array_equal(marked, np.where(occupied, lab, -7))


def _all_patterns(bits: int) -> np.ndarray:
    return ((np.arange(2**bits)[:, None] >> np.arange(bits)) & 1).astype(bool)


@pytest.mark.parametrize(
    "ny, nx, nts",
    [(1, 1, range(1, 13)), (1, 2, range(1, 7)), (2, 1, range(1, 7)), (2, 2, range(1, 4)), (1, 3, (1, 2, 3))],
)
def test_label_components_matches_the_flood_fill_on_every_small_raster(ny, nx, nts):
    """Every occupancy pattern of one column (headings 1..12), of two neighbouring columns (1..6 headings)
    and of 2 x 2 columns (1..3): every run split, seam merge and pairing of runs in neighbouring columns."""
    for nt in nts:
        for occupied in _all_patterns(ny * nx * nt):
            for wrap_t in (False, True):
                same_as_flood(occupied, ny, nx, nt, wrap_t)


def _edge_rasters():
    """``(name, rasters, ny, nx, nt)``: empty, full, each single cell, strips one column wide, runs across the
    heading seam, every other heading, the env's raster."""
    for ny, nx, nt in ((1, 1, 1), (1, 1, 2), (1, 1, 3), (2, 3, 8), (3, 2, 63), (2, 2, 64), (2, 2, 65), (20, 30, 8)):
        yield "empty", [np.zeros(ny * nx * nt, dtype=bool)], ny, nx, nt
        yield "full", [np.ones(ny * nx * nt, dtype=bool)], ny, nx, nt
    for ny, nx, nt in ((3, 4, 1), (3, 4, 2), (3, 4, 3), (2, 3, 8), (2, 2, 63), (2, 2, 64), (1, 2, 65)):
        yield "single cells", list(np.eye(ny * nx * nt, dtype=bool)), ny, nx, nt
    rng = np.random.default_rng(11)
    for ny, nx, nt in ((1, 40, 8), (40, 1, 8), (1, 25, 64), (25, 1, 63), (1, 1, 64), (1, 1, 65), (1, 9, 65)):
        yield "strip", [rng.random(ny * nx * nt) < p for p in (0.1, 0.5, 0.9)], ny, nx, nt
    for nt in (3, 4, 8, 63, 64):
        seam = np.zeros((3, 3, nt), dtype=bool)
        seam[0, 0, [0, nt - 1]] = True  # one circular run, or two runs without the wrap
        seam[1, 1, nt - 1] = True  # touches (0, 0) at nt - 1, and (2, 2) only across the seam
        seam[2, 2, 0] = True
        seam[0, 2, 1 : nt - 1] = True  # the middle headings, touching (1, 1) at nt - 2
        alternate = np.zeros((2, 3, nt), dtype=bool)
        alternate[:, :, ::2] = True  # every other heading: runs of one
        alternate[1, 1] = ~alternate[1, 1]
        yield "seam", [seam.ravel()], 3, 3, nt
        yield "alternate", [alternate.ravel()], 2, 3, nt
    yield "env", [rng.random(20 * 30 * 8) < p for p in (0.05, 0.4, 0.8)], 20, 30, 8


@pytest.mark.parametrize(
    "rasters, ny, nx, nt", [pytest.param(*r[1:], id=f"{r[0]}-{r[2]}x{r[3]}x{r[4]}") for r in _edge_rasters()]
)
def test_label_components_matches_the_flood_fill_on_edge_cases(rasters, ny, nx, nt):
    for occupied in rasters:
        for wrap_t in (False, True):
            same_as_flood(occupied, ny, nx, nt, wrap_t)


@settings(max_examples=400, deadline=None)
@given(
    ny=st.integers(1, 9),
    nx=st.integers(1, 9),
    nt=st.sampled_from([1, 2, 3, 8, 16, 63, 64, 65]) | st.integers(1, 70),
    wrap_t=st.booleans(),
    density=st.floats(0.0, 1.0),
    seed=st.integers(0, 2**32 - 1),
)
def test_label_components_matches_the_flood_fill(ny, nx, nt, wrap_t, density, seed):
    same_as_flood(np.random.default_rng(seed).random(ny * nx * nt) < density, ny, nx, nt, wrap_t)


def test_wrap_float_is_wrap_angle():
    """`filters.pose.wrap_float` (Python floats, used for single angles) gives `wrap_angle`'s bits."""
    from filters.pose import wrap_float

    rng = np.random.default_rng(1)
    edges = [np.pi, -np.pi, 0.0, -0.0, 1e-300, -5e-324, 3 * np.pi, -3 * np.pi, 1e6, -1e6]
    edges += [np.nextafter(v, d) for v in (np.pi, -np.pi) for d in (-np.inf, np.inf)]
    a = np.concatenate([rng.uniform(-4, 4, 20000), rng.uniform(-1e4, 1e4, 2000), edges])
    same_bits(np.array([wrap_float(v) for v in a.tolist()]), wrap_angle(a))


@pytest.mark.parametrize("seed", range(4))
def test_hypothesis_order_is_the_stable_sort_of_the_kept_clusters(seed):
    rng = np.random.default_rng(seed)
    edges = [0.0, 0.01, 0.02, 0.02 - 5e-13, 0.02 - 1e-12, 0.02 - 2e-12, np.nextafter(0.02 - 1e-12, 0), 0.3, 0.5, np.nan]
    for n in (0, 1, 5, 60, 64, 65, 500):  # beyond 64 kept: the merge sort
        cw = rng.choice(edges, n) if seed % 2 else rng.random(n) / 10
        for min_weight in (0.0, 0.02, 1.0):
            keep = np.flatnonzero((cw >= min_weight - 1e-12) & (cw > 0))
            want = keep[np.argsort(-cw[keep], kind="stable")]
            assert np.array_equal(K.hypothesis_order(cw, min_weight), want)


def test_compose_of_one_pose_is_the_array_path():
    """`filters.pose.compose` of one ``(3,)`` pose and increment (Python floats, as the filter's bookkeeping composes
    each step) gives the bits of the same pose composed as a ``(1, 3)`` array, non-finite input included."""
    from filters.pose import compose

    rng = np.random.default_rng(3)
    scale = 10.0 ** rng.integers(-3, 5, (20000, 1))
    poses, deltas = rng.normal(size=(20000, 3)) * scale, rng.normal(size=(20000, 3)) * scale * 0.1
    poses[::9, 2] = rng.choice([np.pi, -np.pi, np.nextafter(np.pi, 0), 1e5, -1e-300, -0.0], size=poses[::9].shape[0])
    special = [(0.0, 0.0, np.inf), (np.nan, 0.0, 0.0), (1e308, 0.0, 0.0), (0.0, 0.0, 0.0)]
    poses = np.vstack([poses, special])
    deltas = np.vstack([deltas, [(1.0, 0.0, 0.0), (1.0, 0.0, 0.0), (1e308, 0.0, 0.0), (np.inf, 1.0, 0.0)]])
    with np.errstate(all="ignore"):
        one = np.array([compose(p, d) for p, d in zip(poses, deltas, strict=True)])
        same_bits(one, compose(poses, deltas))
    assert compose([1.0, 2.0, 0.5], (0.1, 0.0, 0.2)).dtype == np.float64  # sequences too
    with pytest.warns(RuntimeWarning, match="overflow"):  # finite numbers that overflow: NumPy's warning, as before
        compose(np.array([1.5e308, -1.5e308, 0.0]), np.array([1.5e308, 0.0, 0.0]))


@pytest.mark.parametrize(
    "w",
    [
        np.array([0.25, 0.5, 0.25]),
        np.random.default_rng(0).random(5000) ** 20,
        np.array([1e308, 1e308, 1.0]),  # finite weights whose sum overflows: scaled first
        np.array([1e300, 3e299, 0.0, 5e-324]),
        np.array([0.0, 5e-324]),
        np.array([7.0]),
    ],
)
def test_summary_weights_are_normalise_weights_bit_for_bit(w):
    from filters.localization.belief import _normalised
    from filters.smc.resampling import normalise_weights

    same_bits(_normalised(w, w.size), normalise_weights(w))


@pytest.mark.parametrize(
    ("w", "match"),
    [
        (np.zeros(3), "sum to zero"),
        (np.array([1.0, -0.5]), "non-negative"),
        (np.array([1.0, np.nan]), "finite"),
        (np.array([np.inf, 1.0]), "finite"),
    ],
)
def test_summary_refuses_the_weights_normalise_weights_refuses(w, match):
    p = np.zeros((w.size, 3))
    for backend in ("numba", "numpy"):
        with pytest.raises(ValueError, match=match):
            summarize(p, w, backend=backend)


def test_cos_sin_is_numpys_cos_and_sin():
    """`filters.pose.cos_sin` (one compiled sincos pass) gives NumPy's float64 cos and sin bit for bit, strided
    input included: the summary, the likelihood kernels' headings and the audit take it for NumPy's."""
    from filters.pose import cos_sin

    rng = np.random.default_rng(2)
    th = np.concatenate(
        [rng.uniform(-np.pi, np.pi, 200_000), rng.uniform(-1e4, 1e4, 20_000), [0.0, -0.0, np.pi, -np.pi, 1e-300]]
    )
    c, s = cos_sin(th)
    same_bits(c, np.cos(th))
    same_bits(s, np.sin(th))
    p = np.column_stack([th, th, th])[:1000]
    c, s = cos_sin(p[:, 2])
    same_bits(c, np.cos(p[:, 2]))
    same_bits(s, np.sin(p[:, 2]))


@pytest.mark.parametrize("seed", range(6))
def test_cluster_members_is_a_stable_argsort_and_its_starts(seed):
    """Every label a cluster: the stable argsort; with label -1 (no cluster) too: the same without those particles."""
    rng = np.random.default_rng(seed)
    for n, k in ((0, 1), (1, 1), (7, 3), (5000, 1), (5000, 40), (300, 301)):
        labels = rng.integers(0, k, n)
        order, starts = K.cluster_members(labels, k)
        want = np.argsort(labels, kind="stable")
        assert np.array_equal(order, want)
        assert np.array_equal(starts, np.searchsorted(labels[want], np.arange(k + 1)))
        some = np.where(rng.random(n) < 0.3, -1, labels)
        order, starts = K.cluster_members(some, k)
        inside = np.flatnonzero(some >= 0)
        want = inside[np.argsort(some[inside], kind="stable")]
        assert np.array_equal(order, want)
        assert np.array_equal(starts, np.searchsorted(some[want], np.arange(k + 1)))


@pytest.mark.parametrize("spread_m", [(2**30 - 1) * 0.5, (2**31 - 1) * 0.5, 1e9, 1e12, 9e14])
def test_clouds_far_wider_than_any_map_summarise_alike_on_both_backends(spread_m):
    """Raster sizes beyond 2**63 cells: the compiled size check must not overflow (it wrapped round to a small or
    negative size and wrote out of bounds); both backends take the coarser fallback alike."""
    p = np.array([[0.0, 0.0, 0.0], [spread_m, spread_m, 1.0], [0.1, 0.2, 0.3]])
    w = np.array([0.5, 0.3, 0.2])
    same_bits(histogram_entropy(p, w, 0.5, math.pi / 8, "numba"), histogram_entropy(p, w, 0.5, math.pi / 8, "numpy"))
    a, b = summarize(p, w, backend="numba"), summarize(p, w, backend="numpy")
    assert repr(a.as_dict(10**6)) == repr(b.as_dict(10**6))


def test_labels_ignore_the_weights_without_a_bin_fraction_as_the_reference_does():
    p = np.array([[0.0, 0, 0], [0.1, 0, 0], [5, 5, 1]])
    w = np.array([np.nan, 1.0, 1.0])
    lab_a, n_a = cluster_labels(p, 0.5, math.pi / 4, w, 0.0, "numba")
    lab_b, n_b = cluster_labels(p, 0.5, math.pi / 4, w, 0.0, "numpy")
    assert n_a == n_b == 2
    same_bits(lab_a, lab_b)


def test_cos_sin_takes_1d_angles_only():
    from filters.pose import cos_sin

    with pytest.raises(ValueError, match="1D array of angles"):
        cos_sin(np.zeros((2, 3)))
    c, s = cos_sin([0.0, np.pi / 2])  # a list is taken as float64
    same_bits(c, np.cos(np.array([0.0, np.pi / 2])))
