"""Mesh contact pinned by what it does, so a small wrong change of a constant or a branch fails a figure
(docs/testing.md "magnitude"): the exact resting margin, the sharp-edge angle on either side of it, an
open mesh's border as a sharp edge, the most face-on of equally near triangles, a sequence whose files
renumber their triangles, and the broad phase of a mesh that moves fast between two keys."""
from __future__ import annotations

import math

import numpy as np
import pytest

from fraytool.meshes import SHARP_DEG
from fraytool.scene.mesh_files import MeshFileError, read_asset, sharp_edges
from fraytool.sim.builder import ModelBuilder

pytestmark = pytest.mark.fast

from test_mesh_bodies import THICKNESS  # noqa: E402  (the mesh tests' cloth and stepping)
from test_mesh_bodies import _cloth as _mesh_cloth  # noqa: E402
from test_mesh_bodies import _run as _mesh_run  # noqa: E402


def _cloth(builder, n=8, spacing=0.004, y=0.0):
    _mesh_cloth(builder, n=n, spacing=spacing, y=y)


def _run(model, steps, dt=2e-4):
    """The crossings' positions after `steps` steps."""
    return _mesh_run(model, steps, dt).particle_position_m[:model.crossing_count]


SHEET_V = np.array([[-0.1, 0, -0.1], [0.1, 0, -0.1], [0.1, 0, 0.1], [-0.1, 0, 0.1]], float)
SHEET_F = np.array([[0, 2, 1], [0, 3, 2]])


@pytest.mark.parametrize("kind", ["open sheet", "closed box"])
def test_a_cloth_rests_half_a_thickness_above_a_mesh_exactly(kind):
    """Contact keeps a mass `margin` = half the yarn thickness off the surface: on a flat face the resting
    height is that margin to a part in a thousand (a margin 5 % off moves it by 2.5 % of it)."""
    b = ModelBuilder(seed=1)
    _cloth(b, y=0.002)
    if kind == "open sheet":
        b.add_mesh("floor", vertices_m=SHEET_V, triangles=SHEET_F)
        top = 0.0
    else:
        import trimesh

        box = trimesh.creation.box(extents=(0.2, 0.02, 0.2))
        b.add_mesh("floor", vertices_m=box.vertices, triangles=box.faces, position_m=(0.0, -0.01, 0.0))
        top = 0.0
    x = _run(b.finalize(), 400)
    height = x[:, 1] - top
    assert np.abs(height - 0.5 * THICKNESS).max() < 1e-3 * 0.5 * THICKNESS, (height.min(), height.max())


def _hinge(angle_deg: float):
    """Two triangles sharing the edge (0,0,0)-(0,0,1): one in the plane y = 0 (x < 0... as a flat floor), the
    other turned up about the edge by `angle_deg` (their normals differ by that much)."""
    a = math.radians(angle_deg)
    v = np.array([[0, 0, 0], [0, 0, 1], [-1, 0, 0.5], [math.cos(a), math.sin(a), 0.5]], float)
    f = np.array([[0, 2, 1], [0, 1, 3]])  # both normals +y when flat, consistently oriented across the edge
    return v, f


@pytest.mark.parametrize("delta", [-0.2, 0.2])
def test_the_sharp_edge_angle_is_thirty_degrees_on_either_side(delta):
    v, f = _hinge(SHARP_DEG + delta)
    n = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    n /= np.linalg.norm(n, axis=1)[:, None]
    turn = math.degrees(math.acos(float(n[0] @ n[1])))
    assert turn == pytest.approx(30.0 + delta, abs=1e-9)  # the geometry is what the test says
    edges = {tuple(sorted(e)) for e in sharp_edges(v, f).tolist()}
    assert ((0, 1) in edges) == (delta > 0)
    v, f = _hinge(30.0 + delta)
    assert (((0, 1) in {tuple(sorted(e)) for e in sharp_edges(v, f).tolist()}) == (delta > 0))


def test_an_open_meshs_border_edges_are_sharp():
    """The four border edges of a flat two-triangle sheet are sharp (yarns catch on them); its diagonal, with
    two coplanar faces, is not."""
    edges = {tuple(sorted(e)) for e in sharp_edges(SHEET_V, SHEET_F).tolist()}
    assert edges == {(0, 1), (1, 2), (2, 3), (0, 3)}


def test_a_sequence_whose_files_renumber_their_triangles_is_refused(tmp_path):
    """Same vertex and triangle counts, but the second file's triangles join other vertices: not one topology."""
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 0, 1], [0, 0, 1]], float)
    for k, faces in enumerate(([[1, 2, 3], [1, 3, 4]], [[1, 2, 4], [2, 3, 4]]), start=1):
        lines = [f"v {a} {b} {c}" for a, b, c in v] + [f"f {a} {b} {c}" for a, b, c in faces]
        (tmp_path / f"m.{k:04d}.obj").write_text("\n".join(lines) + "\n")
    with pytest.raises(MeshFileError, match="topology differs"):
        read_asset(tmp_path / "m.####.obj", frame_time_s=0.1)


def _wedge(half_angle_deg=20.0, length=0.2, depth=0.1):
    """A closed triangular prism whose sharp edge (the tip) runs along z through the origin; the solid lies
    towards -x between the planes through the tip at +-half_angle."""
    a = math.radians(half_angle_deg)
    top, bot = np.array([-depth, depth * math.tan(a)]), np.array([-depth, -depth * math.tan(a)])
    v = []
    for z in (-0.5 * length, 0.5 * length):
        v += [[0.0, 0.0, z], [top[0], top[1], z], [bot[0], bot[1], z]]
    faces = np.array([[0, 1, 2], [3, 5, 4], [0, 3, 4], [0, 4, 1], [0, 2, 5], [0, 5, 3], [1, 4, 5], [1, 5, 2]])
    return np.array(v), faces  # consistently wound: fraytool turns a closed mesh's normals outward


def test_a_mass_beside_a_sharp_tip_is_outside_by_the_most_face_on_triangle():
    """A mass just off the wedge's tip, above the upper face's plane and below the lower face's: both faces are
    equally near (the tip), the upper one the more face-on, which says outside (Baerentzen & Aanaes 2005). It is
    pushed out to the margin from the tip; taken by the other face it would be judged inside and pulled in."""
    b = ModelBuilder(seed=1, gravity_m_s2=(0.0, 0.0, 0.0))
    d = 0.3 * THICKNESS  # within the margin (0.5 thickness) of the tip
    start = d * np.array([math.cos(math.radians(45.0)), math.sin(math.radians(45.0)), 0.0])
    b.add_cloth(warp_yarns=2, weft_yarns=2, spacing_m=0.004, thickness_m=THICKNESS, mass_per_crossing_kg=2e-5,
                structural_n_per_m=20.0, origin_m=tuple(start), plane="xy")
    v, f = _wedge()
    b.add_mesh("wedge", vertices_m=v, triangles=f)
    x = _run(b.finalize(), 1)
    moved = x[0]
    assert np.linalg.norm(moved[:2]) == pytest.approx(0.5 * THICKNESS, rel=1e-6)  # at the margin from the tip
    assert moved[0] > 0 and moved[1] > 0  # on the side it started: outside


def test_a_mesh_moving_fast_between_two_keys_is_found_between_them():
    """A slab keyed 6 cm below the cloth and 6 cm above it 0.04 s later passes the cloth half way between its
    keys: the broad phase must hold the triangles over the whole interval, or the slab goes through."""
    import trimesh

    b = ModelBuilder(seed=1, gravity_m_s2=(0.0, 0.0, 0.0))
    _cloth(b, n=6)
    slab = trimesh.creation.box(extents=(0.1, 0.01, 0.1))
    keys = np.stack([slab.vertices + (0.0, -0.06, 0.0), slab.vertices + (0.0, 0.06, 0.0)])
    b.add_mesh("slab", vertices_m=keys, triangles=slab.faces, key_times_s=(0.0, 0.04))
    x = _run(b.finalize(), 250)  # 0.05 s: past the second key
    assert x[:, 1].min() > 0.06 + 0.005  # carried up on the slab's top face


def _slope(kind, friction=0.4, angle_deg=30.0, steps=1500):
    """A small cloth lying on a 30 degree slope with friction 0.4 slides down it (tan 30 > 0.4): an analytic
    plane, or the same plane as a two-triangle mesh sheet. Returns how far it slid along the slope [m]."""
    a = math.radians(angle_deg)
    normal = np.array([math.sin(a), math.cos(a), 0.0])
    down = np.array([math.cos(a), -math.sin(a), 0.0])  # along the slope
    side = np.array([0.0, 0.0, 1.0])
    b = ModelBuilder(seed=1)
    corner = 0.5 * THICKNESS * normal - 0.006 * down - 0.006 * side
    b.add_cloth(warp_yarns=4, weft_yarns=4, spacing_m=0.004, thickness_m=THICKNESS, mass_per_crossing_kg=2e-5,
                structural_n_per_m=20.0, origin_m=tuple(corner), rotation_deg=(0.0, 0.0, -angle_deg))
    if kind == "plane":
        b.add_plane("slope", normal=tuple(normal), friction=friction)
    else:
        corners = np.array([0.5 * (u * down + w * side) for u, w in ((-1, -1), (1, -1), (1, 1), (-1, 1))])
        f = np.array([[0, 2, 1], [0, 3, 2]])
        if np.cross(corners[f[0, 1]] - corners[f[0, 0]], corners[f[0, 2]] - corners[f[0, 0]]) @ normal < 0:
            f = f[:, [0, 2, 1]]
        b.add_mesh("slope", vertices_m=corners, triangles=f, friction=friction)
    model = b.finalize()
    start = model.crossing_rest_position_m.mean(axis=0)
    np.testing.assert_allclose(model.crossing_rest_position_m @ normal, 0.5 * THICKNESS, atol=1e-12)  # on it
    x = _run(model, steps)
    return float((x.mean(axis=0) - start) @ down)


def test_friction_on_a_mesh_slope_is_the_analytic_planes():
    """Sliding down a slope, the same friction law on a mesh as on the analytic plane: the distance slid over
    0.3 s agrees to 2 % (friction 10 % weaker on the mesh slides about 20 % further)."""
    slid_plane, slid_mesh = _slope("plane"), _slope("mesh")
    assert slid_plane > 0.02  # it slid (about 7 cm without friction, a few cm with it)
    assert slid_mesh == pytest.approx(slid_plane, rel=0.02)
    frictionless = _slope("mesh", friction=0.0)
    assert frictionless > 1.5 * slid_mesh  # the friction is doing something


def test_a_mass_in_a_concave_corner_is_pushed_off_both_faces():
    """A mass 0.3 thickness from a floor and from a wall meeting at a right angle: the first pass pushes it off
    one face, still within the margin of the other; the next pass pushes it off that one too."""
    b = ModelBuilder(seed=1, gravity_m_s2=(0.0, 0.0, 0.0))
    near = 0.3 * THICKNESS
    b.add_cloth(warp_yarns=2, weft_yarns=2, spacing_m=0.004, thickness_m=THICKNESS, mass_per_crossing_kg=2e-5,
                structural_n_per_m=20.0, origin_m=(near, near, 0.0))
    v = np.array([[0, 0, -0.1], [0.1, 0, -0.1], [0.1, 0, 0.1], [0, 0, 0.1],          # the floor, y = 0
                  [0, 0.1, -0.1], [0, 0.1, 0.1]], float)                             # the wall, x = 0
    f = np.array([[0, 2, 1], [0, 3, 2], [0, 4, 5], [0, 5, 3]])
    b.add_mesh("corner", vertices_m=v, triangles=f)
    x = _run(b.finalize(), 1)
    assert x[0, 0] >= 0.5 * THICKNESS * (1 - 1e-6) and x[0, 1] >= 0.5 * THICKNESS * (1 - 1e-6), x[0] / THICKNESS


def test_an_animated_mesh_is_interpolated_between_the_keys_around_each_time():
    """Keys at 0, 1 and 3 s moving a triangle by 0, 1 and 5 cm in x: at any time the vertices are the linear
    interpolation of the two keys around it, held before the first and after the last."""
    from fraytool.meshes import MeshTable

    tri = np.array([[0.0, 0, 0], [0.01, 0, 0], [0, 0, 0.01]])
    keys = np.stack([tri + (dx, 0, 0) for dx in (0.0, 0.01, 0.05)])
    b = ModelBuilder(seed=1)
    _cloth(b, n=2)
    b.add_mesh("m", vertices_m=keys, triangles=[[0, 1, 2]], key_times_s=(0.0, 1.0, 3.0))
    table = MeshTable(b.finalize())
    for time_s, dx in ((-1.0, 0.0), (0.5, 0.005), (1.0, 0.01), (2.0, 0.03), (2.5, 0.04), (4.0, 0.05)):
        np.testing.assert_allclose(table.vertices_at(0, time_s), tri + (dx, 0, 0), atol=1e-15, err_msg=str(time_s))


def test_the_builder_refuses_a_non_finite_vertex_in_arrays():
    from fraytool.sim.builder import ModelBuilderError

    b = ModelBuilder(seed=1)
    _cloth(b, n=2)
    v = SHEET_V.copy()
    v[2, 1] = np.nan
    with pytest.raises(ModelBuilderError, match="vertex 2 is not finite"):
        b.add_mesh("m", vertices_m=v, triangles=SHEET_F)
