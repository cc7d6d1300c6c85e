"""Coarse cells against a mesh body (fraytool.sim.kernels.multires_mesh; docs/multires.md, "Against a
mesh"): cloth on a gently curved body stays coarse, cloth on a tight curve refines, and in both no
crossing ends below the surface by more than the contact margin. Checked with a brute-force signed
distance (every triangle, its face normal), not the kernels' trees; and with the test switched off, the
coarse cloth on the small ball does sink in (so the check can fail)."""
from __future__ import annotations

import numba as nb
import numpy as np
import pytest

from fraytool.geometry.triangles import closest_on_triangle
from fraytool.sim import multires
from fraytool.sim.builder import ModelBuilder
from fraytool.sim.solver import SolverExplicitPBD

trimesh = pytest.importorskip("trimesh")

THICKNESS = 0.0008
MARGIN = 0.5 * THICKNESS
SPACING = 0.004


@nb.njit(cache=True)
def _signed_distances(points, vertices, triangles, out):
    """Signed distance of each point from a closed mesh: the nearest of all triangles, the sign from its
    face normal (outward for a counter-clockwise winding seen from outside)."""
    for i in range(points.shape[0]):
        best, sign = np.inf, 1.0
        x = points[i]
        for j in range(triangles.shape[0]):
            a, b, c = vertices[triangles[j, 0]], vertices[triangles[j, 1]], vertices[triangles[j, 2]]
            qx, qy, qz, _, _, _ = closest_on_triangle(x[0], x[1], x[2], a[0], a[1], a[2], b[0], b[1], b[2],
                                                      c[0], c[1], c[2])
            d = np.sqrt((qx - x[0]) ** 2 + (qy - x[1]) ** 2 + (qz - x[2]) ** 2)
            if d < best:
                n = np.cross(b - a, c - a)
                best = d
                sign = 1.0 if (x[0] - qx) * n[0] + (x[1] - qy) * n[1] + (x[2] - qz) * n[2] >= 0.0 else -1.0
        out[i] = sign * best


def _drop_on_ball(radius_m: float, factor: int, steps: int = 700):
    """A 32 x 32 cloth at `factor` dropped flat onto the top of a static icosphere of radius_m (its top at
    y = 0), stepped `steps` times; returns (model, completed state, the sphere's vertices and faces)."""
    ball = trimesh.creation.icosphere(subdivisions=4, radius=radius_m)
    vertices = np.asarray(ball.vertices) - np.array([0.0, radius_m, 0.0])
    faces = np.asarray(ball.faces)
    b = ModelBuilder(seed=1, gravity_m_s2=(0.0, -9.81, 0.0))
    n = 32
    half = 0.5 * (n - 1) * SPACING
    b.add_cloth(warp_yarns=n, weft_yarns=n, spacing_m=SPACING, thickness_m=THICKNESS, mass_per_crossing_kg=2e-5,
                structural_n_per_m=20.0, bend_n_per_m=0.05, shear_n_per_m=1.0, origin_m=(-half, 0.002, -half))
    b.add_mesh("ball", vertices_m=vertices[None], triangles=faces, key_times_s=[0.0], friction=0.3)
    b.set_multires(factor=factor, band_cells=1)
    model = b.finalize()
    state, solver = model.state(), SolverExplicitPBD(model)
    for _ in range(steps):
        solver.step(state, 2e-4)
    solver.complete(state, 2e-4)
    return model, state, vertices, faces


def _depths(model, state, vertices, faces) -> np.ndarray:
    d = np.empty(model.crossing_count)
    _signed_distances(state.particle_position_m[:model.crossing_count], vertices, faces, d)
    return d


def test_cloth_resting_on_a_large_ball_stays_coarse_and_outside():
    """Radius 0.3 m under cells of 8 mm (factor 2): a cell's middle sags about D^2 / 4R = 0.1 mm, under
    the margin, so the cells on the ball rest on it through their nodes and stay coarse."""
    model, state, vertices, faces = _drop_on_ball(0.3, factor=2)
    lay = multires.coarse_layout(model)
    depth = _depths(model, state, vertices, faces)
    assert depth.min() > -MARGIN, depth.min()
    touching = depth < 3 * MARGIN
    assert touching.sum() > 100  # the cloth lies on the ball
    coarse = ~state.coarse_cell_refined
    slaved_touching = touching & ~multires.free_crossings(lay, state.coarse_cell_refined)
    assert coarse.sum() > 0.5 * coarse.size and slaved_touching.sum() > 50


def test_cloth_on_a_small_ball_refines_where_it_wraps_and_stays_outside():
    """Radius 0.02 m under cells of 16 mm (factor 4): a cell's middle would sag about 6 mm into it. The
    cells over the ball refine; no crossing ends below the surface by more than the margin."""
    model, state, vertices, faces = _drop_on_ball(0.02, factor=4)
    lay = multires.coarse_layout(model)
    depth = _depths(model, state, vertices, faces)
    assert depth.min() > -MARGIN, depth.min()
    near = depth < 3 * MARGIN
    free = multires.free_crossings(lay, state.coarse_cell_refined)
    assert near.sum() > 20 and free[near].all()
    assert (~state.coarse_cell_refined).any()  # the corners, away from the ball, are still coarse


def test_without_the_mesh_test_the_coarse_cloth_sinks_into_a_small_ball(monkeypatch):
    monkeypatch.setattr(multires.CoarseMeshTest, "mark", lambda *args: 0)  # at the start and every step
    model, state, vertices, faces = _drop_on_ball(0.02, factor=4)
    assert _depths(model, state, vertices, faces).min() < -4 * MARGIN


def test_mesh_contact_moves_no_segment_with_a_slaved_end():
    """The segment pass takes the yarn segments between free crossings only: one with a slaved end would be
    moved by its free end alone, with an unbounded lever near the slaved end."""
    from fraytool.sim.stages.mesh_contact import MeshContact

    model, state, _, _ = _drop_on_ball(0.3, factor=2, steps=5)
    solver = SolverExplicitPBD(model)
    stage = next(s for s in solver.stages if type(s) is MeshContact)
    solver.context.coarse.ensure(state)
    slaved = np.zeros(model.particle_count, bool)
    slaved[solver.context.slaved(state)] = True
    assert slaved.any()
    segments = stage.segments(state, solver.context)
    assert segments.shape[0] > 0 and not slaved[segments].any()


@pytest.mark.parametrize("moving", ["mesh", "cloth"], ids=["a ball rising into the cloth", "cloth falling on a ball"])
def test_the_distance_bounds_change_nothing(moving):
    """cells_on_meshes skips crossings and whole cells by their distance bounds (against their own or their
    nodes' moves, and the mesh's travel). A run with the bounds forgotten before every step (every slaved
    crossing queried) must refine the same cells at the same steps, bit for bit: with an animated ball rising
    into a still cloth (the travel), and with a cloth falling onto a still ball (the moves)."""
    import fraytool.sim.stages.multires as stages

    ball = trimesh.creation.icosphere(subdivisions=3, radius=0.03)
    v = np.asarray(ball.vertices)
    if moving == "mesh":
        keys, times, gravity = np.stack([v + np.array([0.0, -0.045 + 0.02 * k, 0.0]) for k in range(3)]), \
            [0.0, 0.05, 0.1], (0.0, 0.0, 0.0)
    else:
        keys, times, gravity = (v - np.array([0.0, 0.035, 0.0]))[None], [0.0], (0.0, -9.81, 0.0)
    runs = []
    for forget in (False, True):
        b = ModelBuilder(seed=1, gravity_m_s2=gravity)
        n = 25
        half = 0.5 * (n - 1) * SPACING
        b.add_cloth(warp_yarns=n, weft_yarns=n, spacing_m=SPACING, thickness_m=THICKNESS, mass_per_crossing_kg=2e-5,
                    structural_n_per_m=20.0, origin_m=(-half, 0.0, -half))
        b.add_mesh("ball", vertices_m=keys, triangles=np.asarray(ball.faces), key_times_s=times,
                   motion="kinematic" if moving == "mesh" else "static")
        b.set_multires(factor=4, band_cells=1)
        model = b.finalize()
        state, solver = model.state(), SolverExplicitPBD(model)
        refinement = next(s for s in solver.stages if type(s) is stages.Refinement)
        history = []
        for _ in range(400):
            if forget:
                refinement.mesh_test.bounds.value_m[:] = -np.inf
                refinement.mesh_test.bounds.group_value_m[:] = -np.inf
            solver.step(state, 2e-4)
            history.append(state.coarse_cell_refined.copy())
        runs.append((np.array(history), state.particle_position_m.copy()))
    (refined_a, x_a), (refined_b, x_b) = runs
    assert refined_a[0].sum() < refined_a[-1].sum() < refined_a[-1].size  # the ball refined some, not all
    assert np.array_equal(refined_a, refined_b)
    assert np.array_equal(x_a, x_b)


def _pierce(mesh, factor: int, at_m: tuple[float, float], steps: int = 300) -> tuple[float, int]:
    """A thin kinematic body (its axis along y, its top 2 mm under a still 32 x 32 cloth) rising 12 mm
    through the cloth's plane at (x, z): (the highest crossing [m], cells refined)."""
    vertices = np.asarray(mesh.vertices)[:, [0, 2, 1]]  # axis z -> y (and the winding kept outward)
    faces = np.asarray(mesh.faces)[:, [0, 2, 1]]
    top = vertices[:, 1].max()
    b = ModelBuilder(seed=1, gravity_m_s2=(0.0, 0.0, 0.0))
    n = 32
    half = 0.5 * (n - 1) * SPACING
    b.add_cloth(warp_yarns=n, weft_yarns=n, spacing_m=SPACING, thickness_m=THICKNESS, mass_per_crossing_kg=2e-5,
                structural_n_per_m=20.0, bend_n_per_m=0.05, shear_n_per_m=1.0, origin_m=(-half, 0.0, -half))
    b.add_mesh("thin", vertices_m=vertices[None], triangles=faces, key_times_s=[0.0], friction=0.3,
               motion="kinematic", position_m=(-half + at_m[0], -top - 0.002, -half + at_m[1]),
               velocity_m_s=(0.0, 0.2, 0.0))
    if factor > 1:
        b.set_multires(factor=factor, band_cells=1)
    model = b.finalize()
    state, solver = model.state(), SolverExplicitPBD(model)
    for _ in range(steps):
        solver.step(state, 2e-4)
    solver.complete(state, 2e-4)
    refined = int(state.coarse_cell_refined.sum()) if factor > 1 else 0
    return float(state.particle_position_m[:model.crossing_count, 1].max()), refined


@pytest.mark.parametrize("body", ["rod", "needle"])
def test_a_body_thinner_than_the_yarns_catches_coarse_cloth_as_it_catches_fine_cloth(body):
    """A smooth rod of radius 1.2 mm (no sharp edge: thin, so tested by distance) and a three-sided needle
    (sharp edges) 1 mm from a node rise between the crossings. At yarn resolution the yarn segments catch them
    and the cloth is lifted; at factor 2 the cells near them must refine and lift it as high (before, they
    went through coarse cloth: no crossing is ever inside such a body, and slaved segments are not tested)."""
    if body == "rod":
        mesh, at = trimesh.creation.capsule(height=0.03, radius=0.0012, count=[16, 16]), (14.5 * SPACING, 15 * SPACING)
    else:
        mesh, at = trimesh.creation.cylinder(radius=0.0003, height=0.03, sections=3), (14 * SPACING + 0.001, 16 * SPACING)
    fine, _ = _pierce(mesh, 1, at)
    coarse, refined = _pierce(mesh, 2, at)
    assert fine > 0.004  # lifted by the body at yarn resolution
    assert refined > 0 and coarse > fine - 0.001
