"""The per-frame geometry kernels (numba loops over every crossing and spline sample) against plain
NumPy statements of the same formulas: the same numbers, to the bit, on random cloths and pieces
with cuts, degenerate crossings and shaped panels."""
import numpy as np
import pytest

from fraytool.grid import base_yarn_points, crossing_normals, yarn_neighbours
from fraytool.render.ribbon import CASTER_SAGITTA_RADII, ribbon_shadow_positions, ribbon_triangles, shadow_casters
from fraytool.render.tube import body_pairs, fade_alpha


def _normals_reference(x, W, H, neighbours=None):
    """docs/method.md §3.3: normalise((x_{i+1} - x_{i-1}) x (x_{j+1} - x_{j-1})), one-sided at the border,
    a degenerate crossing gets the mean of the others (or +z)."""
    if neighbours is None:
        g = x.reshape(H, W, 3)
        du, dv = np.empty_like(g), np.empty_like(g)
        du[:, 1:-1], du[:, 0], du[:, -1] = g[:, 2:] - g[:, :-2], g[:, 1] - g[:, 0], g[:, -1] - g[:, -2]
        dv[1:-1], dv[0], dv[-1] = g[2:] - g[:-2], g[1] - g[0], g[-1] - g[-2]
        n = np.cross(du, dv).reshape(-1, 3)
    else:
        n = np.cross(x[neighbours[1]] - x[neighbours[0]], x[neighbours[3]] - x[neighbours[2]])
    length = np.linalg.norm(n, axis=1)
    good = length > 1e-300
    n[good] /= length[good, None]
    if not good.all():
        mean = n[good].sum(axis=0)
        n[~good] = mean / np.linalg.norm(mean)
    return n


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_crossing_normals_and_base_points_match_the_numpy_formula(seed):
    rng = np.random.default_rng(seed)
    W, H = 7, 5
    j, i = np.divmod(np.arange(W * H), W)
    x = np.stack([i * 0.01, j * 0.01, np.zeros(W * H)], axis=1) + rng.normal(0, 0.002, (W * H, 3))
    x[2] = x[2 * W + 2]                              # the j neighbours of crossing W + 2 coincide: degenerate
    n = crossing_normals(x, W, H)
    assert np.array_equal(n, _normals_reference(x.copy(), W, H))
    assert np.allclose(np.linalg.norm(n, axis=1), 1.0)
    on_top = rng.random(W * H) < 0.5
    weft, warp = base_yarn_points(x, n, on_top, 3e-4)
    s = np.where(on_top, 1.5e-4, -1.5e-4)[:, None]
    assert np.array_equal(weft, x + s * n) and np.array_equal(warp, x - s * n)


def test_crossing_normals_through_a_shaped_panels_neighbours():
    rng = np.random.default_rng(3)
    # a 4 x 3 grid with its corner (i = 3, j = 2) cut away: 11 crossings, springs along the yarns
    places = [(i, j) for j in range(3) for i in range(4) if (i, j) != (3, 2)]
    index = {p: c for c, p in enumerate(places)}
    a, b, weft, warp = [], [], np.full((11, 2), -1), np.full((11, 2), -1)
    for (i, j), c in index.items():
        for (di, dj), slots in (((1, 0), weft), ((0, 1), warp)):
            other = index.get((i + di, j + dj))
            if other is not None:
                slots[c, 1] = slots[other, 0] = len(a)
                a.append(c)
                b.append(other)
    nb = yarn_neighbours(weft, warp, np.array(a), np.array(b))
    x = np.array([[i * 0.01, j * 0.01, 0.0] for i, j in places]) + rng.normal(0, 0.002, (11, 3))
    assert np.array_equal(crossing_normals(x, 4, 3, nb), _normals_reference(x.copy(), 4, 3, nb))


def _pieces(rng, counts):
    off = np.concatenate([[0], np.cumsum(counts)])
    t = np.arange(off[-1], dtype=float)
    x = np.stack([t * 0.002, 3e-5 * np.cos(np.pi * t), rng.normal(0, 2e-5, t.size)], axis=1)
    tangents = np.gradient(x, axis=0)
    tangents /= np.linalg.norm(tangents, axis=1)[:, None]
    return x, tangents, off


def test_fade_alpha_matches_the_arc_length_formula():
    rng = np.random.default_rng(4)
    x, _, off = _pieces(rng, [9, 2, 14, 5])
    start, end = np.array([True, False, True, False]), np.array([False, True, True, False])
    got = fade_alpha(x, off, start, end, 0.005)
    seg = np.zeros(len(x))
    seg[1:] = np.linalg.norm(x[1:] - x[:-1], axis=1)
    seg[off[:-1]] = 0.0
    s = np.cumsum(seg)
    piece = np.repeat(np.arange(4), np.diff(off))
    a = np.ones(len(x))
    a = np.where(start[piece], np.minimum(a, (s - s[off[:-1]][piece]) / 0.005), a)
    a = np.where(end[piece], np.minimum(a, (s[off[1:] - 1][piece] - s) / 0.005), a)
    assert np.array_equal(got, np.clip(a, 0.0, 1.0).astype(np.float32))
    assert got[off[3]:].min() == 1.0 and got[0] == 0.0 and got[off[2] - 1] == 0.0


def test_shadow_casters_match_the_even_and_bent_samples_rule():
    rng = np.random.default_rng(5)
    x, t, off = _pieces(rng, [11, 2, 7, 4])
    x[15] += [0.0, 0.004, 0.0]                        # a kink: an odd sample off its chord
    alpha = np.ones(len(x), np.float32)
    alpha[4] = 0.5                                     # a fading sample inside the first piece
    radius = 0.0004
    light = np.array([0.3, 1.0, 0.2]) / np.linalg.norm([0.3, 1.0, 0.2])
    positions, triangles = shadow_casters(x, t, off, alpha, radius, light)
    piece = np.repeat(np.arange(4), np.diff(off))
    local = np.arange(len(x)) - off[:-1][piece]
    last = np.zeros(len(x), bool)
    last[off[1:] - 1] = True
    inner = np.nonzero((local % 2 == 1) & ~last)[0]
    bent = np.zeros(len(x), bool)
    bent[inner] = np.linalg.norm(x[inner] - 0.5 * (x[inner - 1] + x[inner + 1]), axis=1) > CASTER_SAGITTA_RADII * radius
    keep = np.nonzero((local % 2 == 0) | last | bent)[0]
    assert 15 in keep
    kept_off = np.concatenate([[0], np.cumsum(np.bincount(piece[keep], minlength=4))])
    fading = np.concatenate([[0], np.cumsum(alpha < 1.0)])
    r = body_pairs(kept_off)
    see_through = fading[keep[r + 1] + 1] - fading[keep[r]] > 0
    assert see_through.sum() == 2                      # the strips either side of sample 4
    assert np.array_equal(positions, ribbon_shadow_positions(x[keep], t[keep], radius, light))
    assert np.array_equal(triangles, ribbon_triangles(kept_off)[~np.repeat(see_through, 2)])


def test_ribbon_curves_drop_the_straight_steps_middles():
    """ribbon_curves against its statement in NumPy: the spline sampled with every one-sample segment
    split in two, those middles within a quarter radius of their chord left out of the drawn samples
    (a tight bend keeps its middle), their tangents handed to the end of their step, and each sample's
    previous drawn tangent and index along its piece."""
    from fraytool.render.ribbon import ribbon_curves
    from fraytool.render.spline import catmull_rom, polyline_tangents

    rng = np.random.default_rng(6)
    x, _, off = _pieces(rng, [6, 2, 9])
    x[11] += [0.0, 0.003, 0.0]                        # a kink in the third piece
    radius = 0.0004
    m = rng.integers(1, 4, size=len(x) - 3)
    m[:3] = 1                                          # a run of straight steps from a piece's start
    m[4] = 1                                           # the second piece's only segment
    m[6:10] = 1                                        # steps around the kink
    curves, tangents, steps = ribbon_curves(x, off, m, radius)
    fine = catmull_rom(x, off, np.where(m == 1, 2, m))
    fine_t = polyline_tangents(fine.points, fine.offsets)
    first = np.ones(len(x), bool)
    first[off[1:] - 1] = False
    middle = fine.control_index[np.flatnonzero(first)][m == 1] + 1
    chord = 0.5 * (fine.points[middle - 1] + fine.points[middle + 1])
    bent = np.linalg.norm(fine.points[middle] - chord, axis=1) > CASTER_SAGITTA_RADII * radius
    assert 0 < bent.sum() < len(middle) - 3
    middle = middle[~bent]
    keep = np.ones(len(fine.points), bool)
    keep[middle] = False
    row = np.cumsum(keep) - 1
    assert np.array_equal(curves.points, fine.points[keep])
    assert np.array_equal(tangents, fine_t[keep])
    assert np.array_equal(curves.control_index, row[fine.control_index])
    assert np.array_equal(curves.offsets, np.concatenate([[0], row[fine.offsets[1:] - 1] + 1]))
    want = np.zeros((len(tangents), 7), np.float32)
    starts = curves.offsets[:-1]
    want[:, 0:3] = np.roll(tangents, 1, axis=0)
    want[starts, 0:3] = tangents[starts]
    want[row[middle + 1], 3:6] = fine_t[middle]
    want[:, 6] = np.arange(len(tangents)) - np.repeat(starts, np.diff(curves.offsets))
    assert np.array_equal(steps[0::2], want) and np.array_equal(steps[1::2], want)
    assert (np.abs(steps[:, 3:6]).sum(axis=1) > 0).sum() == 2 * len(middle)


def test_ribbon_curves_tilt_only_the_steps_asked_for():
    """With `tilted` given, only those one-sample segments get a middle (and its tangent); the others
    stay one plain step, sampled as catmull_rom samples them."""
    from fraytool.render.ribbon import ribbon_curves
    from fraytool.render.spline import catmull_rom

    rng = np.random.default_rng(7)
    x, _, off = _pieces(rng, [7])
    m = np.ones(6, dtype=np.int64)
    tilted = np.array([True, False, False, True, True, False])
    curves, _, steps = ribbon_curves(x, off, m, 0.0004, tilted)
    assert np.array_equal(curves.points, catmull_rom(x, off, m).points)        # no middle is drawn
    has_middle = np.abs(steps[0::2, 3:6]).sum(axis=1) > 0
    assert np.array_equal(np.flatnonzero(has_middle), np.flatnonzero(tilted) + 1)  # at each tilted step's end


def test_ribbon_steps_and_the_drawn_length_on_screen():
    """lod.ribbon_steps: 4-8 px segments become tilted one-sample steps where drawn at least half their
    length; projected_lengths_px measures the chord on screen (inf behind the near plane)."""
    from fraytool.render import lod
    from fraytool.render.camera import Camera
    from fraytool.scene.spec import CameraSpec

    length = np.array([3.0, 5.0, 7.0, 7.0, 9.0])
    drawn = np.array([3.0, 5.0, 3.0, 4.0, 9.0])
    samples = lod.samples_for_lengths(length, 4)
    assert samples.tolist() == [1, 2, 2, 2, 2]
    new, tilted = lod.ribbon_steps(length, drawn, samples)
    assert new.tolist() == [1, 1, 2, 1, 2] and tilted.tolist() == [False, True, False, True, False]
    cam = Camera(CameraSpec(position_m=(0.0, 0.0, 1.0), target_m=(0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0), fov_deg=90.0))
    # at 1 m with a 90 degree field of view, 1 m spans half the image's height on screen: 100 px of 200
    pts = np.array([[0.0, 0.0, 0.0], [0.5, 0.0, 0.0], [0.5, 0.0, 2.0]])
    got = lod.projected_lengths_px(cam, (200, 200), pts, np.array([0, 3]))
    assert got[0] == pytest.approx(50.0) and got[1] == np.inf


def test_caster_points_bound_a_tuple_as_its_concatenation():
    from fraytool.render.shadow import caster_points

    rng = np.random.default_rng(8)
    a, b = rng.normal(size=(50, 3)).astype(np.float32), rng.normal(size=(7, 3)).astype(np.float32)
    none = np.zeros(0, np.int8), np.zeros((0, 3)), np.zeros(0), np.zeros((0, 3))
    together = caster_points(np.concatenate([a, b]).astype(np.float64), *none)
    apart = caster_points((a, b), *none)
    assert np.array_equal(together[0], apart[0]) and np.array_equal(together[1], apart[1])
    assert apart[0].min(axis=0) == pytest.approx(np.concatenate([a, b]).min(axis=0))
