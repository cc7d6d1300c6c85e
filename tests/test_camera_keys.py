"""A moving camera: [camera] position_keys_m, target_keys_m, fov_keys_deg and interpolation
(docs/scene-format.md [camera], docs/rendering.md "A moving camera").

The pose at a time is checked against the analytic interpolants; rendered frames of a still cloth differ
between frames when the camera moves (and are identical when it does not), motion blur sees the camera's
motion, --fit frames every frame of a moving camera, the USD camera is time-sampled, and bad keys are one
line and exit 2."""
from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from fraytool.commands.main import main
from fraytool.render.camera import Camera, camera_at, check_camera, is_animated
from fraytool.scene.spec import CameraSpec
from helpers import small_scene_text

FRAME_S = 4e-4 * 5          # small_scene_text: step_s x steps_per_frame
W, H = 96, 54

MOVING = """
[camera]
position_keys_m = [[0.0, -0.03, 0.12, 0.12], [{end}, 0.03, 0.12, 0.12]]
target_keys_m = [[0.0, -0.03, 0.1, 0.0], [{end}, 0.03, 0.1, 0.0]]
fov_deg = 40.0

[render]
resolution = [96, 54]
samples = 2
"""
"""The camera trucks 6 cm to the right over `end` seconds, past the cloth (0.1 m up, 6 cm across)."""

STILL = """
[camera]
position_m = [0.0, 0.12, 0.12]
target_m = [0.0, 0.1, 0.0]

[render]
resolution = [96, 54]
samples = 2
"""


def _scene(folder: Path, camera: str, name: str = "cam", frames: int = 3, gravity: str = "[0.0, 0.0, 0.0]") -> Path:
    """The small test cloth, still (no gravity) unless `gravity` is given, seen by `camera`."""
    path = folder / f"{name}.toml"
    path.write_text(small_scene_text(name=name, frames=frames, gravity=gravity) + camera)
    return path


def _render(scene: Path, out: Path, *flags: str) -> None:
    assert main(["render", str(scene), "-o", str(out), "--png", "--no-mp4", "--progress", "none", *flags]) == 0


def _png(out: Path, frame: int) -> np.ndarray:
    return np.asarray(Image.open(out / "png" / f"frame_{frame:06d}.png")).astype(int)


# -- the pose at a time ---------------------------------------------------------------------------

def test_linear_keys_give_the_midpoint_and_are_held_outside():
    cam = CameraSpec(position_keys_m=((1.0, 0.0, 0.2, 1.0), (3.0, 2.0, 0.4, 3.0)),
                     target_keys_m=((0.0, 0.0, 0.0, 0.0), (2.0, 0.0, 1.0, 0.0)),
                     fov_keys_deg=((0.0, 20.0), (4.0, 60.0)))
    mid = camera_at(cam, 2.0)
    assert mid.position_m == pytest.approx((1.0, 0.3, 2.0))
    assert mid.target_m == pytest.approx((0.0, 1.0, 0.0))
    assert mid.fov_deg == pytest.approx(40.0)
    assert not is_animated(mid) and not mid.position_keys_m and not mid.fov_keys_deg
    before, after = camera_at(cam, 0.0), camera_at(cam, 9.0)       # held before the first, after the last
    assert before.position_m == (0.0, 0.2, 1.0) and after.position_m == (2.0, 0.4, 3.0)
    assert before.fov_deg == 20.0 and after.fov_deg == 60.0 and after.target_m == (0.0, 1.0, 0.0)
    assert camera_at(CameraSpec(), 5.0) is not None and camera_at(CameraSpec(), 5.0) == CameraSpec()
    # a value without keys stays the static one
    only_fov = CameraSpec(fov_keys_deg=((0.0, 20.0), (1.0, 30.0)))
    assert camera_at(only_fov, 0.5).position_m == CameraSpec().position_m
    assert camera_at(only_fov, 0.5).fov_deg == pytest.approx(25.0)


def test_catmull_rom_keys_pass_through_the_keys_and_are_exact_on_quadratic_motion():
    times = np.array([0.0, 0.3, 1.1, 1.5, 2.6])                   # uneven spacing
    a, b, c = np.array([0.1, -0.2, 1.0]), np.array([0.5, 0.3, -0.4]), np.array([-0.7, 0.2, 0.25])

    def motion(t):
        return a + b * t + c * t * t

    def fov(t):
        return 30.0 + 4.0 * t + 3.0 * t * t

    cam = CameraSpec(interpolation="catmull_rom",
                     position_keys_m=tuple((t, *motion(t)) for t in times),
                     fov_keys_deg=tuple((t, fov(t)) for t in times))
    for t in times:
        assert camera_at(cam, t).position_m == pytest.approx(tuple(motion(t)), abs=1e-12)
    for t in (0.05, 0.7, 1.3, 2.0, 2.55):
        assert camera_at(cam, t).position_m == pytest.approx(tuple(motion(t)), abs=1e-12)
        assert camera_at(cam, t).fov_deg == pytest.approx(fov(t), abs=1e-9)
        # and not what the linear interpolation gives
        linear = camera_at(dataclasses.replace(cam, interpolation="linear"), t)
        assert np.abs(np.subtract(linear.position_m, motion(t))).max() > 1e-3


def test_camera_object_follows_the_time():
    cam = CameraSpec(position_keys_m=((0.0, 0.0, 0.3, 0.6), (1.0, 0.6, 0.3, 0.0)))
    c0 = Camera(cam)
    c1 = c0.at(1.0)
    assert c0.at(0.0) is c0 and c1 is not c0
    np.testing.assert_allclose(c1.eye, (0.6, 0.3, 0.0))
    assert not np.allclose(c0.view, c1.view)
    still = Camera(CameraSpec())
    assert still.at(3.0) is still                                  # a static camera is one camera


def test_a_key_that_puts_the_eye_on_the_target_is_refused(tmp_path, capsys):
    cam = CameraSpec(position_keys_m=((0.0, 0.0, 0.3, 0.6), (1.0, 0.0, 0.0, 0.0)))
    with pytest.raises(Exception, match="at t = 1 s"):
        check_camera(cam)
    scene = _scene(tmp_path, "\n[camera]\nposition_keys_m = [[0.0, 0.0, 0.3, 0.6], [1.0, 0.0, 0.0, 0.0]]\n")
    assert main(["render", str(scene), "-o", str(tmp_path / "out"), "--png", "--no-mp4"]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "[camera]" in err and "at t = 1 s" in err, err


# -- bad input ------------------------------------------------------------------------------------

BAD = {
    "position keys out of order": ("position_keys_m = [[0.1, 0.0, 0.3, 0.6], [0.05, 0.0, 0.3, 0.7]]",
                                   ["[camera] position_keys_m", "times from 0 to 1e6 s and increasing"]),
    "target keys out of order": ("target_keys_m = [[0.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.1, 0.0]]",
                                 ["[camera] target_keys_m", "increasing"]),
    "fov key out of range": ("fov_keys_deg = [[0.0, 40.0], [0.1, 200.0]]",
                             ["[camera] fov_keys_deg = [[0.0, 40.0], [0.1, 200.0]]", ">= 1 and <= 170"]),
    "fov key of 3 numbers": ("fov_keys_deg = [[0.0, 40.0, 1.0]]", ["[camera] fov_keys_deg", "[t, value]"]),
    "non-finite key": ("target_keys_m = [[0.0, nan, 0.0, 0.0]]", ["[camera] target_keys_m", "finite numbers"]),
    "non-finite fov key": ("fov_keys_deg = [[inf, 40.0]]", ["[camera] fov_keys_deg", "finite numbers"]),
    "unknown interpolation": ('interpolation = "cubic"', ['[camera] interpolation = "cubic"', '"catmull_rom"']),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_camera_keys_give_one_line_and_exit_2(case, tmp_path, capsys):
    line, expected = BAD[case]
    path = _scene(tmp_path, f"\n[camera]\n{line}\n", name="bad")
    assert main(["check", str(path)]) == 2
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1, err
    assert str(path) in err and "Traceback" not in err
    for fragment in expected:
        assert fragment in err, f"{fragment!r} not in {err!r}"


# -- rendering ------------------------------------------------------------------------------------

def test_a_moving_camera_moves_the_picture_and_a_still_one_does_not(tmp_path):
    moving, still = tmp_path / "moving", tmp_path / "still"
    _render(_scene(tmp_path, MOVING.format(end=2 * FRAME_S), name="moving"), moving)
    _render(_scene(tmp_path, STILL, name="still"), still)
    s = [_png(still, f) for f in range(3)]
    assert (s[0] == s[1]).all() and (s[0] == s[2]).all()           # a still cloth, a still camera
    m = [_png(moving, f) for f in range(3)]
    assert (m[0] != m[2]).any(axis=-1).mean() > 0.02
    assert (m[0] != m[1]).any() and (m[1] != m[2]).any()
    # the cloth slides to the left in the picture as the camera trucks to the right
    background = m[0][0, 0]

    def centre_x(image):
        mask = np.abs(image - background).sum(axis=-1) > 30
        return float(np.nonzero(mask)[1].mean())
    assert centre_x(m[0]) > centre_x(m[1]) + 1 > centre_x(m[2]) + 2


def test_motion_blur_includes_the_cameras_motion(tmp_path):
    scene = _scene(tmp_path, MOVING.format(end=2 * FRAME_S), name="blur")
    sharp, blurred = tmp_path / "sharp", tmp_path / "blurred"
    _render(scene, sharp, "--frames", "0:1")
    _render(scene, blurred, "--frames", "0:1", "--motion-blur", "1", "--motion-samples", "4")
    moved = np.abs(_png(sharp, 0) - _png(blurred, 0)).max(axis=-1)
    assert (moved > 8).mean() > 0.02                                 # a still cloth blurred by the camera alone
    # the still camera's blur of the still cloth is the sharp frame (but for the float target's rounding at
    # a few edge pixels)
    still = _scene(tmp_path, STILL, name="stillblur")
    _render(still, tmp_path / "s1", "--frames", "0:1")
    _render(still, tmp_path / "s2", "--frames", "0:1", "--motion-blur", "1", "--motion-samples", "4")
    same = np.abs(_png(tmp_path / "s1", 0) - _png(tmp_path / "s2", 0)).max(axis=-1)
    assert (same > 8).mean() == 0.0 and (same > 2).mean() < 0.002


def test_renderer_takes_the_camera_of_each_frames_time(gl_ctx, posed_cloth):
    """The renderer draws frame records with the camera of their time (also the geometry builder's level of
    detail), whichever order they come in: a frame drawn after another equals itself drawn alone."""
    from fraytool.render.renderer import Renderer

    spec = posed_cloth.spec
    cam = dataclasses.replace(spec.camera, position_keys_m=((0.0, *spec.camera.position_m),
                                                            (1.0, 0.3, 0.25, 0.3)))
    size = (80, 60)
    records = [dataclasses.replace(posed_cloth.draped(1), time_s=t) for t in (0.0, 1.0)]

    def draw(order, camera=cam):
        r = Renderer(gl_ctx, size, 2, spec.render, camera, posed_cloth.topology)
        try:
            b = r.geometry_builder(posed_cloth.topology)
            out = {}
            for k in order:
                out[k] = r.render(b.build(records[k]))
                assert np.allclose(r.camera.eye, camera_at(camera, records[k].time_s).position_m)
            return out
        finally:
            r.release()
    forward, backward = draw([0, 1]), draw([1, 0])
    assert (forward[0] != forward[1]).any()
    assert (forward[0] == backward[0]).all() and (forward[1] == backward[1]).all()
    # and as a static camera placed where the keys are at that time draws it (the shading's eye too)
    assert (draw([1], camera_at(cam, 1.0))[1] == forward[1]).all()


# -- --fit ----------------------------------------------------------------------------------------

FIT_CAMERA = """
[camera]
position_keys_m = [[0.0, 0.4, 0.5, 0.4], [{end}, -0.4, 0.3, 0.5]]
target_keys_m = [[0.0, 0.3, 0.2, 0.0], [{end}, 0.2, 0.3, -0.1]]
fov_keys_deg = [[0.0, 25.0], [{end}, 35.0]]
interpolation = "catmull_rom"

[render]
resolution = [96, 54]
samples = 2
"""
"""A move that looks past a falling cloth (targets 20-30 cm off it): only --fit shows it."""


def test_fit_with_a_moving_camera_frames_every_crossing_of_every_frame(tmp_path, capsys):
    from fraytool.io.frame_store import FrameStore
    from fraytool.render.fit import fitted_camera
    from fraytool.scene import load_scene

    frames = 5
    scene = _scene(tmp_path, FIT_CAMERA.format(end=(frames - 1) * FRAME_S), name="fitmove", frames=frames,
                   gravity="[0.0, -9.81, 0.0]")
    out = tmp_path / "out"
    _render(scene, out, "--fit")
    assert "moving on 5 keys" in capsys.readouterr().err
    spec = load_scene(str(scene))
    store = FrameStore(out)
    records = [store.load_frame(f) for f in range(frames)]
    assert records[-1].particle_position_m[:, 1].min() < records[0].particle_position_m[:, 1].min()  # it falls

    def ndc(camera, record):
        clip = Camera(camera, record.time_s).view_proj(W / H) @ np.c_[record.particle_position_m,
                                                                      np.ones(len(record.particle_position_m))].T
        assert (clip[3] > 0).all()
        return clip[:2] / clip[3]
    assert max(np.abs(ndc(spec.camera, r)).max() for r in records) > 1     # unfitted: off the picture
    fitted = fitted_camera(dataclasses.replace(spec, camera=dataclasses.replace(spec.camera, fit=True)), store)
    assert len(fitted.position_keys_m) == frames and not fitted.fit
    worst = 0.0
    for r in records:
        worst = max(worst, float(np.abs(ndc(fitted, r)).max()))
        assert np.abs(ndc(fitted, r)).max() <= 1.0 - spec.camera.fit_margin + 1e-6
        # each frame keeps the view direction and field of view of the keys at its time
        a, b = Camera(spec.camera, r.time_s), Camera(fitted, r.time_s)
        np.testing.assert_allclose(b.view[2, :3], a.view[2, :3], atol=1e-9)
        assert b.spec.fov_deg == pytest.approx(a.spec.fov_deg)
    assert worst == pytest.approx(1.0 - spec.camera.fit_margin, abs=1e-6)   # and no farther than it must be
    for f in range(frames):                                                   # the render drew every frame
        assert (out / "png" / f"frame_{f:06d}.png").is_file()


# -- USD ------------------------------------------------------------------------------------------

def test_usd_camera_is_time_sampled_as_the_renderer_moves(tmp_path, posed_cloth):
    pytest.importorskip("pxr")
    from pxr import Usd, UsdGeom

    from fraytool.export.usd import frame_time_s, write_usd

    spec = posed_cloth.spec
    dt = frame_time_s(spec)
    cam = dataclasses.replace(spec.camera, position_keys_m=((0.0, *spec.camera.position_m), (2 * dt, 0.3, 0.25, 0.3)),
                              fov_keys_deg=((0.0, 30.0), (2 * dt, 50.0)))
    spec = dataclasses.replace(spec, camera=cam)
    records = [dataclasses.replace(posed_cloth.copy(f), time_s=f * dt) for f in range(3)]
    stage = Usd.Stage.Open(str(write_usd(tmp_path / "moving.usda", spec, posed_cloth.topology, records)))
    prim = UsdGeom.Camera(stage.GetPrimAtPath(stage.GetDefaultPrim().GetPath().AppendChild("Camera")))
    w, h = spec.render.resolution
    points = np.concatenate([records[0].particle_position_m[::5].astype(np.float64), [[0.0, 0.05, 0.0]]])
    transforms = []
    for f, r in enumerate(records):
        frustum = prim.GetCamera(f).frustum
        m = np.array(frustum.ComputeViewMatrix() * frustum.ComputeProjectionMatrix())
        clip = np.c_[points, np.ones(len(points))] @ m
        usd_ndc = clip[:, :3] / clip[:, 3:]
        clip = Camera(cam, r.time_s).view_proj(w / h) @ np.c_[points, np.ones(len(points))].T
        np.testing.assert_allclose(usd_ndc, (clip[:3] / clip[3]).T, atol=1e-5)
        transforms.append(np.array(UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(f)))
        np.testing.assert_allclose(transforms[-1][3, :3], camera_at(cam, r.time_s).position_m, atol=1e-9)
    assert not np.allclose(transforms[0], transforms[2])
    ops = prim.GetOrderedXformOps()
    assert all(op.GetAttr().GetTimeSamples() == [0.0, 1.0, 2.0] for op in ops)
    assert prim.GetFocalLengthAttr().GetTimeSamples() == [0.0, 1.0, 2.0]
    assert prim.GetFocalLengthAttr().Get(0) > prim.GetFocalLengthAttr().Get(2)   # wider fov: shorter lens


# -- the golden report ----------------------------------------------------------------------------

def test_golden_report_projects_with_the_camera_of_the_frame():
    from fraytool.golden.run import project_to_pixel
    from fraytool.scene import parse_scene

    spec = parse_scene(small_scene_text() + MOVING.format(end=1.0), "moving.toml")
    for t, x in ((0.0, -0.03), (1.0, 0.03)):    # the target: the image centre at any time
        assert project_to_pixel(spec, (x, 0.1, 0.0), t) == [W // 2, H // 2]
    off = (0.02, 0.1, 0.0)
    x0, x1 = project_to_pixel(spec, off, 0.0)[0], project_to_pixel(spec, off, 1.0)[0]
    assert x0 != x1
    expected = Camera(spec.camera, 1.0).view_proj(W / H) @ np.array([*off, 1.0])
    assert x1 == int((expected[0] / expected[3] + 1.0) * 0.5 * W)
    assert math.isfinite(x0)


def test_a_moving_cameras_ground_checker_stays_put_on_the_ground():
    """The ground's squares are world-fixed under a moving camera (one cell size over the shot, the centre on a
    two-cell lattice); a still camera keeps its own centre and cell as before."""
    from fraytool.render.camera import Camera
    from fraytool.render.renderer import ground_checker

    spec = CameraSpec(position_keys_m=((0.0, 0.0, 0.4, 0.5), (1.0, 0.37, 0.9, 1.3)),
                      target_keys_m=((0.0, 0.0, 0.0, 0.0), (1.0, 0.23, 0.0, -0.11)), interpolation="catmull_rom")
    up = np.array([0.0, 1.0, 0.0])
    cam0, cam1 = Camera(spec, 0.0), Camera(spec, 1.0)
    shot = max(np.linalg.norm(c.target - c.eye) for c in (cam0, cam1))
    (c0, cell0), (c1, cell1) = (ground_checker(c, up, -0.05, shot) for c in (cam0, cam1))
    assert cell0 == cell1
    points = np.random.default_rng(1).uniform(-1, 1, (200, 3)) * [1, 0, 1] + [0, -0.05, 0]

    def parity(centre, cell):
        d = points - centre
        return (np.floor(d[:, 0] / cell) + np.floor(d[:, 2] / cell)) % 2

    assert np.array_equal(parity(c0, cell0), parity(c1, cell1))
    (s0, k0), (s1, k1) = (ground_checker(c, up, -0.05) for c in (cam0, cam1))  # as a still camera would
    assert k0 != k1 or not np.array_equal(parity(s0, k0), parity(s1, k1))  # (which is why the moving one snaps)
    assert np.allclose(s0, [0.0, -0.05, 0.0])
