"""Yarn geometry without GL: pieces from frame records, splines, rotation-minimising frames, tubes,
fade alpha, level of detail."""
from __future__ import annotations

import numpy as np
import pytest

from fraytool.render.camera import Camera
from fraytool.render.lod import choose_detail, segment_samples
from fraytool.render.spline import catmull_rom, polyline_tangents, sample_counts
from fraytool.render.tube import (
    fade_alpha,
    sweep_tubes,
    transport_frames,
    translucent_triangles,
    tube_triangle_count,
    tube_triangles,
    tube_vertex_count,
)
from fraytool.render.yarns import WARP, WEFT, yarn_pieces
from fraytool.scene.spec import CameraSpec

RNG = np.random.default_rng(12)


def _pieces(*polylines):
    pts = np.concatenate(polylines)
    off = np.concatenate([[0], np.cumsum([len(p) for p in polylines])])
    return pts, off


# -- spline -----------------------------------------------------------------------------------

def test_spline_passes_through_control_points():
    a = np.cumsum(RNG.uniform(0.001, 0.03, size=(9, 3)), axis=0)          # unevenly spaced
    b = RNG.normal(size=(2, 3))                                             # a two-point piece
    c = np.cumsum(RNG.uniform(-0.01, 0.01, size=(5, 3)), axis=0) + 1.0
    pts, off = _pieces(a, b, c)
    for m in (1, 3, 5):
        curves = catmull_rom(pts, off, m)
        np.testing.assert_allclose(curves.points[curves.control_index], pts, atol=1e-12)
        assert np.array_equal(np.diff(curves.offsets), sample_counts(np.diff(off), m))
        # piece boundaries: first and last samples are the first and last control points
        np.testing.assert_allclose(curves.points[curves.offsets[:-1]], pts[off[:-1]], atol=1e-12)
        np.testing.assert_allclose(curves.points[curves.offsets[1:] - 1], pts[off[1:] - 1], atol=1e-12)


def test_centripetal_spline_does_not_backtrack_on_uneven_collinear_points():
    """Uniform Catmull-Rom overshoots and runs backwards between close points; centripetal does not
    (Yuksel et al. 2011). The uniform case shows the check can fail."""
    x = np.array([0.0, 1.0, 1.02, 3.0])
    pts = np.stack([x, np.zeros(4), np.zeros(4)], axis=1)
    off = np.array([0, 4])
    centripetal = catmull_rom(pts, off, 16).points[:, 0]
    uniform = catmull_rom(pts, off, 16, alpha=0.0).points[:, 0]
    assert np.all(np.diff(centripetal) >= -1e-12)
    assert np.any(np.diff(uniform) < -1e-3)


def test_a_segment_with_its_own_sample_count_gives_the_same_curve_points():
    """Per-segment counts (the level of detail): a segment sampled m times has the points the uniform
    sampling at 4 gives at the same parameters (u = k / m), and control_index still finds every
    control point, piece ends included."""
    a = np.cumsum(RNG.uniform(0.001, 0.03, size=(7, 3)), axis=0)
    b = np.cumsum(RNG.uniform(-0.01, 0.01, size=(4, 3)), axis=0) + 1.0
    pts, off = _pieces(a, b)
    m = np.array([1, 2, 4, 2, 1, 4, 2, 4, 1], dtype=np.int64)               # 6 + 3 segments
    fine = catmull_rom(pts, off, 4)
    mixed = catmull_rom(pts, off, m)
    np.testing.assert_allclose(mixed.points[mixed.control_index], pts, atol=1e-12)
    assert np.array_equal(np.diff(mixed.offsets), [m[:6].sum() + 1, m[6:].sum() + 1])
    seg = 0
    for p in range(2):
        for i in range(off[p], off[p + 1] - 1):
            for k in range(m[seg]):
                want = fine.points[fine.control_index[i] + k * 4 // m[seg]]
                np.testing.assert_allclose(mixed.points[mixed.control_index[i] + k], want, atol=1e-12)
            seg += 1
    with pytest.raises(ValueError):
        catmull_rom(pts, off, np.zeros(9, np.int64))


def test_spline_rejects_single_point_pieces():
    with pytest.raises(ValueError):
        catmull_rom(np.zeros((3, 3)), np.array([0, 1, 3]), 4)


# -- rotation-minimising frames ------------------------------------------------------------------

def _helix(a=0.02, b=0.005, turns=2.0, n=4001):
    c = np.hypot(a, b)
    s = np.linspace(0.0, turns * 2 * np.pi * c, n)
    t = s / c
    p = np.stack([a * np.cos(t), a * np.sin(t), b * t], axis=1)
    T = np.stack([-a * np.sin(t), a * np.cos(t), np.full_like(t, b)], axis=1) / c
    N = np.stack([-np.cos(t), -np.sin(t), np.zeros_like(t)], axis=1)        # Frenet normal
    B = np.cross(T, N)
    tau = b / c ** 2                                                        # torsion
    return s, p, T, N, B, tau


def test_transport_frames_are_orthonormal_and_rotation_minimising_on_a_helix():
    s, p, T, N, B, tau = _helix()
    U, V = transport_frames(p, T, np.array([0, len(p)]), reference_normal=N[:1])
    # orthonormal
    np.testing.assert_allclose(np.linalg.norm(U, axis=1), 1.0, atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(V, axis=1), 1.0, atol=1e-9)
    np.testing.assert_allclose(np.einsum("ij,ij->i", U, T), 0.0, atol=1e-9)
    np.testing.assert_allclose(np.einsum("ij,ij->i", U, V), 0.0, atol=1e-9)
    # analytic rotation-minimising frame: the Frenet frame turned by -tau * s about T (Bishop 1975)
    theta = -tau * s
    U_exact = np.cos(theta)[:, None] * N + np.sin(theta)[:, None] * B
    angle = np.arccos(np.clip(np.einsum("ij,ij->i", U, U_exact), -1, 1))
    assert angle.max() < 1e-4, f"frame drifts from the analytic RMF by {angle.max():.2e} rad"
    # untwisted: dU/ds has no component along V (no rotation about the tangent)
    dU = np.gradient(U, s, axis=0)
    twist = np.abs(np.einsum("ij,ij->i", dU, V))[2:-2]
    frenet_twist = np.abs(np.einsum("ij,ij->i", np.gradient(N, s, axis=0), B))[2:-2]
    assert twist.max() < 1e-3 * frenet_twist.min(), "transported normal rotates about the tangent"


def test_transport_frames_start_from_the_reference_normal():
    p = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0]], float)
    T = np.tile([1.0, 0, 0], (3, 1))
    U, _ = transport_frames(p, T, np.array([0, 3]), reference_normal=np.array([[0.3, 0.0, 1.0]]))
    np.testing.assert_allclose(U, np.tile([0, 0, 1.0], (3, 1)), atol=1e-12)      # straight: no turn


# -- tubes ----------------------------------------------------------------------------------------

@pytest.mark.parametrize("sides,m", [(3, 1), (6, 4), (8, 3)])
def test_tube_vertex_and_triangle_counts_match_the_sampling(sides, m):
    pts, off = _pieces(np.cumsum(RNG.uniform(0.001, 0.01, (7, 3)), 0), RNG.normal(size=(2, 3)) * 0.01,
                       np.cumsum(RNG.uniform(0.001, 0.01, (4, 3)), 0))
    curves = catmull_rom(pts, off, m)
    counts = np.diff(curves.offsets)
    assert list(counts) == [6 * m + 1, 1 * m + 1, 3 * m + 1]
    T = polyline_tangents(curves.points, curves.offsets)
    mesh = sweep_tubes(curves.points, T, curves.offsets, 0.001, sides, np.ones(len(T)))
    assert len(mesh.vertices) == tube_vertex_count(counts, sides) == sides * counts.sum() + 2 * 3 * (sides + 1)
    assert len(mesh.triangles) == tube_triangle_count(counts, sides) == 2 * sides * (counts - 1).sum() + 2 * 3 * sides
    assert mesh.triangles.max() < len(mesh.vertices)


def test_tube_is_closed_and_faces_outward():
    pts = np.array([[0, 0, 0], [0.01, 0.002, 0], [0.02, 0, 0.003], [0.03, 0.001, 0.001]], float)
    off = np.array([0, 4])
    curves = catmull_rom(pts, off, 4)
    T = polyline_tangents(curves.points, curves.offsets)
    r = 0.001
    mesh = sweep_tubes(curves.points, T, curves.offsets, r, 6, np.ones(len(T)))
    tri = mesh.triangles.astype(np.int64)
    P = mesh.position.astype(np.float64)
    # every edge is shared by exactly two triangles: the capped tube is watertight
    edges = np.sort(np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]]), axis=1)
    pos_key = {}
    for e in map(tuple, edges):     # weld cap rim vertices with ring vertices by position
        a, b = (tuple(np.round(P[v], 9)) for v in e)
        key = tuple(sorted((a, b)))
        pos_key[key] = pos_key.get(key, 0) + 1
    assert set(pos_key.values()) == {2}
    # counter-clockwise from outside: the face normal agrees with the vertex normals
    face_n = np.cross(P[tri[:, 1]] - P[tri[:, 0]], P[tri[:, 2]] - P[tri[:, 0]])
    vert_n = mesh.normal[tri].mean(axis=1)
    assert np.all(np.einsum("ij,ij->i", face_n, vert_n) > 0)
    # ring vertices lie at the radius from the centre line
    ring = P[: len(curves.points) * 6].reshape(-1, 6, 3)
    np.testing.assert_allclose(np.linalg.norm(ring - curves.points[:, None, :], axis=2), r, rtol=1e-5)


def test_alpha_is_one_away_from_broken_ends_and_zero_at_the_tip():
    x = np.linspace(0.0, 0.1, 101)
    line = np.stack([x, np.zeros_like(x), np.zeros_like(x)], axis=1)
    pts, off = _pieces(line, line, line)
    fade = 0.02
    # piece 0: cut at its end; piece 1: cut at its start; piece 2: both ends at the cloth border
    alpha = fade_alpha(pts, off, np.array([False, True, False]), np.array([True, False, False]), fade)
    a0, a1, a2 = alpha[:101], alpha[101:202], alpha[202:]
    assert a0[-1] == 0.0 and a1[0] == 0.0                     # the broken tips are transparent
    assert np.all(a0[x <= 0.1 - fade - 1e-9] == 1.0)          # opaque farther than fade from the cut
    assert np.all(a1[x >= fade + 1e-9] == 1.0)
    assert np.all(a2 == 1.0)                                  # border ends do not fade
    np.testing.assert_allclose(a0[90], 0.5, atol=1e-6)        # linear over the fade length
    assert np.all(np.diff(a0) <= 0)


def test_translucent_mask_matches_the_triangles_vertices():
    x = np.linspace(0.0, 0.05, 11)
    line = np.stack([x, np.zeros_like(x), np.zeros_like(x)], axis=1)
    pts, off = _pieces(line, line + 1.0)
    curves = catmull_rom(pts, off, 3)
    alpha = fade_alpha(curves.points, curves.offsets, np.array([True, False]), np.array([False, False]), 0.01)
    T = polyline_tangents(curves.points, curves.offsets)
    mesh = sweep_tubes(curves.points, T, curves.offsets, 0.001, 5, alpha)
    expected = (mesh.alpha[mesh.triangles] < 1.0).any(axis=1)
    assert np.array_equal(translucent_triangles(curves.offsets, 5, alpha), expected)
    assert expected.any() and not expected.all()


def test_triangle_index_buffer_is_the_documented_layout():
    """Two pieces of 3 and 2 samples, 3 sides, written out by hand from the layout in the
    fraytool.render.tube docstring: ring vertex k * 3 + q is side q of sample k (15 of them), then
    per piece a start cap (centre, 3 rim) and an end cap (centre, 3 rim): 15-18 and 19-22 for
    piece 0, 23-26 and 27-30 for piece 1. Quad (a, b, c, d) = (sample k side q, k side q+1,
    k+1 side q, k+1 side q+1) gives triangles (a, b, c) and (b, d, c); start caps (centre, q+1, q)
    face -T, end caps (centre, q, q+1) face +T. No quad joins sample 2 to sample 3 (another piece).
    The buffer depends on nothing but the sample counts, so a renderer can cache it."""
    expected = [
        # piece 0, samples 0-1
        [0, 1, 3], [1, 4, 3], [1, 2, 4], [2, 5, 4], [2, 0, 5], [0, 3, 5],
        # piece 0, samples 1-2
        [3, 4, 6], [4, 7, 6], [4, 5, 7], [5, 8, 7], [5, 3, 8], [3, 6, 8],
        # piece 1, samples 3-4
        [9, 10, 12], [10, 13, 12], [10, 11, 13], [11, 14, 13], [11, 9, 14], [9, 12, 14],
        # start caps, pieces 0 and 1
        [15, 17, 16], [15, 18, 17], [15, 16, 18], [23, 25, 24], [23, 26, 25], [23, 24, 26],
        # end caps, pieces 0 and 1
        [19, 20, 21], [19, 21, 22], [19, 22, 20], [27, 28, 29], [27, 29, 30], [27, 30, 28],
    ]
    tri = tube_triangles(np.array([0, 3, 5]), 3)
    assert tri.dtype == np.uint32
    np.testing.assert_array_equal(tri, expected)


# -- yarn pieces from frame records ------------------------------------------------------------------

def test_yarns_follow_the_weave_at_base_level(posed_cloth):
    pc = posed_cloth
    rec = pc.copy()
    pieces = yarn_pieces(pc.topology, rec.particle_position_m, rec.crossing_yarn_level, rec.spring_alive)
    assert pieces.count == pc.W + pc.H                           # every yarn whole
    assert not pieces.broken_start.any() and not pieces.broken_end.any()
    weft0 = pieces.points[pieces.offsets[0]:pieces.offsets[1]]   # weft yarn j = 0
    on_top = pc.topology["crossing_weft_on_top"][: pc.W]
    y0 = rec.particle_position_m[: pc.W, 1]                      # flat cloth in xz, normal +-y
    half = 0.5 * pc.model.thickness_m
    np.testing.assert_allclose(np.abs(weft0[:, 1] - y0), half, rtol=1e-6)
    normal_sign = np.sign(pieces.normal[0, 1])
    assert np.array_equal((weft0[:, 1] - y0) * normal_sign > 0, on_top)


def test_pieces_split_at_a_dead_structural_spring(posed_cloth):
    pc = posed_cloth
    rec = pc.copy()
    j, i = 4, 6
    rec.spring_alive[pc.topology["weft_structural_spring"][j, i]] = False
    pieces = yarn_pieces(pc.topology, rec.particle_position_m, rec.crossing_yarn_level, rec.spring_alive)
    assert pieces.count == pc.W + pc.H + 1
    weft_j = np.nonzero((pieces.kind == WEFT) & (pieces.yarn == j))[0]
    assert len(weft_j) == 2
    lengths = np.diff(pieces.offsets)[weft_j]
    assert list(lengths) == [i + 1, pc.W - i - 1]
    first, second = weft_j
    assert not pieces.broken_start[first] and pieces.broken_end[first]       # border ... cut
    assert pieces.broken_start[second] and not pieces.broken_end[second]     # cut ... border
    assert pieces.first_crossing[second] == pc.crossing(i + 1, j)
    # warp yarns are untouched
    warp = pieces.kind == WARP
    assert warp.sum() == pc.W and not pieces.broken_start[warp].any()


def test_isolated_crossings_are_dropped_and_yarn_level_masses_used(posed_cloth):
    pc = posed_cloth
    rec = pc.copy()
    j, i = 5, 3
    for k in (i - 1, i):                                         # cut both sides of crossing i
        rec.spring_alive[pc.topology["weft_structural_spring"][j, k]] = False
    pieces = yarn_pieces(pc.topology, rec.particle_position_m, rec.crossing_yarn_level, rec.spring_alive)
    weft_j = np.nonzero((pieces.kind == WEFT) & (pieces.yarn == j))[0]
    assert list(np.diff(pieces.offsets)[weft_j]) == [i, pc.W - i - 1]    # the lone crossing is gone
    # a yarn-level crossing: the weft goes through slot c, the warp through slot C + c
    c = pc.crossing(2, 2)
    rec.crossing_yarn_level[c] = True
    rec.particle_position_m[c] += (0.0, 0.003, 0.0)
    rec.particle_position_m[pc.C + c] = rec.particle_position_m[c] - (0.0, 0.009, 0.0)
    pieces = yarn_pieces(pc.topology, rec.particle_position_m, rec.crossing_yarn_level, rec.spring_alive)
    weft2 = np.nonzero((pieces.kind == WEFT) & (pieces.yarn == 2))[0][0]
    warp2 = np.nonzero((pieces.kind == WARP) & (pieces.yarn == 2))[0][0]
    np.testing.assert_allclose(pieces.points[pieces.offsets[weft2] + 2], rec.particle_position_m[c])
    np.testing.assert_allclose(pieces.points[pieces.offsets[warp2] + 2], rec.particle_position_m[pc.C + c])


# -- level of detail ---------------------------------------------------------------------------------

def test_detail_grows_as_the_camera_comes_closer_and_stops_at_the_scene_maximum():
    pts = np.zeros((1, 3))
    details = []
    for d in (2.0, 0.5, 0.1, 0.02):
        cam = Camera(CameraSpec(position_m=(0.0, 0.0, d), target_m=(0.0, 0.0, 0.0), fov_deg=40.0))
        details.append(choose_detail(cam, 720, pts, radius_m=0.0005, spacing_m=0.004, max_sides=6, max_samples=4))
    sides = [x.sides for x in details]
    samples = [x.samples_per_segment for x in details]
    assert sides == sorted(sides) and samples == sorted(samples)
    assert details[0].sides == 3 and details[0].samples_per_segment == 2
    assert details[-1].sides == 6 and details[-1].samples_per_segment == 4


def test_segments_far_from_the_camera_get_fewer_samples_than_near_ones():
    """A piece running away from the camera: its segments' counts fall with distance, never above the
    frame's most, never below 2 but where a segment spans at most lod.STRAIGHT_PX pixels (then 1), each
    sample step at most lod.SAMPLE_PX pixels while the count can grow."""
    from fraytool.render import lod

    cam = Camera(CameraSpec(position_m=(0.0, 0.0, 0.05), target_m=(0.0, 0.0, 0.0), fov_deg=40.0))
    z = -np.linspace(0.0, 1.0, 251)
    pts = np.stack([np.full_like(z, 0.01), np.zeros_like(z), z], axis=1)      # 4 mm segments, going away
    off = np.array([0, len(z)])
    m = segment_samples(cam, 720, pts, off, 0.004, max_samples=6)
    assert m.shape == (250,) and m.dtype == np.int64
    assert np.all(np.diff(m) <= 0) and m[0] == 6 and m[-1] == 1
    depth = 0.05 - z[:-1]                                                    # the nearer end of each segment
    seg_px = 0.004 * 720 / (2.0 * depth * np.tan(np.radians(20.0)))
    assert np.all((seg_px / m <= lod.SAMPLE_PX + 1e-9) | (m == 6))
    assert np.array_equal(m == 1, seg_px <= lod.STRAIGHT_PX)                  # straight only where short
    assert (m == 2).any()
    assert np.all((seg_px / np.maximum(m - 1, 1) > lod.SAMPLE_PX) | (m <= 2))  # one fewer would be too long
