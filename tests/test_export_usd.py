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
