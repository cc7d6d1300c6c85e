"""Clearance bounds (fraytool.sim.kernels.mesh_clearance): a mass's bound never exceeds its true distance
from the mesh, however the mass and an animated mesh move, and skipping what the bounds clear leaves the
contact passes' result unchanged, bit for bit."""
from __future__ import annotations

import numba as nb
import numpy as np
import pytest

from fraytool.geometry.triangles import closest_on_triangle
from fraytool.kinds import STRUCT_WARP, STRUCT_WEFT
from fraytool.sim.builder import ModelBuilder
from fraytool.sim.kernels.mesh_clearance import (SKIP_FACTOR, clearance_left, empty_clearance, empty_segment_clearance,
                                                  nearest_distance, segment_clearance, segment_clearance_left,
                                                  segment_distance)
from fraytool.sim.kernels.mesh_contact import NO_LEAVES, STACK
from fraytool.sim.mesh_geometry import MeshGeometry
from fraytool.sim.solver import SolverExplicitPBD

trimesh = pytest.importorskip("trimesh")

THICKNESS = 0.0008


@nb.njit(cache=True)
def _brute_distance(x, vertices, triangles):
    """Distance from x to the nearest triangle, every triangle tried (no tree, no bound)."""
    best = np.inf
    for j in range(triangles.shape[0]):
        a, b, c = vertices[triangles[j, 0]], vertices[triangles[j, 1]], vertices[triangles[j, 2]]
        qx, qy, qz, _, _, _ = closest_on_triangle(x[0], x[1], x[2], a[0], a[1], a[2], b[0], b[1], b[2],
                                                  c[0], c[1], c[2])
        best = min(best, np.sqrt((qx - x[0]) ** 2 + (qy - x[1]) ** 2 + (qz - x[2]) ** 2))
    return best


def _wobbling_ball(keys=3, duration=0.02):
    """An icosphere whose vertices swell and shift between keys (an animated mesh)."""
    m = trimesh.creation.icosphere(subdivisions=2, radius=0.03)
    v = np.asarray(m.vertices)
    rng = np.random.default_rng(4)
    frames = [v * (1.0 + 0.1 * k) + 0.002 * k * rng.standard_normal(v.shape) for k in range(keys)]
    return np.stack(frames), np.asarray(m.faces), np.linspace(0.0, duration, keys)


def _cloth(builder, n=16, spacing=0.004, y=0.0):
    half = 0.5 * (n - 1) * spacing
    builder.add_cloth(warp_yarns=n, weft_yarns=n, spacing_m=spacing, thickness_m=THICKNESS,
                      mass_per_crossing_kg=2e-5, structural_n_per_m=20.0, origin_m=(-half, y, -half))


def test_a_bound_never_exceeds_the_true_distance_as_points_and_an_animated_mesh_move():
    frames, faces, times = _wobbling_ball()
    b = ModelBuilder(seed=1)
    _cloth(b, n=8)
    b.add_mesh("ball", vertices_m=frames, triangles=faces, key_times_s=times, motion="kinematic")
    model = b.finalize()
    g = MeshGeometry(model)
    meshes = g.meshes_in(model)
    rng = np.random.default_rng(7)
    points = rng.uniform(-0.06, 0.06, (model.particle_count, 3))
    clear = g.clearance  # the mesh's travel counted by g.at_step
    stack = np.empty(STACK, np.int64)
    steps = np.linspace(0.0, 0.02, 21)
    g.at_step(steps[0], steps[1])
    for p, x in enumerate(points):  # references at the first step's end
        clear.clearance_m[0, p] = nearest_distance(0, meshes, x, clear.reach_m, stack, NO_LEAVES, -1)
        clear.reference_m[0, p] = x
        clear.travel_at_m[0, p] = clear.travel_start_m[0]
    exact = np.array([_brute_distance(x, g.vertex_end_m, faces) for x in points])
    assert np.all(clear.clearance_m[0] <= exact)
    assert np.all(clear.clearance_m[0] >= np.minimum(exact, clear.reach_m) - 1e-12)  # no looser than need be
    checked = 0
    for t0, t1 in zip(steps[1:-1], steps[2:]):
        g.at_step(t0, t1)
        moved = points + rng.normal(0.0, 0.0005, points.shape)
        for p in range(points.shape[0]):
            bound = clearance_left(clear, 0, p, *points[p], *moved[p])
            for tau in (0.0, 0.5, 1.0):  # any point of the path, against the surface at any time of the step
                x = points[p] + tau * (moved[p] - points[p])
                v = g.vertex_start_m + tau * (g.vertex_end_m - g.vertex_start_m)
                assert bound <= _brute_distance(x, v, faces) + 1e-12
                checked += bound > 0.0
        points = moved
    assert checked > 100  # the bounds were of use (positive), not all void


@nb.njit(cache=True)
def _brute_segment_distance(a, b, vertices, triangles, samples):
    """Least distance over `samples` evenly spaced points of segment ab to the nearest triangle, every triangle
    tried: at least the segment's distance, and at most |b - a| / (2 (samples - 1)) over it."""
    best = np.inf
    for i in range(samples):
        x = a + (i / (samples - 1)) * (b - a)
        best = min(best, _brute_distance(x, vertices, triangles))
    return best


def _segments_round(rng, count, radius):
    """Segments 2-6 mm long with their middles in a shell round a ball of `radius`, some through its
    surface."""
    mid = rng.normal(size=(count, 3))
    mid *= (radius + rng.uniform(-0.003, 0.004, (count, 1))) / np.linalg.norm(mid, axis=1, keepdims=True)
    half = rng.normal(size=(count, 3))
    half *= rng.uniform(0.001, 0.003, (count, 1)) / np.linalg.norm(half, axis=1, keepdims=True)
    return mid - half, mid + half


def test_a_segments_distance_is_the_least_over_its_points():
    """segment_distance (ends, edges, the plane crossing) against a dense search along the segment, on a
    ball: from segments crossing the surface (0) to segments millimetres off it."""
    m = trimesh.creation.icosphere(subdivisions=2, radius=0.03)
    b = ModelBuilder(seed=1)
    _cloth(b, n=2)
    b.add_mesh("ball", vertices_m=m.vertices, triangles=m.faces)
    model = b.finalize()
    g = MeshGeometry(model)
    meshes = g.meshes_in(model)
    v, f = np.asarray(m.vertices, np.float64), np.asarray(m.faces, np.int64)
    rng = np.random.default_rng(3)
    a, c = _segments_round(rng, 300, 0.03)
    samples = 2001
    stack = np.empty(STACK, np.int64)
    crossing = 0
    for i in range(a.shape[0]):
        d = segment_distance(0, meshes, a[i], c[i], 0.02, stack)
        dense = _brute_segment_distance(a[i], c[i], v, f, samples)
        step = np.linalg.norm(c[i] - a[i]) / (samples - 1)
        assert dense - 0.5 * step - 1e-12 <= d <= dense + 1e-12, (i, d, dense)
        crossing += dense < 0.5 * step
    assert 10 < crossing < 290  # both kinds met


def test_a_segments_bound_never_exceeds_its_true_distance_as_it_and_an_animated_mesh_move():
    """A segment's own bound (mesh_clearance, SegmentClearanceInOut) over a step: at most the distance of
    any point of the segment at any time of the step from the surface at any time of it, as segments and a
    wobbling ball move; and taken afresh when stale, never looser than need be."""
    frames, faces, times = _wobbling_ball()
    b = ModelBuilder(seed=1)
    _cloth(b, n=2)
    b.add_mesh("ball", vertices_m=frames, triangles=faces, key_times_s=times, motion="kinematic")
    model = b.finalize()
    g = MeshGeometry(model)
    meshes = g.meshes_in(model)
    clear = g.clearance
    rng = np.random.default_rng(11)
    a, c = _segments_round(rng, 60, 0.037)
    ends = np.stack([a, c], axis=1)
    bounds = empty_segment_clearance(1, ends.shape[0])
    stack = np.empty(STACK, np.int64)
    margin = 0.5 * THICKNESS
    steps = np.linspace(0.0, 0.02, 11)
    g.at_step(steps[0], steps[1])
    for s in range(ends.shape[0]):  # references at the first step's end
        segment_clearance(*bounds, clear, (0, s), meshes, ends[s], ends[s], margin, -1.0, stack)
        exact = _brute_segment_distance(ends[s, 0], ends[s, 1], g.vertex_end_m, faces, 1001)
        assert bounds.clearance_m[0, s] <= exact + 1e-12
    positive = 0
    for t0, t1 in zip(steps[1:-1], steps[2:]):
        g.at_step(t0, t1)
        moved = ends + rng.normal(0.0, 0.0003, ends.shape)
        for s in range(ends.shape[0]):
            # renewed when stale (the skip threshold out of reach), else as it was
            bound = segment_clearance(*bounds, clear, (0, s), meshes, ends[s], moved[s], margin, 1.0, stack)
            assert bound == segment_clearance_left(*bounds, clear, 0, s, ends[s], moved[s])
            for tau in (0.0, 0.5, 1.0):
                x = ends[s] + tau * (moved[s] - ends[s])
                v = g.vertex_start_m + tau * (g.vertex_end_m - g.vertex_start_m)
                assert bound <= _brute_segment_distance(x[0], x[1], v, faces, 401) + 1e-12
            positive += bound > 0.0
        ends = moved
    assert positive > 100


def test_a_bound_counts_the_whole_path_not_only_its_end():
    """A mass that went toward the surface and came back within the step: its path's start is nearer
    than its end, and the bound holds there too (a static ball: no travel)."""
    b = ModelBuilder(seed=1)
    _cloth(b, n=2)
    m = trimesh.creation.icosphere(subdivisions=3, radius=0.03)
    b.add_mesh("ball", vertices_m=m.vertices, triangles=m.faces)
    model = b.finalize()
    g = MeshGeometry(model)
    g.at_step(0.0, 1e-4)
    meshes = g.meshes_in(model)
    ref = np.array([0.0, 0.035, 0.0])
    clear = g.clearance
    clear.clearance_m[0, 0] = nearest_distance(0, meshes, ref, clear.reach_m, np.empty(STACK, np.int64), NO_LEAVES, -1)
    clear.reference_m[0, 0] = ref
    start = ref - (0.0, 0.003, 0.0)  # 3 mm nearer the ball
    bound = clearance_left(clear, 0, 0, *start, *ref)
    true_start = _brute_distance(start, np.asarray(m.vertices), np.asarray(m.faces))
    assert 0.0 < bound <= true_start


def _rising_model(kind: str):
    """Cloth falling onto a plate that rises into it (an animated mesh, keys, or a rigid one on a path),
    or onto a thin blade, edge up, rising between two yarns on a path (the yarn segments catch on its edge:
    the masses either side pass by it)."""
    b = ModelBuilder(seed=1)
    _cloth(b)
    # a pillar beside the cloth, its top over it: the mesh's box holds the cloth from the start, so its
    # masses take bounds while still far from the plate or the blade
    pillar = trimesh.creation.box(extents=(0.01, 0.08, 0.01))
    pillar.apply_translation((0.045, 0.037, 0.045))
    if kind == "ball":  # closed and smooth: no sharp edge; the cloth falls 5 mm onto its top and drapes
        ball = trimesh.creation.icosphere(subdivisions=3, radius=0.02)
        ball.apply_translation((0.0, -0.025, 0.0))
        both = trimesh.util.concatenate([ball, pillar])
        b.add_mesh("ball", vertices_m=np.asarray(both.vertices), triangles=np.asarray(both.faces), friction=0.5)
        return b.finalize()
    if kind == "blade":
        blade = trimesh.creation.box(extents=(0.0006, 0.02, 0.08))
        both = trimesh.util.concatenate([blade, pillar])
        b.add_mesh("blade", vertices_m=np.asarray(both.vertices), triangles=np.asarray(both.faces),
                   motion="kinematic", path=[(0.0, 0.0, -0.03, 0.0), (0.1, 0.0, 0.005, 0.0)])
        return b.finalize()
    plate = trimesh.creation.box(extents=(0.1, 0.006, 0.1))
    both = trimesh.util.concatenate([plate, pillar])
    v, f = np.asarray(both.vertices), np.asarray(both.faces)
    if kind == "path":
        b.add_mesh("plate", vertices_m=v, triangles=f, motion="kinematic",
                   path=[(0.0, 0.0, -0.03, 0.0), (0.1, 0.0, 0.005, 0.0)], friction=0.5)
    else:
        keys = np.stack([v + (0.0, y, 0.0) for y in (-0.03, 0.005, 0.005)])
        b.add_mesh("plate", vertices_m=keys, triangles=f, key_times_s=[0.0, 0.1, 0.2], motion="kinematic",
                   friction=0.5)
    return b.finalize()


def _run(model, clearance: bool, steps=700, dt=2e-4):
    """The run's end state, and whether masses' bounds and segments' own bounds were ever high enough to skip
    something (and, for the segments, to skip the corner test of a segment within the margin)."""
    state = model.state()
    solver = SolverExplicitPBD(model)
    g = solver.context.meshes
    contact = [s for s in solver.stages if hasattr(s, "segment_clearance")][0]
    if not clearance:  # a reach of 0: every bound is 0, nothing is ever skipped
        g.clearance = g.clearance._replace(reach_m=0.0)
    skipped = np.zeros(3, bool)
    margin = 0.5 * model.thickness_m
    for _ in range(steps):
        solver.step(state, dt)
        skipped[0] |= bool((g.clearance.clearance_m > 2.0 * SKIP_FACTOR * margin).any())
        own = contact.segment_clearance.clearance_m
        skipped[1] |= bool((own > 2.0 * SKIP_FACTOR * margin).any())
        skipped[2] |= bool(((own > 1e-5) & (own < margin)).any())
    return state, skipped


@pytest.mark.parametrize("kind", ["keys", "path", "blade", "ball"])
def test_skipping_cleared_masses_and_segments_changes_nothing(kind):
    model = _rising_model(kind)
    with_bounds, used = _run(model, clearance=True)
    without, unused = _run(model, clearance=False)
    assert used[0] and used[1] and not unused.any()
    if kind == "ball":  # segments at rest on it, under the margin, skip the corner test
        assert used[2]
    x = with_bounds.particle_position_m[:model.crossing_count]
    # the plate caught the cloth and lifted it, or the blade's edge holds it up, or the cloth lies on the
    # ball (contact happened, late in the run, after bounds were taken)
    if kind == "blade":
        assert x[:, 1].max() > 0.012
    elif kind == "ball":
        assert abs(x[:, 1].max() + 0.005) < 0.001 and x[:, 1].min() < -0.015  # on its top, hanging down
    else:
        assert x[:, 1].mean() > 0.006
    assert with_bounds.particle_position_m.tobytes() == without.particle_position_m.tobytes()
    assert with_bounds.particle_velocity_m_s.tobytes() == without.particle_velocity_m_s.tobytes()


def test_an_edge_push_does_not_hide_the_next_edge_behind_the_stale_query_box():
    """A segment pushed off one sharp edge toward another whose own box missed the pass's query box: the
    second edge is still tested in that pass, as when every edge of a met leaf was (the primitive boxes
    only save work, they never change a result)."""
    from fraytool.sim.kernels import mesh_bvh
    from fraytool.sim.kernels.bodies import BodiesIn
    from fraytool.sim.kernels.mesh_contact import MeshesIn, collide_mesh_segments

    mm = 1e-3
    v = np.array([[3.6, -0.2, -1.0], [3.6, -0.2, 1.0],   # under the segment, near its end
                  [3.9, 0.45, -1.0], [3.9, 0.45, 1.0],   # over it, outside the first query box
                  [-10, -10, -10], [10, 10, -10], [0, 10, 10]]) * mm
    edges = np.array([[0, 1], [2, 3]], np.int32)
    tris = np.array([[4, 5, 6]], np.int32)
    eb = mesh_bvh.build([v[edges].mean(axis=1)], [0], median=False)
    tb = mesh_bvh.build([v[tris].mean(axis=1)], [0])
    mesh_bvh.refit_mesh(eb, 0, edges, np.array([0, 2]), v, v)
    mesh_bvh.refit_mesh(tb, 0, tris, np.array([0, 1]), v, v)
    every = eb.box.copy()  # every edge's own box infinite: each edge of a met leaf is tested
    every[eb.child.shape[0]:, :3] = -np.inf
    every[eb.child.shape[0]:, 3:] = np.inf
    bodies = BodiesIn(np.zeros(1, np.int8), np.zeros((1, 3)), np.eye(3)[None].copy(), np.zeros(1), np.array([True]),
                      np.array([False]), np.zeros((1, 3)), np.zeros((1, 3)), np.zeros((1, 3)))
    start = np.array([[0.0, 0.0, 0.0], [4.0, 0.0, 0.0]]) * mm
    out = []
    for box in (eb.box, every):
        meshes = MeshesIn(np.array([0]), np.array([False]), tris, edges, v, v, tb.node_start, tb.child, tb.prim_range,
                          tb.box, tb.order, eb.node_start, eb.child, eb.prim_range, box, eb.order)
        x = start.copy()
        none = (empty_clearance(1, 2, np.zeros(1), 0.0), empty_segment_clearance(1, 1))  # no bounds: no skip
        hits = collide_mesh_segments(np.array([[0, 1, 0]], np.int64), np.ones((1, 1), np.bool_), meshes, bodies,
                                     0.4 * mm, 1e-4, np.array([1.0, 1.0]), start.copy(), x, none)
        out.append((hits, x))
    assert out[0][0] == out[1][0] > 0
    assert out[0][1].tobytes() == out[1][1].tobytes()


def _deepest_inside(points, normals, offsets):
    """How far [m] the deepest of `points` lies inside the convex solid {x: n_i . x <= o_i for all i} (negative:
    every point outside)."""
    return float(np.min(offsets[None, :] - points @ normals.T, axis=1).max())


def test_no_yarn_cuts_through_the_crease_of_a_faceted_drum():
    """Cloth draped over a 14-sided drum lying on its side: its creases turn by 25.7 degrees, under the sharp
    edges' 30, so only the corner test (mesh_contact._segment_through) keeps a yarn segment across a crease
    from cutting through it, 4 mm long over a 0.2 mm margin, with both ends outside. With the segments' own
    bounds skipping that test only for segments clear of the surface, no point of any yarn is inside."""
    sides, radius, length = 14, 0.02, 0.1
    drum = trimesh.creation.cylinder(radius=radius, height=length, sections=sides)  # axis along z
    b = ModelBuilder(seed=1)
    n, spacing = 16, 0.004
    half = 0.5 * (n - 1) * spacing
    b.add_cloth(warp_yarns=n, weft_yarns=n, spacing_m=spacing, thickness_m=0.0004, mass_per_crossing_kg=2e-5,
                structural_n_per_m=20.0, origin_m=(-half, radius + 0.002, -half))
    b.add_mesh("drum", vertices_m=np.asarray(drum.vertices), triangles=np.asarray(drum.faces), friction=0.3)
    model = b.finalize()
    state = model.state()
    solver = SolverExplicitPBD(model)
    for _ in range(1000):
        solver.step(state, 2e-4)
    # the drum's faces as half-spaces (its triangles' outward planes)
    tri = np.asarray(drum.vertices)[np.asarray(drum.faces)]
    normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    offsets = np.einsum("ij,ij->i", normals, tri[:, 0])
    x = state.particle_position_m
    segs = np.flatnonzero(((model.spring_kind == STRUCT_WEFT) | (model.spring_kind == STRUCT_WARP)) & state.spring_alive)
    a, c = x[state.spring_particle_a[segs]], x[state.spring_particle_b[segs]]
    along = np.linspace(0.0, 1.0, 41)
    points = (a[:, None, :] + along[None, :, None] * (c - a)[:, None, :]).reshape(-1, 3)
    assert x[:model.crossing_count, 1].min() < 0.5 * radius  # draped down both sides, over creases
    assert _deepest_inside(points, normals, offsets) < 0.0
