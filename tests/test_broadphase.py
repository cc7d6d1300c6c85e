"""Tests of the spring broad phase (fraytool.collision.broadphase) and of the batch detection
(fraytool.collision.detect) against brute-force oracles on seeded random configurations."""
from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest

from fraytool.collision import (
    detect_edge_edge_collisions,
    edge_edge_ccd,
    find_candidate_pairs,
)
from fraytool.collision.broadphase import candidate_pairs_of_segments_kernel, swept_boxes_kernel


# --- helpers ------------------------------------------------------------------------------------
def random_scene(seed: int, particles: int = 300, springs: int = 500, motion: float = 0.01):
    """Particles in the unit cube moving a little; springs: a yarn chain (neighbours share end
    particles) plus short springs to particles 1-3 indices on (some zero-length); about 15 % dead;
    yarn ids with -1 for about 10 % (non-yarn springs)."""
    rng = np.random.default_rng(seed)
    # a random walk folded into the unit cube: particles with near indices are near in space
    x_start = np.abs((np.cumsum(0.04 * rng.standard_normal((particles, 3)), axis=0) + 0.5) % 2.0 - 1.0)
    x_end = x_start + motion * rng.standard_normal((particles, 3))
    chain = min(springs // 2, particles - 1)
    a = np.concatenate([np.arange(chain), rng.integers(0, particles, springs - chain)])
    b = np.concatenate([np.arange(1, chain + 1), np.zeros(springs - chain, dtype=np.int64)])
    b[chain:] = np.minimum(a[chain:] + rng.integers(1, 4, springs - chain), particles - 1)
    alive = rng.random(springs) > 0.15
    yarn = np.where(rng.random(springs) < 0.1, -1, rng.integers(0, 8, springs))
    return x_start, x_end, a.astype(np.int32), b.astype(np.int32), alive, yarn.astype(np.int32)


def swept_boxes(x_start, x_end, a, b, margin):
    lo = np.empty((a.shape[0], 3))
    hi = np.empty((a.shape[0], 3))
    swept_boxes_kernel(x_start, x_end, a, b, float(margin), lo, hi)
    return lo, hi


def brute_force_pairs(x_start, x_end, a, b, alive, margin, yarn=None) -> np.ndarray:
    """O(n^2) oracle over the same swept boxes, with the documented pair rule (all pairs tested
    at once with NumPy broadcasting)."""
    lo, hi = swept_boxes(x_start, x_end, a, b, margin)
    use = alive.copy()
    if yarn is not None:
        use &= yarn >= 0
    overlap = np.all((lo[:, None, :] <= hi[None, :, :]) & (lo[None, :, :] <= hi[:, None, :]), axis=2)
    shared = (
        (a[:, None] == a[None, :])
        | (a[:, None] == b[None, :])
        | (b[:, None] == a[None, :])
        | (b[:, None] == b[None, :])
    )
    keep = overlap & ~shared & use[:, None] & use[None, :]
    i, j = np.nonzero(np.triu(keep, k=1))
    return np.stack([i, j], axis=1).astype(np.int32)


def assert_same_pairs(got: np.ndarray, want: np.ndarray) -> None:
    got_set = set(map(tuple, got.tolist()))
    want_set = set(map(tuple, want.tolist()))
    assert got_set == want_set, (
        f"missing {sorted(want_set - got_set)[:10]}, extra {sorted(got_set - want_set)[:10]}"
    )
    assert got.shape[0] == len(got_set), "duplicate pairs"


# --- broad phase --------------------------------------------------------------------------------
@pytest.mark.parametrize("seed", [0, 1, 2, 3])
@pytest.mark.parametrize("margin", [0.0, 0.01])
def test_pairs_equal_brute_force(seed, margin):
    x_start, x_end, a, b, alive, yarn = random_scene(seed)
    got = find_candidate_pairs(x_start, x_end, a, b, alive, margin)
    assert got.dtype == np.int32 and got.ndim == 2 and got.shape[1] == 2
    assert_same_pairs(got, brute_force_pairs(x_start, x_end, a, b, alive, margin))
    # sorted lexicographically, i < j
    assert np.all(got[:, 0] < got[:, 1])
    keys = got[:, 0].astype(np.int64) * a.shape[0] + got[:, 1]
    assert np.all(np.diff(keys) > 0)


@pytest.mark.parametrize("seed", [4, 5])
def test_pairs_with_yarn_ids_and_small_cells(seed):
    x_start, x_end, a, b, alive, yarn = random_scene(seed, particles=200, springs=300)
    want = brute_force_pairs(x_start, x_end, a, b, alive, 0.02, yarn)
    got = find_candidate_pairs(x_start, x_end, a, b, alive, 0.02, spring_yarn=yarn)
    assert_same_pairs(got, want)
    # a cell much smaller than the boxes: each box spans many cells, pairs still reported once
    got_small = find_candidate_pairs(x_start, x_end, a, b, alive, 0.02, spring_yarn=yarn, cell_size=0.03)
    assert np.array_equal(got_small, got)


def test_deterministic():
    scene = random_scene(7)
    first = find_candidate_pairs(*scene[:5], 0.01)
    for _ in range(3):
        assert np.array_equal(find_candidate_pairs(*scene[:5], 0.01), first)


def test_shared_end_points_and_dead_springs_skipped():
    # a yarn of 4 collinear segments: neighbours share a particle, others do not overlap
    x = np.array([[i, 0.0, 0.0] for i in range(5)])
    a = np.arange(4, dtype=np.int32)
    b = np.arange(1, 5, dtype=np.int32)
    alive = np.ones(4, bool)
    assert find_candidate_pairs(x, x, a, b, alive, 0.0).shape == (0, 2)
    # with a margin, springs 0 and 2 overlap (gap 1 <= 2 * 0.6), but 0-1 and 1-2 stay skipped
    got = find_candidate_pairs(x, x, a, b, alive, 0.6)
    assert got.tolist() == [[0, 2], [1, 3]]
    alive[2] = False
    assert find_candidate_pairs(x, x, a, b, alive, 0.6).tolist() == [[1, 3]]


def test_degenerate_inputs():
    x = np.zeros((4, 3))
    a = np.array([0, 2], np.int32)
    b = np.array([1, 3], np.int32)
    # all points at one place: boxes of size zero, still reported (they touch)
    assert find_candidate_pairs(x, x, a, b, np.ones(2, bool), 0.0).tolist() == [[0, 1]]
    # fewer than two live springs, or none at all
    assert find_candidate_pairs(x, x, a, b, np.array([True, False]), 0.0).shape == (0, 2)
    empty = np.zeros(0, np.int32)
    assert find_candidate_pairs(x, x, empty, empty, np.zeros(0, bool), 0.0).shape == (0, 2)
    # one huge box among small ones (coarse grid) is still exact
    x_start, x_end, a, b, alive, _ = random_scene(8, particles=100, springs=150)
    x_end[5] += 50.0
    assert_same_pairs(
        find_candidate_pairs(x_start, x_end, a, b, alive, 0.0),
        brute_force_pairs(x_start, x_end, a, b, alive, 0.0),
    )


def test_bad_inputs_raise():
    x = np.zeros((3, 3))
    a = np.array([0], np.int32)
    with pytest.raises(ValueError):
        find_candidate_pairs(x, x, a, np.array([3], np.int32), np.ones(1, bool), 0.0)
    with pytest.raises(ValueError):
        find_candidate_pairs(x, x, a, np.array([1, 2], np.int32), np.ones(1, bool), 0.0)
    with pytest.raises(ValueError):
        find_candidate_pairs(x, x, a, np.array([1], np.int32), np.ones(1, bool), -1.0)
    x_bad = x.copy()
    x_bad[1, 0] = np.nan
    with pytest.raises(ValueError):
        find_candidate_pairs(x_bad, x, a, np.array([1], np.int32), np.ones(1, bool), 0.0)


def test_swept_boxes_contain_inflated_end_points():
    x_start, x_end, a, b, _, _ = random_scene(9, particles=50, springs=60)
    margin = 0.1
    lo, hi = swept_boxes(x_start, x_end, a, b, margin)
    m = Fraction(margin)
    for s in range(a.shape[0]):
        pts = np.stack([x_start[a[s]], x_start[b[s]], x_end[a[s]], x_end[b[s]]])
        for k in range(3):
            assert Fraction(lo[s, k]) <= Fraction(pts[:, k].min()) - m  # exact comparison
            assert Fraction(hi[s, k]) >= Fraction(pts[:, k].max()) + m


# --- batch detection ----------------------------------------------------------------------------
@pytest.mark.parametrize("seed", [10, 11])
def test_detect_matches_pairwise_narrow_phase(seed):
    x_start, x_end, a, b, alive, _ = random_scene(seed, particles=150, springs=200, motion=0.1)
    thickness = 0.01
    pairs, t = detect_edge_edge_collisions(x_start, x_end, a, b, alive, thickness)
    want_pairs, want_t = [], []
    for i, j in find_candidate_pairs(x_start, x_end, a, b, alive, thickness).tolist():
        rows = [a[i], b[i], a[j], b[j]]
        hit, tij = edge_edge_ccd(x_start[rows], x_end[rows], thickness)
        if hit:
            want_pairs.append((i, j))
            want_t.append(tij)
    assert pairs.dtype == np.int32 and t.dtype == np.float64
    assert pairs.tolist() == [list(p) for p in want_pairs]
    assert np.array_equal(t, np.array(want_t))
    assert len(want_pairs) > 0


def test_detect_crossing_yarns():
    # yarn A along x at z = 0; yarn B along y at x = 0.5, falling from z = 1 to z = -1
    xa = np.array([[i, 0.0, 0.0] for i in range(4)])
    xb_start = np.array([[0.5, j - 1.5, 1.0] for j in range(4)])
    x_start = np.vstack([xa, xb_start])
    x_end = np.vstack([xa, xb_start - [0.0, 0.0, 2.0]])
    a = np.array([0, 1, 2, 4, 5, 6], np.int32)
    b = np.array([1, 2, 3, 5, 6, 7], np.int32)
    alive = np.ones(6, bool)
    pairs, t = detect_edge_edge_collisions(x_start, x_end, a, b, alive, 0.0)
    # only segment 0 of A (x in [0, 1]) meets segment 1 of B (y in [-0.5, 0.5]), at t = 0.5
    assert pairs.tolist() == [[0, 4]]
    assert 0.5 - 1e-5 <= t[0] <= 0.5
    # a thickness of 0.6 reaches the neighbouring segments too, earlier
    pairs, t = detect_edge_edge_collisions(x_start, x_end, a, b, alive, 0.6)
    assert [0, 4] in pairs.tolist() and len(pairs) > 1
    assert np.all(t < 0.5)


# --- listed segments, buffer growth, degenerate grids -----------------------------------------
@pytest.mark.parametrize("seed", [12, 13])
def test_listed_segments_match_the_full_kernel(seed):
    x_start, x_end, a, b, alive, yarn = random_scene(seed)
    segments = np.nonzero(yarn >= 0)[0].astype(np.int32)  # dead ones included: skipped
    got = candidate_pairs_of_segments_kernel(x_start, x_end, a, b, alive, segments, 0.01, 0.0)
    assert np.array_equal(got, find_candidate_pairs(x_start, x_end, a, b, alive, 0.01, spring_yarn=yarn))
    with pytest.raises(ValueError):
        candidate_pairs_of_segments_kernel(x_start, x_end, a, b, alive, segments[::-1].copy(), 0.01, 0.0)


def test_more_pairs_than_the_first_buffer():
    # 150 short springs in a small cube with a large margin: nearly all 11175 pairs overlap, far
    # more than the first pair buffer (2 n + 16) holds
    rng = np.random.default_rng(14)
    x = rng.random((300, 3)) * 0.1
    a = np.arange(0, 300, 2, dtype=np.int32)
    b = np.arange(1, 300, 2, dtype=np.int32)
    alive = np.ones(150, bool)
    got = find_candidate_pairs(x, x, a, b, alive, 0.05)
    want = brute_force_pairs(x, x, a, b, alive, 0.05)
    assert len(want) > 10000
    assert np.array_equal(got, want)


def test_tiny_cells_and_huge_coordinates():
    x_start, x_end, a, b, alive, _ = random_scene(15, particles=100, springs=150)
    # a cell far smaller than the boxes: coarsened (at most 4 n + 1024 columns), still exact
    got = find_candidate_pairs(x_start, x_end, a, b, alive, 0.01, cell_size=1e-5)
    assert np.array_equal(got, brute_force_pairs(x_start, x_end, a, b, alive, 0.01))
    # coordinates near the float64 limit: the scene's extent overflows, one column, still exact
    x_far = x_end.copy()
    x_far[3] = [1e308, -1e308, 1e308]
    x_far[4] = [-1e308, 1e308, -1e308]
    x_near_far = x_start.copy()
    x_near_far[10:13] = x_far[10:13] = 1e308  # boxes entirely at the far end too
    got = find_candidate_pairs(x_near_far, x_far, a, b, alive, 0.0)
    assert np.array_equal(got, brute_force_pairs(x_near_far, x_far, a, b, alive, 0.0))
