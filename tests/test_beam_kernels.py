"""The compiled beam selection (`filters.localization.beam_kernels`) against `LikelihoodFieldModel.beams_reference`:
the same `BeamSet` arrays, bit for bit, on random scans and configs."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from filters.localization import beam_kernels as K
from filters.localization.likelihood_field import (
    LikelihoodFieldConfig,
    LikelihoodFieldModel,
    NegativeEvidenceConfig,
    select_beams,
)
from filters.mapping.grid import GridMap
from filters.robot_data.scans import LaserScan, SemanticScan

FIELDS = ("lx", "ly", "table", "nx", "ny", "n_starts")
SCALARS = ("n_lidar", "n_semantic", "n_detections", "lidar_range_max_m", "semantic_range_max_m", "n_negative")


def grid() -> GridMap:
    occ = np.zeros((20, 30), np.float32)
    occ[5, 5:25] = 1.0
    sem = np.zeros((3, 20, 30), np.float32)
    sem[0, 10, 10] = sem[1, 3, 20] = sem[2, 15, 3] = 1.0
    return GridMap(occ, 0.1, (-1.0, -0.5), sem, ("door", "chair", "bin"))


def same_beams(a, b) -> None:
    for name in FIELDS:
        x, y = getattr(a, name), getattr(b, name)
        assert x.dtype == y.dtype and x.shape == y.shape, name
        assert x.tobytes() == y.tobytes(), name
    for name in SCALARS:
        assert repr(getattr(a, name)) == repr(getattr(b, name)), name


def random_scans(rng: np.random.Generator):
    n_l = int(rng.integers(0, 200))
    rmax = float(rng.uniform(2.0, 12.0))
    r = rng.uniform(0.0, rmax * 1.2, n_l)
    r[rng.random(n_l) < 0.1] = rmax  # exactly at the maximum: no return
    rmin = float(rng.choice([0.0, 0.1, 0.5]))
    pose = rng.choice([None, "turned", "shifted"])
    sp = {None: (0.0, 0.0, 0.0), "turned": (0.0, 0.0, float(rng.uniform(-3, 3))), "shifted": (0.1, -0.05, 0.3)}[pose]
    lidar = LaserScan(r, np.linspace(-math.pi, math.pi, n_l, endpoint=False), rmax, rmin, sp)
    n_s = int(rng.integers(0, 80))
    s_max = float(rng.uniform(2.0, 6.0))
    sr = rng.uniform(0.0, s_max * 1.2, n_s)
    sr[rng.random(n_s) < 0.1] = s_max
    labels = rng.integers(0, 4, n_s) * (rng.random(n_s) < rng.uniform(0, 1))
    labels[rng.random(n_s) < 0.3] = rng.integers(0, 4)  # runs of one label
    sp_s = (float(rng.uniform(-0.2, 0.2)), 0.0, float(rng.choice([0.0, -0.0, 0.5])))
    semantic = SemanticScan(sr, np.linspace(-0.6, 0.6, n_s), labels, s_max, sp_s)
    return lidar, semantic


@pytest.mark.parametrize("seed", range(12))
def test_compiled_beams_are_the_reference_bit_for_bit(seed):
    rng = np.random.default_rng(seed)
    g = grid()
    for _ in range(15):
        stride, max_beams = int(rng.integers(1, 4)), int(rng.choice([0, 1, 2, 7, 30, 500]))
        lidar_cfg = LikelihoodFieldConfig(beam_stride=stride, max_beams=max_beams)
        sem_cfg = LikelihoodFieldConfig(sigma_hit_m=0.3, max_dist_m=2.0, beam_stride=int(rng.integers(1, 3)))
        neg = NegativeEvidenceConfig(
            p_detect=float(rng.choice([0.0, 0.8])),
            max_beams=int(rng.integers(1, 40)),
            step_m=float(rng.choice([0.01, 0.15, 0.3])),
            margin_m=float(rng.choice([0.0, 0.2])),
        )
        model = LikelihoodFieldModel(g, lidar_cfg, sem_cfg, "numba", neg)
        lidar, semantic = random_scans(rng)
        for lid, sem in ((lidar, semantic), (None, semantic), (lidar, None), (None, None)):
            same_beams(model.beams(lid, sem), model.beams_reference(lid, sem))


def test_a_label_without_class_and_wrong_types_are_refused_alike():
    model = LikelihoodFieldModel(grid())
    bad = SemanticScan(np.ones(3), np.zeros(3), np.array([0, 9, 0]), 4.0)
    for beams in (model.beams, model.beams_reference):
        with pytest.raises(ValueError, match="no class in the map"):
            beams(None, bad)
        with pytest.raises(TypeError, match="lidar must be a LaserScan"):
            beams(bad, None)
        with pytest.raises(TypeError, match="semantic must be a SemanticScan"):
            beams(None, LaserScan(np.ones(3), np.zeros(3), 4.0))


@settings(max_examples=300, deadline=None)
@given(count=st.integers(2, 3000), data=st.data())
def test_spread_picks_are_numpys_rounded_linspace(count, data):
    max_beams = data.draw(st.integers(1, count - 1))
    want = np.round(np.linspace(0.0, count - 1, max_beams)).astype(np.int64)
    assert np.array_equal(K.spread_picks(count, max_beams), want)


@settings(max_examples=200, deadline=None)
@given(
    mask=st.lists(st.booleans(), max_size=300),
    stride=st.integers(1, 5),
    max_beams=st.integers(0, 40),
)
def test_select_is_select_beams(mask, stride, max_beams):
    m = np.array(mask, dtype=bool)
    assert np.array_equal(K.select(m, stride, max_beams), select_beams(m, stride, max_beams))


def test_returns_too_far_for_negative_evidence_are_refused_alike():
    """A semantic return 1e20 m away would need ~1e21 points: both paths refuse it with one message (the reference
    raised NumPy's "repeats may not contain negative values", the compiled pass dropped every negative beam)."""
    neg = NegativeEvidenceConfig(p_detect=0.8)
    model = LikelihoodFieldModel(grid(), negative=neg)
    scan = SemanticScan(np.array([1.0, 2.0, 1e20, 3.0]), np.linspace(-0.5, 0.5, 4), np.zeros(4, int), 1e305)
    for beams in (model.beams, model.beams_reference):
        with pytest.raises(ValueError, match="negative evidence samples points along each return"):
            beams(None, scan)
    ok = SemanticScan(np.array([1.0, 2.0, 1e20]), np.linspace(-0.5, 0.5, 3), np.zeros(3, int), 5.0)  # no return
    same_beams(model.beams(None, ok), model.beams_reference(None, ok))
    plain = LikelihoodFieldModel(grid())  # without negative evidence the distance does not matter
    same_beams(plain.beams(None, scan), plain.beams_reference(None, scan))
