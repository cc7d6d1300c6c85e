"""`fraytool export --usd`: the file is read back with the USD API (pxr) and checked against the frame
records: curve counts, the yarn centre-line points the renderer draws, widths, colours, the fade of
broken ends, body transforms, time codes and stage metadata."""
from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import numpy as np
import pytest

from fraytool.commands.main import main
from fraytool.render.color import srgb_to_linear
from fraytool.render.yarns import WARP, WEFT, yarn_pieces

SCENE = Path(__file__).resolve().parent / "scenes" / "golden_small.toml"   # 12 x 12, a ball, 4 frames at 24 fps


def test_export_without_usd_exits_2_naming_the_extra(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "pxr", None)          # `from pxr import ...` now raises ImportError
    assert main(["export", str(SCENE), "--usd", str(tmp_path / "shot.usd"), "-o", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert 'pip install "fraytool[usd]"' in err and len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert not (tmp_path / "frames").exists()              # refused before simulating


@pytest.mark.parametrize("flags,needle", [
    (["--usd", "shot.abc"], "--usd 'shot.abc': expected a file name ending in .usd, .usda, .usdc"),
    (["--usd", "shot.usd", "--frames", "2:9"], "--frames '2:9': expected START:END[:STEP]"),
    (["--usd", "shot_dir/no/such/out.usd"], "does not exist; create it first"),
    (["--usd", "shot_dir"], "is a folder: give a file name"),
    (["--usd", "shot.usd", "--set", "camera.up=[0.03, 0.115, 0.1]"], "is parallel to the view direction"),
])
def test_export_bad_flags_exit_2(tmp_path, capsys, flags, needle):
    pytest.importorskip("pxr")
    flags = [str(tmp_path / f) if f.startswith("shot") else f for f in flags]
    (tmp_path / "shot_dir").mkdir()
    assert main(["export", str(SCENE), "-o", str(tmp_path), *flags]) == 2
    err = capsys.readouterr().err
    assert needle.replace("'shot", f"'{tmp_path}/shot") in err and "Traceback" not in err
    assert not (tmp_path / "frames").exists()


def test_export_writes_yarn_curves_and_bodies_per_frame(tmp_path, capsys):
    """Frames 1..3 of the golden scene: every time sample against the frame records on disk."""
    pytest.importorskip("pxr")
    from pxr import Gf, Usd, UsdGeom

    from fraytool.io.frame_store import FrameStore
    from fraytool.scene import load_scene

    out, usd = tmp_path / "out", tmp_path / "shot.usd"
    assert main(["export", str(SCENE), "--usd", str(usd), "-o", str(out), "--frames", "1:4"]) == 0
    assert f"exported 3 frames to {usd}" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out", "shot.usd"]      # no temp file left
    spec = load_scene(SCENE)
    store = FrameStore(out)
    topology = store.load_topology()

    stage = Usd.Stage.Open(str(usd))
    assert UsdGeom.GetStageMetersPerUnit(stage) == 1.0 and UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.y
    assert stage.GetTimeCodesPerSecond() == 24 and stage.GetFramesPerSecond() == 24
    assert (stage.GetStartTimeCode(), stage.GetEndTimeCode()) == (1, 3)
    root = stage.GetDefaultPrim().GetPath()
    assert root.name == "golden_small"
    weft = UsdGeom.BasisCurves(stage.GetPrimAtPath(root.AppendPath("Yarns/Weft")))
    warp = UsdGeom.BasisCurves(stage.GetPrimAtPath(root.AppendPath("Yarns/Warp")))
    for curves, colour in ((weft, spec.render.weft_color), (warp, spec.render.warp_color)):
        assert curves and curves.GetTypeAttr().Get() == "cubic" and curves.GetBasisAttr().Get() == "catmullRom"
        assert curves.GetWrapAttr().Get() == "pinned"
        assert curves.GetPointsAttr().GetTimeSamples() == [1.0, 2.0, 3.0]
        np.testing.assert_allclose(np.array(curves.GetDisplayColorAttr().Get())[0], srgb_to_linear(colour), rtol=1e-6)
        assert curves.GetWidthsInterpolation() == "vertex"

    thickness = float(topology["thickness_m"])
    for frame in (1, 3):
        record = store.load_frame(frame)
        pieces = yarn_pieces(topology, record.particle_position_m, record.crossing_yarn_level, record.spring_alive)
        for kind, curves in ((WEFT, weft), (WARP, warp)):
            counts = np.array(curves.GetCurveVertexCountsAttr().Get(frame))
            sel = pieces.kind == kind
            np.testing.assert_array_equal(counts, np.diff(pieces.offsets)[sel])
            points = np.array(curves.GetPointsAttr().Get(frame))
            expected = np.concatenate([pieces.points[a:b] for a, b in
                                       zip(pieces.offsets[:-1][sel], pieces.offsets[1:][sel])])
            np.testing.assert_allclose(points, expected, atol=1e-7)
            widths = np.array(curves.GetWidthsAttr().Get(frame))
            np.testing.assert_allclose(widths, 2 * spec.render.yarn_radius_m, rtol=1e-6)   # the drawn diameter
            assert len(widths) == len(points)
            np.testing.assert_array_equal(np.array(curves.GetDisplayOpacityAttr().Get(frame)), 1.0)  # untorn
        # independently of the renderer's code: weft yarn j runs through crossings (i, j) at +-T/2 from them
        W = int(topology["warp_yarns"])
        first_weft = np.array(weft.GetPointsAttr().Get(frame))[:W]
        crossings = record.particle_position_m[:W].astype(np.float64)
        np.testing.assert_allclose(first_weft[:, [0, 2]], crossings[:, [0, 2]], atol=2e-4)
        np.testing.assert_allclose(np.linalg.norm(first_weft - crossings, axis=1), thickness / 2, rtol=1e-2)
        ball = UsdGeom.Sphere(stage.GetPrimAtPath(root.AppendPath("Bodies/ball")))
        assert ball and ball.GetRadiusAttr().Get() == pytest.approx(0.035)
        centre = ball.ComputeLocalToWorldTransform(frame).Transform(Gf.Vec3d(0, 0, 0))
        np.testing.assert_allclose(np.array(centre), record.body_position_m[0], atol=1e-7)

    try:
        from pxr import UsdValidation
    except ImportError:
        return
    validators = UsdValidation.ValidationRegistry().GetOrLoadAllValidators()
    errors = UsdValidation.ValidationContext(validators).Validate(stage)
    assert not errors, [e.GetMessage() for e in errors]


def test_export_fades_broken_ends_and_places_turned_boxes(tmp_path, posed_cloth):
    """A torn frame (posed): more curves than yarns, opacity 0 at the broken ends and 1 at the cloth
    border, as the renderer fades them; a box body turned and moved: its corners land where the frame
    record's rotation and position put them, through the USD transform."""
    pytest.importorskip("pxr")
    from pxr import Gf, Usd, UsdGeom

    from fraytool.export.usd import write_usd
    from fraytool.kinds import SHAPE_BOX
    from fraytool.render.geometry import YarnStyle, yarn_curves

    pc = posed_cloth
    topology = dict(pc.topology, body_shape=np.array([SHAPE_BOX], np.int8),
                    body_half_extents_m=np.array([[0.01, 0.02, 0.03]]))
    angle = np.radians(35.0)
    axis = np.array([1.0, 2.0, 0.5]) / np.linalg.norm([1.0, 2.0, 0.5])
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    R = np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K             # Rodrigues
    torn = pc.torn(2)
    torn = dataclasses.replace(torn, body_rotation=R[None].astype(np.float32),
                               body_position_m=np.array([[0.01, 0.03, -0.02]], np.float32))
    path = write_usd(tmp_path / "torn.usda", pc.spec, topology, [pc.copy(0), torn])
    stage = Usd.Stage.Open(str(path))
    root = stage.GetDefaultPrim().GetPath()
    weft = UsdGeom.BasisCurves(stage.GetPrimAtPath(root.AppendPath("Yarns/Weft")))
    warp = UsdGeom.BasisCurves(stage.GetPrimAtPath(root.AppendPath("Yarns/Warp")))
    assert len(weft.GetCurveVertexCountsAttr().Get(0)) == pc.H and len(warp.GetCurveVertexCountsAttr().Get(0)) == pc.W
    counts = [len(c.GetCurveVertexCountsAttr().Get(2)) for c in (weft, warp)]
    assert counts[0] > pc.H and counts[1] > pc.W                           # torn yarns are several pieces

    curves = yarn_curves(topology, torn, YarnStyle.from_spec(pc.spec.render, topology))
    pieces = yarn_pieces(topology, torn.particle_position_m, torn.crossing_yarn_level, torn.spring_alive)
    opacity = np.concatenate([np.array(c.GetDisplayOpacityAttr().Get(2)) for c in (weft, warp)])
    assert (np.diff(pieces.kind) >= 0).all()                                # weft pieces first, as in the file
    first, last = pieces.offsets[:-1], pieces.offsets[1:] - 1
    assert pieces.broken_start.any() and pieces.broken_end.any()
    assert (opacity[first[pieces.broken_start]] == 0).all() and (opacity[last[pieces.broken_end]] == 0).all()
    assert (opacity[first[~pieces.broken_start]] == 1).all() and (opacity[last[~pieces.broken_end]] == 1).all()
    assert ((opacity > 0) & (opacity < 1)).any()                            # the fade itself
    np.testing.assert_allclose(opacity, curves.opacity)                     # the renderer's fade at the points

    box = UsdGeom.Cube(stage.GetPrimAtPath(root.AppendPath("Bodies/ball")))
    assert box and box.GetSizeAttr().Get() == 2.0
    M = box.ComputeLocalToWorldTransform(2)
    for corner in ((1, 1, 1), (-1, 1, -1), (1, -1, 1)):
        world = np.array(M.Transform(Gf.Vec3d(*corner)))
        np.testing.assert_allclose(world, R @ (np.array(corner) * [0.01, 0.02, 0.03]) + [0.01, 0.03, -0.02], atol=1e-6)


def test_up_axis_follows_the_camera(tmp_path, posed_cloth):
    """USD allows Y or Z up: a scene whose camera has z up gets a Z-up stage (the shipped ones Y)."""
    pytest.importorskip("pxr")
    from pxr import Usd, UsdGeom

    from fraytool.export.usd import up_axis, write_usd

    spec = posed_cloth.spec
    z_up = dataclasses.replace(spec, camera=dataclasses.replace(spec.camera, up=(0.1, 0.2, -0.9)))
    path = write_usd(tmp_path / "z.usdc", z_up, posed_cloth.topology, [posed_cloth.copy(5)])
    stage = Usd.Stage.Open(str(path))
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.z
    assert (stage.GetStartTimeCode(), stage.GetEndTimeCode()) == (5, 5)
    assert up_axis((0.0, 1.0, 0.0)) == "Y" and up_axis((0.3, -0.8, 0.5)) == "Y"


# -- the camera -----------------------------------------------------------------------------------

def _usd_ndc(stage, time: float, points: np.ndarray) -> np.ndarray:
    """Normalised device coordinates of world points seen by the stage's camera, through USD's own
    camera maths (GfCamera -> GfFrustum view and projection matrices, row vectors: p V P)."""
    from pxr import UsdGeom

    prim = stage.GetPrimAtPath(stage.GetDefaultPrim().GetPath().AppendChild("Camera"))
    frustum = UsdGeom.Camera(prim).GetCamera(time).frustum
    m = np.array(frustum.ComputeViewMatrix() * frustum.ComputeProjectionMatrix())
    clip = np.c_[points, np.ones(len(points))] @ m
    return clip[:, :3] / clip[:, 3:]


def _renderer_ndc(camera_spec, resolution, points: np.ndarray) -> np.ndarray:
    """The same through the renderer's view-projection matrix (fraytool.render.camera, column vectors)."""
    from fraytool.render.camera import Camera

    w, h = resolution
    clip = Camera(camera_spec).view_proj(w / h) @ np.c_[points, np.ones(len(points))].T
    return (clip[:3] / clip[3]).T


@pytest.mark.parametrize("camera,resolution", [
    ({}, (160, 120)),                                                                    # the scene's own
    ({"position_m": (0.3, -0.2, 0.25), "target_m": (0.01, 0.02, 0.03), "up": (0.1, 0.2, 0.9), "fov_deg": 70.0},
     (300, 700)),                                                                        # z up, portrait
    ({"position_m": (-0.05, 0.9, 0.01), "up": (0.3, 0.0, -1.0), "fov_deg": 12.0}, (1920, 817)),
])
def test_usd_camera_sees_what_the_renderer_draws(tmp_path, posed_cloth, camera, resolution):
    """World points in front of the camera land on the same normalised device coordinates (x, y and
    depth) through the USD camera as through the renderer's matrices; the camera is static."""
    pytest.importorskip("pxr")
    from pxr import Usd, UsdGeom

    from fraytool.export.usd import write_usd

    spec = posed_cloth.spec
    spec = dataclasses.replace(spec, camera=dataclasses.replace(spec.camera, **camera),
                               render=dataclasses.replace(spec.render, resolution=resolution))
    records = [posed_cloth.copy(0), posed_cloth.draped(1), posed_cloth.torn(2)]
    stage = Usd.Stage.Open(str(write_usd(tmp_path / "cam.usda", spec, posed_cloth.topology, records)))
    eye, target = np.array(spec.camera.position_m), np.array(spec.camera.target_m)
    distance = np.linalg.norm(target - eye)
    rng = np.random.default_rng(7)
    points = np.concatenate([target + rng.uniform(-0.4, 0.4, (40, 3)) * distance,
                             [target, eye + 0.01 * (target - eye), eye + 50.0 * (target - eye)],
                             records[2].particle_position_m[::7]])
    expected = _renderer_ndc(spec.camera, resolution, points)
    assert (np.abs(expected[:, 2]) < 1).all() and (np.abs(expected[:, :2]) < 1).any()  # between near and far
    for time in (0, 2):
        np.testing.assert_allclose(_usd_ndc(stage, time, points), expected, atol=1e-5)
    cam = UsdGeom.Camera(stage.GetPrimAtPath(stage.GetDefaultPrim().GetPath().AppendChild("Camera")))
    assert cam.GetProjectionAttr().Get() == UsdGeom.Tokens.perspective
    assert cam.GetHorizontalApertureAttr().Get() / cam.GetVerticalApertureAttr().Get() == \
        pytest.approx(resolution[0] / resolution[1], rel=1e-6)
    assert all(not op.GetAttr().GetTimeSamples() for op in cam.GetOrderedXformOps())   # no camera animation
    assert UsdGeom.GetStageUpAxis(stage) == (UsdGeom.Tokens.z if abs(camera.get("up", (0, 1, 0))[2]) > 0.5
                                             else UsdGeom.Tokens.y)


def test_export_fits_the_camera_as_render_does(tmp_path, capsys):
    """[camera] fit = true: the USD camera is the fitted one, which frames every particle of the shot
    with the fit margin free on its tightest side (fraytool.render.fit's exact fit)."""
    pytest.importorskip("pxr")
    from pxr import Usd

    from fraytool.io.frame_store import FrameStore
    from fraytool.scene import load_scene

    out, usd = tmp_path / "out", tmp_path / "fit.usd"
    assert main(["export", str(SCENE), "--usd", str(usd), "-o", str(out), "--frames", "1:2",
                 "--set", "camera.fit=true"]) == 0
    assert "fit: camera at" in capsys.readouterr().err
    spec = load_scene(SCENE)
    store = FrameStore(out)
    particles = np.concatenate([store.load_frame(f).particle_position_m for f in range(spec.time.frames)])
    ndc = _usd_ndc(Usd.Stage.Open(str(usd)), 1, particles.astype(np.float64))
    assert np.abs(ndc[:, :2]).max() == pytest.approx(1.0 - spec.camera.fit_margin, abs=2e-3)
    assert (np.abs(ndc[:, 2]) < 1).all()


# -- velocities -----------------------------------------------------------------------------------

def _frame_time_scale(spec) -> float:
    """Stage seconds per simulated second: the shot plays frame_time = step_s x steps_per_frame of
    simulated time per 1 / fps of the stage's timeline."""
    return spec.time.step_s * spec.time.steps_per_frame * spec.time.fps


def test_free_falling_cloth_exports_g_t(tmp_path):
    """golden_drape's first frames are a free fall (the cloth 10 mm above the ball): every yarn point
    moves at g t, in stage units per second of the stage's timeline, within the half step by which
    symplectic Euler's positions lead its velocities; the static ball has zero velocity."""
    pytest.importorskip("pxr")
    from pxr import Usd, UsdGeom

    from fraytool.scene import load_scene

    scene = SCENE.parent / "golden_drape.toml"
    usd = tmp_path / "drape.usdc"
    assert main(["export", str(scene), "--usd", str(usd), "-o", str(tmp_path / "out"), "--frames", "0:4"]) == 0
    spec = load_scene(scene)
    stage = Usd.Stage.Open(str(usd))
    root = stage.GetDefaultPrim().GetPath()
    g = np.array(spec.gravity_m_s2)
    scale = _frame_time_scale(spec)
    for frame in range(4):
        t = frame * spec.time.step_s * spec.time.steps_per_frame
        for name in ("Weft", "Warp"):
            curves = UsdGeom.BasisCurves(stage.GetPrimAtPath(root.AppendPath(f"Yarns/{name}")))
            v = np.array(curves.GetVelocitiesAttr().Get(frame))
            assert v.shape == np.array(curves.GetPointsAttr().Get(frame)).shape
            np.testing.assert_allclose(v, np.broadcast_to(g * t * scale, v.shape),
                                       atol=np.linalg.norm(g) * spec.time.step_s * scale)
        ball = UsdGeom.PrimvarsAPI(stage.GetPrimAtPath(root.AppendPath("Bodies/ball")))
        np.testing.assert_array_equal(np.array(ball.GetPrimvar("fraytool:velocity").Get(frame)), 0.0)


def test_kinematic_bars_and_the_edges_they_hold_export_their_velocity(tmp_path):
    """golden_tear's bars move at velocity_m_s = -+0.8 m/s and hold the cloth's left and right edges:
    the bars' velocity primvar is that velocity (on the stage's timeline), matching their translate
    samples, with no spin; the points of warp yarn 0 (the held left edge) move with the left bar."""
    pytest.importorskip("pxr")
    from pxr import Usd, UsdGeom

    from fraytool.scene import load_scene

    scene = SCENE.parent / "golden_tear.toml"
    usd = tmp_path / "tear.usda"
    assert main(["export", str(scene), "--usd", str(usd), "-o", str(tmp_path / "out"), "--frames", "0:2"]) == 0
    spec = load_scene(scene)
    scale = _frame_time_scale(spec)
    stage = Usd.Stage.Open(str(usd))
    root = stage.GetDefaultPrim().GetPath()
    warp = UsdGeom.BasisCurves(stage.GetPrimAtPath(root.AppendPath("Yarns/Warp")))
    for body in spec.bodies:
        prim = stage.GetPrimAtPath(root.AppendPath(f"Bodies/{body.name}"))
        primvars = UsdGeom.PrimvarsAPI(prim)
        expected = np.array(body.velocity_m_s) * scale
        translate = prim.GetAttribute("xformOp:translate")
        for frame in (0, 1):
            velocity = np.array(primvars.GetPrimvar("fraytool:velocity").Get(frame))
            np.testing.assert_allclose(velocity, expected, atol=1e-6)
            np.testing.assert_allclose(primvars.GetPrimvar("fraytool:angularVelocity").Get(frame), 0.0, atol=1e-6)
            moved = np.array(translate.Get(frame + 1) if frame == 0 else translate.Get(frame)) - \
                np.array(translate.Get(frame) if frame == 0 else translate.Get(frame - 1))
            np.testing.assert_allclose(moved * stage.GetTimeCodesPerSecond(), expected, atol=1e-6)
    left = np.array(spec.bodies[0].velocity_m_s) * scale
    for frame in (0, 1):
        H = int(spec.cloth.weft_yarns)
        assert warp.GetCurveVertexCountsAttr().Get(frame)[0] == H                 # warp yarn 0 whole
        held = np.array(warp.GetVelocitiesAttr().Get(frame))[:H]
        np.testing.assert_allclose(held, np.broadcast_to(left, held.shape), atol=0.03 * np.linalg.norm(left))


def test_velocities_follow_the_pieces_as_the_cloth_tears(tmp_path, posed_cloth):
    """Hand-posed frames: rest (1), torn (2), then the torn cloth translated by d per frame (3, 4) while
    the ball turns about z at a known rate and an animated mesh body's key vertices slide. Every time
    sample has a velocity per point, as many as the points though the piece count changes; once the
    cloth moves rigidly every yarn point moves at d x fps; the ball's primvars are its linear and
    angular velocity; the mesh's `velocities` are its vertices' own (body-frame) rate."""
    pytest.importorskip("pxr")
    from pxr import Usd, UsdGeom

    from fraytool.export.usd import write_usd
    from fraytool.kinds import SHAPE_MESH

    pc = posed_cloth
    fps = pc.spec.time.fps
    frame_time = pc.spec.time.step_s * pc.spec.time.steps_per_frame
    d = np.array([0.0012, -0.0021, 0.0004])                        # cloth displacement per frame [m]
    ball_step = np.array([0.003, 0.0, -0.001])                     # ball displacement per frame [m]
    spin = 0.25                                                    # ball's turn per frame about z [rad]
    slide = np.array([0.0, 0.5, 0.0])                              # mesh vertices' velocity [m/s, simulated]
    mesh = {"mesh_body": np.array([0], np.int32), "mesh_closed": np.array([False]),
            "mesh_vertex_start": np.array([0, 3], np.int64), "mesh_triangle_start": np.array([0, 1], np.int64),
            "mesh_triangles": np.array([[0, 1, 2]], np.int32), "mesh_key_start": np.array([0, 2], np.int64),
            "mesh_key_time_s": np.array([0.0, 1.0]),
            "mesh_key_vertex_m": np.concatenate([np.eye(3) * 0.01, np.eye(3) * 0.01 + slide]),
            "mesh_edge_start": np.array([0, 0], np.int64), "mesh_sharp_edges": np.zeros((0, 2), np.int32)}
    records = [pc.copy(1), pc.torn(2), pc.torn(3), pc.torn(4)]
    for k, record in enumerate(records):
        frame = k + 1
        if frame >= 3:
            record.particle_position_m += (frame - 2) * d.astype(np.float32)
        c, s = np.cos(spin * frame), np.sin(spin * frame)
        record.body_rotation[0] = [[c, -s, 0], [s, c, 0], [0, 0, 1]]
        record.body_position_m[0] += frame * ball_step.astype(np.float32)
        record.time_s = frame * frame_time
    for topology, body in ((pc.topology, "ball"),
                           (dict(pc.topology, body_shape=np.array([SHAPE_MESH], np.int8), **mesh), "mesh")):
        spec = dataclasses.replace(pc.spec, bodies=(dataclasses.replace(pc.spec.bodies[0], name=body),))
        stage = Usd.Stage.Open(str(write_usd(tmp_path / f"{body}.usda", spec, topology, records)))
        root = stage.GetDefaultPrim().GetPath()
        counts = {}
        for name in ("Weft", "Warp"):
            curves = UsdGeom.BasisCurves(stage.GetPrimAtPath(root.AppendPath(f"Yarns/{name}")))
            for frame in (1, 2, 3, 4):
                points = np.array(curves.GetPointsAttr().Get(frame))
                v = np.array(curves.GetVelocitiesAttr().Get(frame))
                assert v.shape == points.shape and np.isfinite(v).all()
                counts[name, frame] = len(curves.GetCurveVertexCountsAttr().Get(frame))
                if frame >= 3:
                    np.testing.assert_allclose(v, np.broadcast_to(d * fps, v.shape), atol=1e-3 * np.linalg.norm(d) * fps)
            assert counts[name, 2] > counts[name, 1]                           # the tear split yarns
        prim = stage.GetPrimAtPath(root.AppendPath(f"Bodies/{body}"))
        primvars = UsdGeom.PrimvarsAPI(prim)
        for frame in (1, 2, 3, 4):
            np.testing.assert_allclose(primvars.GetPrimvar("fraytool:velocity").Get(frame), ball_step * fps,
                                       atol=1e-5)
            np.testing.assert_allclose(primvars.GetPrimvar("fraytool:angularVelocity").Get(frame),
                                       [0.0, 0.0, spin * fps], rtol=1e-5)
        if body == "mesh":
            mesh_v = np.array(UsdGeom.Mesh(prim).GetVelocitiesAttr().Get(2))
            np.testing.assert_allclose(mesh_v, np.broadcast_to(slide * frame_time * fps, (3, 3)), rtol=1e-5)
        else:
            assert not prim.HasAttribute("velocities")                          # a sphere has no points


def test_a_garment_exports_a_prim_per_panel_in_its_colours_and_live_stitches_as_curves(tmp_path):
    """seam_rip (panels "left" and "right", sewn by two seams): a Scope per panel named by it, its Weft and
    Warp holding that panel's pieces in its colours (right has its own, left [render]'s), and the live
    stitches as linear two-point curves between their masses."""
    pytest.importorskip("pxr")
    from pxr import Usd, UsdGeom

    from fraytool.commands.main import main
    from fraytool.io.frame_store import FrameStore
    from fraytool.kinds import STITCH
    from fraytool.scene import load_scene

    out, usd = tmp_path / "shot", tmp_path / "garment.usda"
    assert main(["export", "seam_rip", "--usd", str(usd), "-o", str(out), "--frames", "0:2", "--progress", "none"]) == 0
    stage = Usd.Stage.Open(str(usd))
    root = stage.GetDefaultPrim().GetPath()
    store = FrameStore(out)
    topology, record = store.load_topology(), store.load_frame(1)
    pieces = yarn_pieces(topology, record.particle_position_m, record.crossing_yarn_level, record.spring_alive)
    panel = np.asarray(topology["crossing_panel"])[pieces.first_crossing]
    spec = load_scene("seam_rip")
    assert [p.name for p in spec.all_panels] == ["left", "right"]
    assert not stage.GetPrimAtPath(root.AppendPath("Yarns/Weft"))
    for p, cloth in enumerate(spec.all_panels):
        for kind, name, colour in ((WEFT, "Weft", cloth.weft_color or spec.render.weft_color),
                                   (WARP, "Warp", cloth.warp_color or spec.render.warp_color)):
            curves = UsdGeom.BasisCurves(stage.GetPrimAtPath(root.AppendPath(f"Yarns/{cloth.name}/{name}")))
            assert curves, (cloth.name, name)
            mine = (pieces.yarn >= 0) & (pieces.kind == kind) & (panel == p)
            assert len(curves.GetCurveVertexCountsAttr().Get(1)) == int(mine.sum()) > 0
            np.testing.assert_allclose(curves.GetDisplayColorAttr().Get()[0], srgb_to_linear(colour), atol=1e-6)
    assert spec.all_panels[1].warp_color != spec.render.warp_color  # the two panels' colours differ
    stitches = UsdGeom.BasisCurves(stage.GetPrimAtPath(root.AppendPath("Yarns/Stitches")))
    assert stitches.GetTypeAttr().Get() == UsdGeom.Tokens.linear
    live = np.flatnonzero((np.asarray(topology["spring_kind"]) == STITCH) & record.spring_alive)
    assert live.size > 0 and list(stitches.GetCurveVertexCountsAttr().Get(1)) == [2] * live.size
    ends = np.array(stitches.GetPointsAttr().Get(1)).reshape(-1, 2, 3)
    x = record.particle_position_m
    np.testing.assert_allclose(ends[:, 0], x[np.asarray(topology["spring_crossing_a"])[live]], atol=1e-6)
    np.testing.assert_allclose(ends[:, 1], x[np.asarray(topology["spring_crossing_b"])[live]], atol=1e-6)
