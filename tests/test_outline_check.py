"""The panel outline's checks against plain, quadratic references: the first pair of crossing edges (a grid of
cells in fraytool, every pair here) and the even-odd inside test (a sort in fraytool, every edge against every
point here), on random polygons that cross, touch and do not."""
from __future__ import annotations

import numpy as np
import pytest

from fraytool.scene.panel_shape import first_crossing_edges, inside_polygon, segments_cross

pytestmark = pytest.mark.fast


def reference_first_crossing(outline):
    k = outline.shape[0]
    for e in range(k):
        for f in range(e + 2, k):
            if e == 0 and f == k - 1:
                continue
            if segments_cross(outline[e], outline[(e + 1) % k], outline[f], outline[(f + 1) % k]):
                return e, f
    return None


def reference_inside(points, polygon):
    inside = np.zeros(points.shape[0], bool)
    x, y = points[:, 0], points[:, 1]
    k = polygon.shape[0]
    for e in range(k):
        (x0, y0), (x1, y1) = polygon[e], polygon[(e + 1) % k]
        straddles = (y0 > y) != (y1 > y)
        with np.errstate(divide="ignore", invalid="ignore"):
            xc = x0 + (y - y0) * (x1 - x0) / (y1 - y0)
        inside ^= straddles & (x < xc)
    return inside


def star(rng, k, jitter):
    angle = np.sort(rng.uniform(0, 2 * np.pi, k))
    radius = 1.0 + jitter * rng.uniform(-1, 1, k)
    return np.stack([radius * np.cos(angle), radius * np.sin(angle)], axis=1)


@pytest.mark.parametrize("seed", range(12))
def test_the_first_crossing_pair_is_the_references(seed):
    rng = np.random.default_rng(seed)
    crossings = 0
    for k in (3, 4, 7, 30, 120):
        simple = star(rng, k, 0.1)                    # about a circle: no crossing, mostly
        assert first_crossing_edges(simple) == reference_first_crossing(simple)
        messy = rng.uniform(-1, 1, (k, 2))            # random points: crossings (k > 3)
        assert first_crossing_edges(messy) == reference_first_crossing(messy)
        grid = rng.integers(0, 4, (k, 2)).astype(float)  # on a small lattice: touching, collinear edges
        grid = grid[np.r_[True, (np.diff(grid, axis=0) != 0).any(axis=1)]]
        if len(grid) >= 3 and not (grid[0] == grid[-1]).all():
            assert first_crossing_edges(grid) == reference_first_crossing(grid)
        crossings += reference_first_crossing(messy) is not None
    assert crossings >= 2  # the random cases do cross (k = 3 cannot, k = 4 may not)


@pytest.mark.parametrize("seed", range(6))
def test_inside_is_the_references_bit_for_bit(seed):
    rng = np.random.default_rng(100 + seed)
    polygon = star(rng, 40, 0.5)
    points = rng.uniform(-1.6, 1.6, (5000, 2))
    points[:200] = np.round(points[:200] * 4) / 4     # some on the polygon's corners' rows
    np.testing.assert_array_equal(inside_polygon(points, polygon), reference_inside(points, polygon))
    lattice = np.round(polygon * 8) / 8                 # corners on the points' rows and columns
    grid = np.stack(np.meshgrid(np.arange(-12, 13) / 8, np.arange(-12, 13) / 8), axis=-1).reshape(-1, 2)
    np.testing.assert_array_equal(inside_polygon(grid, lattice), reference_inside(grid, lattice))
