"""Mesh bodies (docs/meshes.md): files through trimesh and USD, contact validated against the analytic
bodies, animated meshes, sharp edges, bad input."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from fraytool.meshes import MeshTable
from fraytool.scene.mesh_files import MeshFileError, read_asset
from fraytool.sim.builder import ModelBuilder, ModelBuilderError
from fraytool.sim.solver import SolverExplicitPBD

trimesh = pytest.importorskip("trimesh")  # a dependency (pyproject.toml): present wherever fraytool is installed

THICKNESS = 0.0008


def _cloth(builder, n=24, spacing=0.004, y=0.0):
    half = 0.5 * (n - 1) * spacing
    builder.add_cloth(warp_yarns=n, weft_yarns=n, spacing_m=spacing, thickness_m=THICKNESS,
                      mass_per_crossing_kg=2e-5, structural_n_per_m=20.0, origin_m=(-half, y, -half))


def _run(model, steps, dt=2e-4):
    state = model.state()
    solver = SolverExplicitPBD(model)
    for _ in range(steps):
        solver.step(state, dt)
    solver.complete(state, dt)
    return state


def _drop(kind, collide=True, steps=900):
    b = ModelBuilder(seed=1)
    _cloth(b)
    centre = (0.0, -0.045, 0.0)
    if kind == "sphere":
        b.add_sphere("ball", radius_m=0.04, position_m=centre, collide=collide)
    else:
        m = trimesh.creation.icosphere(subdivisions=5, radius=0.04)
        b.add_mesh("ball", vertices_m=m.vertices, triangles=m.faces, position_m=centre, collide=collide)
    model = b.finalize()
    return model, _run(model, steps).particle_position_m[:model.crossing_count]


def test_cloth_on_a_fine_sphere_mesh_ends_within_a_thickness_of_the_analytic_sphere():
    _, analytic = _drop("sphere")
    _, mesh = _drop("mesh")
    # the cloth lies on the ball (it did not fall through)...
    assert np.linalg.norm(analytic - (0.0, -0.045, 0.0), axis=1).min() > 0.04
    # ...and on the mesh as on the analytic sphere, mass by mass
    assert np.abs(mesh - analytic).max() < THICKNESS
    # the icosphere's faces lie inside the sphere (by up to 0.02 mm at 5 subdivisions): no mass in the mesh
    assert np.linalg.norm(mesh - (0.0, -0.045, 0.0), axis=1).min() > 0.04 - 0.0001


def test_without_contact_the_cloth_falls_through_the_sphere_mesh():
    _, mesh = _drop("mesh", collide=False, steps=900)
    _, analytic = _drop("sphere", steps=900)
    assert np.abs(mesh - analytic).max() > 10 * THICKNESS


def _disk(turn_deg_per_s, keys=9, duration=0.4, radius=0.06):
    """A closed flat cylinder (a turntable) as keys of an animated mesh turning about y."""
    base = trimesh.creation.cylinder(radius=radius, height=0.01, sections=48)
    v = np.asarray(base.vertices)[:, [0, 2, 1]]  # axis z -> y
    f = np.asarray(base.faces)[:, [0, 2, 1]]     # the swap mirrors: keep the normals outward
    times = np.linspace(0.0, duration, keys)
    frames = []
    for t in times:
        a = np.radians(turn_deg_per_s * t)
        rot = np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])
        frames.append(v @ rot.T)
    return np.stack(frames), f, times


def _turntable(friction, turn_deg_per_s=90.0, steps=2000):
    b = ModelBuilder(seed=1)
    _cloth(b, n=12, y=0.0055)
    v, f, times = _disk(turn_deg_per_s)
    b.add_mesh("disk", vertices_m=v, triangles=f, key_times_s=times, friction=friction, motion="kinematic")
    model = b.finalize()
    state = _run(model, steps)
    x = state.particle_position_m[:model.crossing_count]
    rest = model.crossing_rest_position_m
    # the cloth's turn about y: the mean angle of the masses from their rest direction
    a0 = np.arctan2(rest[:, 0], rest[:, 2])
    a1 = np.arctan2(x[:, 0], x[:, 2])
    far = np.hypot(rest[:, 0], rest[:, 2]) > 0.01
    turned = np.degrees(np.angle(np.exp(1j * (a1 - a0))[far].mean()))
    return turned, x


def test_cloth_on_a_turning_mesh_disk_turns_with_it_by_friction():
    """An animated mesh (keys, as a sequence gives) carries the cloth by friction, as a moving analytic box
    carries it along (test_box_carries_...); with no friction the disk turns under the cloth."""
    turned, x = _turntable(friction=1.0)
    disk_turn = 90.0 * 2000 * 2e-4  # degrees at the end
    assert abs(turned - disk_turn) < 0.15 * disk_turn
    assert x[:, 1].min() > 0.005  # on the disk, not in it
    slipped, _ = _turntable(friction=0.0)
    assert abs(slipped) < 0.15 * disk_turn


def _slab(kind, friction=0.8):
    """The cloth on a slab that moves sideways along a path: a box, or the same box as a mesh."""
    b = ModelBuilder(seed=1)
    _cloth(b, n=12, y=0.0055)
    path = [(0.0, 0.0, 0.0, 0.0), (0.3, 0.03, 0.0, 0.0)]
    if kind == "box":
        b.add_box("slab", half_extents_m=(0.05, 0.005, 0.05), motion="kinematic", path=path, friction=friction)
    else:
        box = trimesh.creation.box(extents=(0.1, 0.01, 0.1))
        b.add_mesh("slab", vertices_m=box.vertices, triangles=box.faces, motion="kinematic", path=path,
                   friction=friction)
    model = b.finalize()
    return _run(model, 1500).particle_position_m[:model.crossing_count]


def test_mesh_slab_carries_the_cloth_as_the_analytic_box_does():
    box, mesh = _slab("box"), _slab("mesh")
    assert box[:, 0].mean() > 0.015  # the box carried the cloth
    assert np.abs(mesh - box).max() < THICKNESS


def _blade(collide=True):
    """A thin mesh blade (0.6 mm, under the 4 mm yarn spacing and under two margins) cuts down edge first
    at 2.75 m/s (0.55 mm a step, more than the 0.4 mm contact margin) into a cloth held at its four edges,
    1.5 cm deep (a 5 % stretch, within the strain limit)."""
    b = ModelBuilder(seed=1)
    _cloth(b, n=24)
    blade = trimesh.creation.box(extents=(0.06, 0.04, 0.0006))
    b.add_mesh("blade", vertices_m=blade.vertices, triangles=blade.faces, motion="kinematic",
               path=[(0.0, 0.0, 0.04, 0.001), (0.02, 0.0, -0.015, 0.001)], collide=collide)
    b.add_sphere("holder", radius_m=0.001, position_m=(0.0, 0.0, 0.0), collide=False)
    for edge in ("left", "right", "top", "bottom"):
        b.add_attachment("holder", edge=edge)
    model = b.finalize()
    return model, _run(model, 150)


def _through_blade(model, state):
    """Yarn segments crossing the blade's middle plane z = 0.001 inside the blade (above its bottom edge,
    y = -0.035 at the end, by more than the contact margin; within its length): the blade lies between
    their masses. A segment draped under the edge crosses the plane below it."""
    x = state.particle_position_m
    a, b = model.spring_crossing_a, model.spring_crossing_b
    s = np.flatnonzero(model.spring_kind <= 1)
    za, zb = x[a[s], 2] - 0.001, x[b[s], 2] - 0.001
    across = za * zb < 0
    w = za[across] / (za[across] - zb[across])
    y = x[a[s][across], 1] + w * (x[b[s][across], 1] - x[a[s][across], 1])
    xc = x[a[s][across], 0] + w * (x[b[s][across], 0] - x[a[s][across], 0])
    return int(((y > -0.035 + 0.5 * THICKNESS) & (y < 0.005) & (np.abs(xc) < 0.03)).sum())


def test_a_thin_fast_mesh_blade_does_not_pass_through_the_cloth():
    model, state = _blade()
    assert state.particle_position_m[:model.crossing_count, 1].min() < -0.035  # the cloth went down with it
    assert _through_blade(model, state) == 0
    model, state = _blade(collide=False)
    assert _through_blade(model, state) > 10  # without contact it cuts straight through the yarns


def test_open_sheet_is_two_sided():
    """A single-sided open sheet (one triangle pair) stops the cloth from above like a floor."""
    b = ModelBuilder(seed=1)
    _cloth(b, n=8, y=0.002)
    v = np.array([[-0.1, 0, -0.1], [0.1, 0, -0.1], [0.1, 0, 0.1], [-0.1, 0, 0.1]])
    f = np.array([[0, 2, 1], [0, 3, 2]])  # normal -y: the cloth lands on its back side
    b.add_mesh("sheet", vertices_m=v, triangles=f)
    model = b.finalize()
    assert not model.mesh_closed[0]
    x = _run(model, 600).particle_position_m[:model.crossing_count]
    assert x[:, 1].min() > 0.5 * THICKNESS * 0.99


@pytest.mark.parametrize("suffix", [".obj", ".ply", ".stl", ".glb"])
def test_mesh_files_read_through_trimesh(tmp_path, suffix):
    box = trimesh.creation.box(extents=(0.2, 0.1, 0.3))
    path = tmp_path / f"box{suffix}"
    box.export(path)
    asset = read_asset(path)
    assert asset.closed
    assert asset.triangles.shape[0] == 12
    v = asset.key_vertices[0]
    assert np.allclose(v.max(axis=0) - v.min(axis=0), (0.2, 0.1, 0.3))
    assert asset.sharp_edges.shape[0] == 12  # the box's edges; the faces' diagonals are flat

def test_sequence_is_read_as_keys_and_interpolated(tmp_path):
    box = trimesh.creation.box(extents=(0.1, 0.1, 0.1))
    for k in range(3):
        moved = box.copy()
        moved.apply_translation((0.01 * k, 0, 0))
        moved.export(tmp_path / f"walk.{k + 1:04d}.obj")
    asset = read_asset(tmp_path / "walk.####.obj", frame_time_s=0.5)
    assert asset.key_vertices.shape[0] == 3
    assert np.allclose(asset.key_time_s, (0.0, 0.5, 1.0))
    b = ModelBuilder(seed=1)
    _cloth(b, n=4)
    b.add_mesh("walker", file=str(tmp_path / "walk.####.obj"), frame_time_s=0.5, position_m=(0, -0.2, 0))
    table = MeshTable(b.finalize())
    mid = table.vertices_at(0, 0.25).mean(axis=0)
    assert mid[0] == pytest.approx(0.005, abs=1e-12)


def test_usd_mesh_points_per_time_sample(tmp_path):
    pytest.importorskip("pxr")  # the usd extra (CI installs it)
    from pxr import Usd, UsdGeom

    path = tmp_path / "char.usda"
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageMetersPerUnit(stage, 0.01)  # centimetres
    stage.SetTimeCodesPerSecond(24)
    mesh = UsdGeom.Mesh.Define(stage, "/Root/Body")
    box = trimesh.creation.box(extents=(10, 10, 10))
    mesh.CreateFaceVertexCountsAttr([3] * len(box.faces))
    mesh.CreateFaceVertexIndicesAttr(box.faces.ravel().tolist())
    for t in (1, 25):
        mesh.GetPointsAttr().Set([tuple(p + (t - 1) * np.array([1.0, 0, 0])) for p in box.vertices], t)
    stage.GetRootLayer().Save()
    asset = read_asset(path, "/Root/Body")
    assert np.allclose(asset.key_time_s, (0.0, 1.0))
    assert np.allclose(asset.key_vertices[1].mean(axis=0) - asset.key_vertices[0].mean(axis=0), (0.24, 0, 0))
    assert np.allclose(np.ptp(asset.key_vertices[0], axis=0), 0.1)
    with pytest.raises(MeshFileError, match="/Root/Body"):
        read_asset(path, "/Root/Nothing")


SCENE = """
[time]
step_s = 0.0002
steps_per_frame = 2
frames = 2
[cloth]
warp_yarns = 4
weft_yarns = 4
spacing_m = 0.004
thickness_m = 0.0008
mass_per_crossing_kg = 2e-5
[cloth.springs]
structural_n_per_m = 20.0
[[bodies]]
name = "thing"
shape = "mesh"
file = "{file}"
position_m = [0.0, -0.1, 0.0]
"""


def _bad(tmp_path, file, *extra_args, env=None):
    scene = tmp_path / "s.toml"
    scene.write_text(SCENE.format(file=file))
    out = tmp_path / "out"
    r = subprocess.run([sys.executable, "-m", "fraytool", "simulate", str(scene), "-o", str(out), *extra_args],
                       capture_output=True, text=True, env=env)
    return r, out


def _write_obj(path, vertices, faces):
    with open(path, "w") as h:
        for v in vertices:
            h.write("v " + " ".join(str(c) for c in v) + "\n")
        for f in faces:
            h.write("f " + " ".join(str(i + 1) for i in f) + "\n")


@pytest.mark.parametrize("case, expect", [
    ("missing", "not found"),
    ("empty", "no triangles"),
    ("nan", "not finite"),
    ("garbage", "cannot read as a mesh"),
    ("topology", "topology differs"),
    ("gap", "frame 2 is missing"),
    ("kind", "unknown mesh file kind"),
])
def test_bad_mesh_input_is_one_line_exit_2_nothing_written(tmp_path, case, expect):
    tri = [(0, 1, 2), (0, 2, 3)]
    quad = [(0, 0, 0), (1, 0, 0), (1, 0, 1), (0, 0, 1)]
    file = "m.obj"
    if case == "empty":
        (tmp_path / "m.obj").write_text("# nothing\nv 0 0 0\n")
    elif case == "nan":
        _write_obj(tmp_path / "m.obj", [(0, 0, 0), (1, 0, 0), (1, float("nan"), 1), (0, 0, 1)], tri)
    elif case == "garbage":
        (tmp_path / "m.glb").write_bytes(b"glTF\x02\x00\x00\x00garbage")
        file = "m.glb"
    elif case in ("topology", "gap"):
        _write_obj(tmp_path / "m.0001.obj", quad, tri)
        if case == "topology":
            _write_obj(tmp_path / "m.0002.obj", quad, tri[:1])
        else:
            _write_obj(tmp_path / "m.0003.obj", quad, tri)
        file = "m.####.obj"
    elif case == "kind":
        (tmp_path / "m.xyz").write_text("1 2 3\n")
        file = "m.xyz"
    r, out = _bad(tmp_path, file)
    assert r.returncode == 2, r.stderr
    lines = [ln for ln in r.stderr.strip().splitlines() if ln.strip()]
    assert len(lines) == 1, r.stderr
    assert expect in lines[0] and "s.toml" in lines[0]
    assert not out.exists()


def test_mesh_too_large_for_memory_is_refused_unless_forced(tmp_path):
    import os

    box = trimesh.creation.box(extents=(0.1, 0.1, 0.1))
    box.export(tmp_path / "m.obj")
    env = dict(os.environ, FRAYTOOL_AVAILABLE_MEMORY_BYTES=str(300 * 2**20))
    (tmp_path / "m.obj").write_text((tmp_path / "m.obj").read_text() + "# " + "x" * (30 * 2**20) + "\n")
    r, out = _bad(tmp_path, "m.obj", env=env)
    assert r.returncode == 2 and "meshes need about" in r.stderr and "--force" in r.stderr
    assert not out.exists()
    r, out = _bad(tmp_path, "m.obj", "--force", env=env)
    assert r.returncode == 0, r.stderr


def test_builder_refuses_dynamic_mesh_and_missing_geometry():
    b = ModelBuilder(seed=1)
    with pytest.raises(ModelBuilderError, match="either file or vertices_m"):
        b.add_mesh("m")
    box = trimesh.creation.box(extents=(0.1, 0.1, 0.1))
    with pytest.raises(ModelBuilderError, match="static.*kinematic"):
        b.add_mesh("m", vertices_m=box.vertices, triangles=box.faces, motion="dynamic")


def _sequence_scene(tmp_path):
    """golden_small's cloth over a box that moves in x, given as a 3-file OBJ sequence (one per frame)."""
    for k in range(3):
        box = trimesh.creation.box(extents=(0.06, 0.03, 0.06))
        box.apply_translation((0.01 * k, 0.0, 0.0))
        box.export(tmp_path / f"slab.{k:03d}.obj")
    text = (Path(__file__).resolve().parent / "scenes" / "golden_small.toml").read_text()
    text = text.replace('shape = "sphere"\nradius_m = 0.035', 'shape = "mesh"\nfile = "slab.###.obj"')
    assert 'file = "slab.###.obj"' in text
    scene = tmp_path / "slab.toml"
    scene.write_text(text)
    return scene


def test_animated_mesh_is_drawn_where_it_is_and_exported_time_sampled(tmp_path, capsys):
    """The renderer draws an animated mesh body at the frame's time (the box's bright pixels move right),
    and the USD export carries its points per frame, as the keys say."""
    from PIL import Image

    from fraytool.commands.main import main

    scene = _sequence_scene(tmp_path)
    out = tmp_path / "out"
    assert main(["render", str(scene), "-o", str(out), "--png", "--no-mp4", "--frames", "0:3"]) == 0
    frames = [np.asarray(Image.open(out / "png" / f"frame_{k:06d}.png").convert("L"), float) for k in (0, 2)]
    assert np.abs(frames[1] - frames[0]).mean() > 1.0  # the box moved (the cloth barely, in 2 frames)
    pytest.importorskip("pxr")
    from pxr import Usd, UsdGeom

    usd = tmp_path / "shot.usda"
    assert main(["export", str(scene), "--usd", str(usd), "-o", str(out)]) == 0
    stage = Usd.Stage.Open(str(usd))
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath(stage.GetDefaultPrim().GetPath().AppendPath("Bodies/ball")))
    assert mesh and len(mesh.GetFaceVertexCountsAttr().Get()) == 12
    samples = mesh.GetPointsAttr().GetTimeSamples()
    assert samples == [0.0, 1.0, 2.0, 3.0]
    shift = np.array(mesh.GetPointsAttr().Get(2)).mean(axis=0) - np.array(mesh.GetPointsAttr().Get(0)).mean(axis=0)
    np.testing.assert_allclose(shift, (0.02, 0.0, 0.0), atol=1e-6)  # file 2 is 2 cm to the right of file 0


def test_mesh_distances_and_placement_against_the_sphere_they_tessellate():
    """mesh_distances (the woven-strain figure's 'near a body') and place_outside_meshes (a split's masses
    placed out of a mesh) against the analytic distance to the sphere the icosphere approximates."""
    from fraytool.sim.kernels.bodies import bodies_in
    from fraytool.sim.kernels.mesh_contact import mesh_distances, place_outside_meshes
    from fraytool.sim.mesh_geometry import MeshGeometry

    b = ModelBuilder(seed=1)
    _cloth(b, n=4)
    ball = trimesh.creation.icosphere(subdivisions=5, radius=0.04)
    b.add_mesh("ball", vertices_m=ball.vertices, triangles=ball.faces, position_m=(0.1, 0.0, 0.0))
    model = b.finalize()
    state = model.state()
    geometry = MeshGeometry(model)
    rng = np.random.default_rng(0)
    direction = rng.normal(size=(200, 3))
    direction /= np.linalg.norm(direction, axis=1)[:, None]
    radius = rng.uniform(0.0405, 0.05, 200)
    x = (0.1, 0.0, 0.0) + direction * radius[:, None]
    d = np.empty(200)
    mesh_distances(0, geometry.meshes_in(model), bodies_in(model, state), 0.02, x, d)
    assert np.abs(d - (radius - 0.04)).max() < 3e-5  # facets lie within 0.02 mm inside the sphere
    mesh_distances(0, geometry.meshes_in(model), bodies_in(model, state), 0.005, x, d)
    assert np.isinf(d[radius - 0.04 > 0.0051]).all()  # beyond the reach: inf
    inside = (0.1, 0.0, 0.0) + direction * 0.0398  # 0.2 mm inside the surface
    place_outside_meshes(geometry.meshes_in(model), bodies_in(model, state), 0.0004, np.arange(200),
                         np.ones(200), inside)
    r = np.linalg.norm(inside - (0.1, 0.0, 0.0), axis=1)
    assert np.abs(r - 0.0404).max() < 3e-5


def test_shipped_mesh_scene_finds_its_asset_from_any_folder(tmp_path):
    """A shipped scene named by its name (not a path), with an override, resolves its mesh file beside the
    scene file."""
    r = subprocess.run([sys.executable, "-m", "fraytool", "check", "mannequin_snag", "--set", "scene.seed=4"],
                       capture_output=True, text=True,
                       cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert "mannequin_snag" in r.stdout


def test_fit_and_shadow_casters_hold_a_mesh_by_its_bounding_sphere():
    """--fit frames a mesh body (its bounding sphere's 6 points) and the key light's box holds it
    (ShadowPass treats a mesh as a sphere of its bounding radius), from the saved topology."""
    from types import SimpleNamespace

    from fraytool.render.bodies import body_bounding_radii
    from fraytool.render.fit import shot_points

    b = ModelBuilder(seed=1)
    _cloth(b, n=4)
    box = trimesh.creation.box(extents=(0.2, 0.1, 0.4))  # farthest corner: sqrt(0.01 + 0.0025 + 0.04)
    b.add_mesh("crate", vertices_m=box.vertices, triangles=box.faces, position_m=(1.0, 0.0, 0.0))
    topology = b.finalize().arrays()
    radius = np.sqrt(0.1 ** 2 + 0.05 ** 2 + 0.2 ** 2)
    assert body_bounding_radii(topology) == pytest.approx([radius])
    record = SimpleNamespace(particle_position_m=np.zeros((1, 3)), body_position_m=np.array([[1.0, 0.0, 0.0]]))
    points = shot_points(topology, [record])
    assert points[:, 0].max() == pytest.approx(1.0 + radius)


def test_exr_depth_and_alpha_hold_a_mesh_body(tmp_path):
    """`render --exr --alpha` of the golden scene with its ball replaced by a mesh of it (an icosphere):
    Z at the image centre is the mesh's distance along the view axis and A is opaque there, as
    tests/test_render_outputs.py checks for the analytic ball."""
    pytest.importorskip("OpenEXR")
    from fraytool.commands.main import main
    from fraytool.render.exr import read_exr

    trimesh.creation.icosphere(subdivisions=4, radius=0.035).export(tmp_path / "ball.obj")
    text = (Path(__file__).resolve().parent / "scenes" / "golden_small.toml").read_text()
    text = text.replace('shape = "sphere"\nradius_m = 0.035', 'shape = "mesh"\nfile = "ball.obj"')
    assert 'file = "ball.obj"' in text
    scene = tmp_path / "mesh_ball.toml"
    scene.write_text(text)
    out = tmp_path / "out"
    level = ["--resolution", "64x48", "--samples", "1", "--camera-position", "0,0.02,0.3",
             "--camera-target", "0,0.02,0", "--frames", "0:1"]  # (test_render_outputs.LEVEL_FLAGS)
    assert main(["render", str(scene), "-o", str(out), *level, "--exr", "--alpha", "--no-mp4"]) == 0
    exr = read_exr(out / "exr" / "frame_000000.exr")
    assert exr["A"][23, 31] == 1.0
    assert abs(exr["Z"][23, 31] - (0.3 - 0.035)) < 5e-4  # the mesh's front, facets within 0.1 mm of the sphere
    assert float(exr["A"][0, 0]) == 0.0 and np.isinf(exr["Z"][0, 0])  # the sky behind


@pytest.mark.parametrize("scale,says", [
    (100.0, "spans 28 m, 111 times the cloth (0.252 m); if its file is in centimetres set scale = [1, 1, 1], "
            "in millimetres [0.1, 0.1, 0.1]"),
    (1.0, None),
    (10.0, None),     # 2.8 m: large, but not past 20 m
])
def test_a_mesh_in_centimetres_is_a_warning_naming_the_scale(scale, says):
    """mannequin_snag's 0.28 m spike read a hundred times too large (a file in centimetres read as metres)
    is named by `fraytool check` with the scale that fixes it; at its own size, or ten times it, nothing."""
    run = subprocess.run([sys.executable, "-m", "fraytool", "check", "mannequin_snag", "--set",
                          f"bodies.0.scale=[{scale:g},{scale:g},{scale:g}]"], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    warnings = [line for line in run.stderr.splitlines() if line.startswith("fraytool: warning:")]
    if says is None:
        assert warnings == []
    else:
        assert len(warnings) == 1 and "[bodies.0] file = 'assets/mannequin.obj': the mesh " + says in warnings[0]
