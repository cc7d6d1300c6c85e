"""Outputs for a studio pipeline (issue 13): the float colour target, 16-bit PNGs, EXR with Z, ProRes 4444.

Independent references: depth against ray casts of the known ground plane and ball, computed here from
the camera; images and videos decoded by the ffmpeg binary imageio-ffmpeg ships; EXRs read by OpenEXR.
"""
from __future__ import annotations

import dataclasses
import math
import re
from pathlib import Path

import numpy as np
import pytest

from fraytool.commands.main import main
from fraytool.render.camera import perspective, window_depth_to_distance
from fraytool.render.color import encode_premultiplied_linear, over_background, srgb_to_linear
from fraytool.render.geometry import GeometryBuilder, YarnStyle
from fraytool.render.png16 import read_png16
from fraytool.render.renderer import Renderer
from fraytool.scene import load_scene
from test_render_encode import decode_rgba64, probe

SCENE = Path(__file__).resolve().parent / "scenes" / "golden_small.toml"

# A level camera at the height of the golden scene's ball (centre (0, 0.02, 0), radius 0.035), looking
# along -z: the ground plane (y = -0.015) fills the bottom rows, the sky the top ones.
EYE = (0.0, 0.02, 0.3)
TARGET = (0.0, 0.02, 0.0)
BALL_CENTRE, BALL_RADIUS, GROUND_Y = np.array([0.0, 0.02, 0.0]), 0.035, -0.015
SIZE = (64, 48)
LEVEL_FLAGS = ["--resolution", "64x48", "--samples", "1", "--camera-position", "0,0.02,0.3",
               "--camera-target", "0,0.02,0", "--frames", "0:1"]


def pixel_rays(size, fov_deg):
    """View-space direction of the ray through each pixel centre, scaled to -1 along the view axis, so
    that a hit at parameter t lies at distance t along the view axis. (H, W, 3), top row first."""
    w, h = size
    tan = math.tan(math.radians(fov_deg) / 2.0)
    x = (2.0 * (np.arange(w) + 0.5) / w - 1.0) * tan * w / h
    y = (1.0 - 2.0 * (np.arange(h) + 0.5) / h) * tan
    X, Y = np.meshgrid(x, y)
    return np.stack([X, Y, -np.ones_like(X)], axis=-1)


def expected_depth(fov_deg: float, radius: float = BALL_RADIUS) -> np.ndarray:
    """Distance along the view axis to the ground plane or the ball (a sphere of `radius`) for the level
    camera, inf where the ray meets neither, and where the ball is hit. The camera at EYE looks along -z
    with +y up, so view and world axes coincide."""
    d = pixel_rays(SIZE, fov_deg)
    eye = np.asarray(EYE)
    with np.errstate(divide="ignore", invalid="ignore"):
        t_ground = np.where(d[..., 1] < 0, (GROUND_Y - eye[1]) / d[..., 1], np.inf)
    oc = eye - BALL_CENTRE
    a = (d * d).sum(-1)
    b = 2.0 * (d * oc).sum(-1)
    c = oc @ oc - radius ** 2
    disc = b * b - 4 * a * c
    t_ball = np.where(disc >= 0, (-b - np.sqrt(np.maximum(disc, 0))) / (2 * a), np.inf)
    return np.minimum(t_ground, t_ball), t_ball < t_ground


def test_window_depth_converts_back_to_the_view_distance():
    """Project points at known distances with the renderer's own perspective matrix, map to window depth
    as GL does (d = (z_ndc + 1) / 2) and convert back."""
    near, far = 0.001, 40.0
    P = perspective(45.0, 1.5, near, far)
    distances = np.array([near, 0.01, 0.3, 1.0, 7.5, far])
    clip = P @ np.stack([np.zeros_like(distances), np.zeros_like(distances), -distances, np.ones_like(distances)])
    d = (clip[2] / clip[3] + 1.0) / 2.0
    np.testing.assert_allclose(window_depth_to_distance(d, near, far), distances, rtol=1e-5)
    assert window_depth_to_distance(np.array([1.0]), near, far)[0] == np.inf    # cleared: nothing drawn


def _render(ctx, pc, record, camera=None, render=None, size=(160, 120), **kwargs):
    render = render or pc.spec.render
    renderer = Renderer(ctx, size, render.samples, render, camera or pc.spec.camera, pc.topology, **kwargs)
    try:
        builder = GeometryBuilder(pc.topology, YarnStyle.from_spec(render, pc.topology), renderer.camera, size[1])
        renderer.draw(builder.build(record))
        out = {"image": renderer.read().copy()}
        if renderer.target == "float":
            out["linear"] = renderer.read_linear().copy()
        if kwargs.get("depth"):
            out["depth"] = renderer.read_depth_m().copy()
        return out
    finally:
        renderer.release()


def test_float_target_draws_the_8bit_image_to_rounding(gl_ctx, posed_cloth):
    """The float target blends and resolves like the sRGB8 one: encoded on the CPU it gives the default
    8-bit image back but for rounding (and a few highlight edges, which it does not clamp before
    the resolve), with and without alpha."""
    rec = posed_cloth.torn()
    for alpha in (False, True):
        base = _render(gl_ctx, posed_cloth, rec, alpha=alpha)["image"].astype(int)
        drawn = _render(gl_ctx, posed_cloth, rec, alpha=alpha, target="float")
        diff = np.abs(drawn["image"].astype(int) - base)
        assert np.sqrt((diff.astype(float) ** 2).mean()) < 0.5 and (diff > 2).mean() < 0.003, (alpha, diff.max())
        a = drawn["linear"][..., 3]
        if alpha:
            opaque = a >= 1 - 1e-6                                          # (float blending: 1 - 1 ulp)
            assert ((a > 0) & ~opaque).sum() > 20 and opaque.sum() > 200     # (the ground plane covers the rest)
        else:
            np.testing.assert_allclose(a, 1.0, atol=1e-6)         # (float blending: 1 - 1 ulp here and there)


def test_16bit_straight_alpha_composites_back_to_the_opaque_render(gl_ctx, posed_cloth):
    """16-bit straight alpha made from the float target, composited over the background in linear
    light, gives the opaque 16-bit render back (to a 16-bit level where the alpha is not tiny), and its
    alpha is the 8-bit render's alpha at 16 bits."""
    rec = posed_cloth.torn()
    render = dataclasses.replace(posed_cloth.spec.render, ground_plane=False)
    rgba = _render(gl_ctx, posed_cloth, rec, render=render, alpha=True, target="float")
    rgb16 = encode_premultiplied_linear(
        _render(gl_ctx, posed_cloth, rec, render=render, target="float")["linear"], 16, alpha=False)
    rgba16 = encode_premultiplied_linear(rgba["linear"], 16, alpha=True)
    assert rgba16.dtype == np.uint16 and rgba16.shape == (120, 160, 4) and rgb16.shape == (120, 160, 3)
    a = rgba16[..., 3]
    partial = (a > 0) & (a < 65535)
    assert a[0, 0] == 0 and partial.sum() > 20
    back = over_background(rgba16, render.background).astype(int)
    diff = np.abs(back - rgb16.astype(int)).max(axis=2)
    assert diff[a == 0].max() <= 1 and np.percentile(diff[a > 2000], 99) <= 257, np.percentile(diff[a > 2000], 99)
    a8 = _render(gl_ctx, posed_cloth, rec, render=render, alpha=True)["image"][..., 3].astype(int)
    assert np.abs(a.astype(int) / 257.0 - a8).max() <= 1.01


@pytest.mark.parametrize("shadows", [False, True], ids=["plain", "shadows"])
def test_depth_is_the_distance_along_the_view_axis(gl_ctx, posed_cloth, shadows):
    """Z of the ground plane and of the ball against ray casts: on the ground every pixel of a row has
    the same Z (a distance along the view axis, not to the eye), the ball's front its known distance,
    the sky +inf. One sample per pixel, so Z is that of the pixel centre. With shadows the ground is
    drawn as for an EXR (one piece: no polygon offset moves its depth)."""
    camera = dataclasses.replace(posed_cloth.spec.camera, position_m=EYE, target_m=TARGET)
    render = dataclasses.replace(posed_cloth.spec.render, samples=0, shadows=shadows)
    z = _render(gl_ctx, posed_cloth, posed_cloth.copy(), camera=camera, render=render, size=SIZE,
                target="float", depth=True)["depth"]
    want, on_ball = expected_depth(camera.fov_deg)
    assert z.shape == (48, 64) and z.dtype == np.float32
    np.testing.assert_allclose(z[-6:], want[-6:], rtol=1e-4)              # ground: exact plane
    # constant along a row to a few 24-bit depth steps (each about 3e-7 m here); a distance to the eye
    # would vary by percents from the row's middle to its ends
    assert np.ptp(z[-1]) < 1e-4 * z[-1].mean()
    # the ball is a UV sphere of 7.5 degree facets, whose surface lies between the sphere and the sphere
    # of radius r cos(7.5 degrees) inside it
    inner, _ = expected_depth(camera.fov_deg, BALL_RADIUS * math.cos(math.radians(7.5)))
    rows, cols = np.nonzero(on_ball)
    front = (np.abs(rows - 23.5) + np.abs(cols - 31.5) <= 6)                # near the axis
    r, c = rows[front], cols[front]
    assert (z[r, c] >= want[r, c] - 1e-5).all() and (z[r, c] <= inner[r, c] + 1e-5).all()
    assert abs(z[23, 31] - (0.3 - BALL_RADIUS)) < 5e-4                     # 0.265 m from the camera plane
    assert np.isinf(z[:6]).all()                                            # sky


def test_exr_holds_linear_premultiplied_rgba_and_z(tmp_path, capsys):
    """`render --exr`: <out>/exr/frame_NNNNNN.exr with R, G, B, A (half) and Z (float): the background
    is the scene colour in linear light with A = 1, or transparent black with --alpha; Z is the ground's
    and the ball's distance along the view axis; the 16-bit PNG of the same render is the EXR encoded."""
    import OpenEXR

    from fraytool.render.exr import read_exr

    out = tmp_path / "out"
    assert main(["render", str(SCENE), "-o", str(out), *LEVEL_FLAGS, "--exr", "--png", "--depth", "16",
                 "--no-mp4"]) == 0
    path = out / "exr" / "frame_000000.exr"
    with OpenEXR.File(str(path), separate_channels=True) as f:
        kinds = {name: ch.pixels.dtype for name, ch in f.channels().items()}
    assert kinds == {"R": np.float16, "G": np.float16, "B": np.float16, "A": np.float16, "Z": np.float32}
    opaque = read_exr(path)
    spec = load_scene(SCENE)
    background = srgb_to_linear(spec.render.background)
    np.testing.assert_allclose([opaque[c][0, 0] for c in "RGB"], background, rtol=2e-3)
    np.testing.assert_array_equal(opaque["A"], 1.0)
    want, _ = expected_depth(spec.camera.fov_deg)
    np.testing.assert_allclose(opaque["Z"][-6:], want[-6:], rtol=1e-4)
    assert abs(opaque["Z"][23, 31] - (0.3 - BALL_RADIUS)) < 5e-4 and np.isinf(opaque["Z"][:6]).all()
    rgba = np.stack([opaque[c].astype(np.float32) for c in "RGBA"], axis=-1)
    png = read_png16(out / "png" / "frame_000000.png")
    assert png.shape == (48, 64, 3)                                     # RGB without --alpha
    assert np.abs(png.astype(int) - encode_premultiplied_linear(rgba, 16, alpha=False)).max() <= 40  # half vs float
    assert "1 rendered, 0 kept" in capsys.readouterr().err

    assert main(["render", str(SCENE), "-o", str(out), *LEVEL_FLAGS, "--exr", "--alpha", "--no-mp4"]) == 0
    assert "1 rendered, 0 kept" in capsys.readouterr().err            # other settings: drawn again
    clear = read_exr(path)
    assert [float(clear[c][0, 0]) for c in "RGBA"] == [0.0, 0.0, 0.0, 0.0]   # transparent black sky
    assert clear["A"][23, 31] == 1.0 and clear["A"][-1, 0] == 1.0          # ball and near ground opaque
    np.testing.assert_array_equal(clear["Z"], opaque["Z"])
    # premultiplied in linear light: colour + background x (1 - A) is the opaque render
    a = clear["A"].astype(np.float32)[..., None]
    composite = np.stack([clear[c] for c in "RGB"], -1).astype(np.float32) + background * (1.0 - a)
    np.testing.assert_allclose(composite, rgba[..., :3], rtol=4e-3, atol=1e-3)
    assert main(["render", str(SCENE), "-o", str(out), *LEVEL_FLAGS, "--exr", "--alpha", "--no-mp4"]) == 0
    assert "0 rendered, 1 kept" in capsys.readouterr().err            # the same settings: kept


def test_prores_render_carries_the_alpha_of_the_16bit_pngs_and_resumes(tmp_path, capsys):
    """`render --codec prores` writes <scene>.mov, ProRes 4444 with an alpha plane (the background is made
    transparent, and it says so); decoded by ffmpeg it matches the 16-bit RGBA PNGs of the same render:
    alpha 0 in the background, 1 on the cloth, partial at the anti-aliased edges, the colour to a few
    10-bit steps. Run again, it keeps the PNGs and rebuilds the same video from them."""
    out = tmp_path / "out"
    flags = ["render", str(SCENE), "-o", str(out), "--resolution", "64x48", "--frames", "0:2", "--codec", "prores",
             "--png", "--depth", "16", "--set", "render.ground_plane=false", "--set", "render.far_field=false"]
    assert main(flags) == 0
    err = capsys.readouterr().err
    assert "ProRes 4444 carries alpha" in err and "2 rendered, 0 kept" in err
    mov = out / "golden_small_000000-000002.mov"
    p = probe(mov)
    assert p["codec"] == "prores" and p["pix_fmt"].startswith("yuva444p") and p["frames"] == 2 and p["fps"] == 24
    video = decode_rgba64(mov, (64, 48)).astype(int)
    png = read_png16(out / "png" / "frame_000000.png").astype(int)
    assert png.shape == (48, 64, 4)
    a_png, a_mov = png[..., 3], video[..., 3]
    assert a_png[0, 0] == 0 and a_mov[0, 0] == 0                          # background
    assert a_png[24, 32] == 65535 and a_mov[24, 32] >= 65535 - 32         # the cloth
    partial = (a_png > 1000) & (a_png < 64000)
    assert partial.sum() > 10 and np.abs(a_mov - a_png)[partial].max() <= 64
    opaque = a_png == 65535
    assert np.percentile(np.abs(video - png)[..., :3][opaque], 95) <= 4 * 64
    (out / "png" / "frame_000001.png").unlink()
    assert main(flags) == 0
    assert "1 rendered, 1 kept" in capsys.readouterr().err
    assert np.array_equal(decode_rgba64(mov, (64, 48)).astype(int), video)  # frame 0 from its 16-bit PNG


def test_output_flags_refuse_bad_values(tmp_path, capsys):
    """--depth, --codec and their combinations: exit 2 with one line naming the flag, the value and what is
    allowed; nothing simulated."""
    cases = [(["--depth", "12"], "--depth '12': expected 8 or 16"),
             (["--depth", "16"], "--depth 16 sets the bit depth of the PNG sequence"),
             (["--codec", "prores", "--no-mp4", "--png"], "--codec prores chooses the video codec")]
    for flags, needle in cases:
        assert main(["render", str(SCENE), "-o", str(tmp_path), *flags]) == 2
        err = capsys.readouterr().err
        assert needle in err and "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    with pytest.raises(SystemExit) as stop:
        main(["render", str(SCENE), "-o", str(tmp_path), "--codec", "vp9"])
    assert stop.value.code == 2
    assert re.search(r"--codec: invalid choice: 'vp9' \(choose from '?h264'?, '?prores'?\)", capsys.readouterr().err)
    assert not (tmp_path / "frames").exists()


def test_prores_takes_odd_sizes_that_h264_refuses(tmp_path, capsys):
    assert main(["render", str(SCENE), "-o", str(tmp_path), "--resolution", "33x25", "--codec", "prores",
                 "--frames", "0:1"]) == 0
    assert probe(tmp_path / "golden_small_000000-000001.mov")["size"] == (33, 25)
    assert main(["render", str(SCENE), "-o", str(tmp_path), "--resolution", "33x25", "--frames", "0:1"]) == 2
    assert "even width and height" in capsys.readouterr().err


def test_a_changed_renderer_or_gl_draws_the_frames_again(tmp_path, capsys, monkeypatch):
    """The reuse key covers what changes pixels beyond the settings: the renderer's own code and the GL
    renderer and version that draw. Kept with nothing changed; drawn again when either changes."""
    import fraytool.render.job as job
    import fraytool.render.sequence as sequence

    out = tmp_path / "out"
    args = ["render", str(SCENE), "-o", str(out), *LEVEL_FLAGS, "--png", "--no-mp4"]
    assert main(args) == 0 and "1 rendered, 0 kept" in capsys.readouterr().err
    assert main(args) == 0 and "0 rendered, 1 kept" in capsys.readouterr().err
    real = job.renderer_code_digest
    monkeypatch.setattr(job, "renderer_code_digest", lambda *a: real(*a) + "-edited")
    assert main(args) == 0 and "1 rendered, 0 kept" in capsys.readouterr().err   # a renderer module changed
    monkeypatch.setattr(job, "renderer_code_digest", real)
    assert main(args) == 0 and "1 rendered, 0 kept" in capsys.readouterr().err   # back: drawn again too
    monkeypatch.setattr(sequence, "gl_strings", lambda ctx: "llvmpipe (LLVM 99.0, 256 bits); 4.5 (Core Profile) Mesa 99.0")
    assert main(args) == 0 and "1 rendered, 0 kept" in capsys.readouterr().err   # another Mesa


def test_the_renderer_code_digest_follows_its_modules_only(tmp_path):
    """A copy of the package: editing a module of fraytool.render changes the digest; a simulation module
    does not."""
    import shutil

    from fraytool.render.job import renderer_code_digest

    package = Path(__file__).resolve().parents[1] / "fraytool"
    copy = tmp_path / "fraytool"
    shutil.copytree(package, copy, ignore=shutil.ignore_patterns("__pycache__", "*.nbi", "*.nbc"))
    before = renderer_code_digest(copy)
    assert before == renderer_code_digest(package)
    (copy / "sim" / "model.py").write_text((copy / "sim" / "model.py").read_text() + "\n# a comment\n")
    assert renderer_code_digest(copy) == before
    (copy / "render" / "tube.py").write_text((copy / "render" / "tube.py").read_text() + "\n# a comment\n")
    assert renderer_code_digest(copy) != before
