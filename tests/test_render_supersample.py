"""Supersampling ([render] supersample = k, fraytool.render.renderer): the frame drawn at k times the size in
each axis and each output pixel the mean of its k x k drawn pixels in linear light.

Checked against a slow reference: the same frame drawn at the k x size without supersampling and averaged
by NumPy (fraytool.render.aliasing.box_downsample); and against the far field's aliasing measure (a weave
under two pixels comes nearer its 4x picture)."""
from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from conftest import GOLDEN_SCENE, PosedCloth
from fraytool.errors import InputError
from fraytool.render.aliasing import blurred_rms
from fraytool.render.renderer import Renderer
from test_render_farfield import FLAT, _draw as _draw_frame, _reference, _view, _with


@pytest.fixture(scope="module")
def small():
    return PosedCloth(GOLDEN_SCENE)


def _draw(ctx, spec, pc, record, size, target="srgb8", alpha=False, depth=False, wireframe="off"):
    image, _, z = _draw_frame(ctx, spec, pc, record, size, target=target, alpha=alpha, depth=depth, wireframe=wireframe)
    return image, z


def _block_mean(a: np.ndarray, k: int) -> np.ndarray:
    H, W = a.shape[0] // k, a.shape[1] // k
    return a.reshape(H, k, W, k, -1).astype(np.float64).mean(axis=(1, 3))


@pytest.mark.parametrize("k", [2, 3])
def test_each_pixel_is_the_linear_mean_of_its_drawn_block(gl_ctx, small, k):
    """Float target, transparent background: colour (premultiplied) and alpha are NumPy's k x k means of the
    frame drawn at k x the size (the torn frame: yarns, fading ends, the ball, the ground)."""
    size = (160, 120)
    rec = small.torn()
    spec = small.spec
    fine, _ = _draw(gl_ctx, spec, small, rec, (size[0] * k, size[1] * k), target="float", alpha=True)
    out, _ = _draw(gl_ctx, _with(spec, supersample=k), small, rec, size, target="float", alpha=True)
    assert out.shape == (size[1], size[0], 4)
    assert np.abs(out - _block_mean(fine, k)).max() < 1e-5


def test_the_8bit_output_is_the_encoded_mean(gl_ctx, small):
    """The 8-bit frame (drawn in float, encoded by GL on the downsample's write) is the sRGB encoding of the
    linear mean, within a level, and brighter than a mean of the encoded values where the picture varies
    (the encoding is concave)."""
    from fraytool.render.color import encode_premultiplied_linear

    size, k = (160, 120), 2
    rec = small.torn()
    fine, _ = _draw(gl_ctx, small.spec, small, rec, (size[0] * k, size[1] * k), target="float")
    out, _ = _draw(gl_ctx, _with(small.spec, supersample=k), small, rec, size)
    want = encode_premultiplied_linear(_block_mean(fine, k).astype(np.float32), 8, False)
    assert np.abs(out.astype(int) - want.astype(int)).max() <= 1
    encoded_mean = _block_mean(encode_premultiplied_linear(fine, 8, False), k)
    assert (out >= np.floor(encoded_mean) - 1).all() and out.astype(float).sum() > encoded_mean.sum()


def test_depth_is_the_nearest_of_the_block(gl_ctx, small):
    size, k = (160, 120), 2
    rec = small.draped()
    _, fine = _draw(gl_ctx, small.spec, small, rec, (size[0] * k, size[1] * k), target="float", depth=True)
    _, out = _draw(gl_ctx, _with(small.spec, supersample=k), small, rec, size, target="float", depth=True)
    want = fine.reshape(size[1], k, size[0], k).min(axis=(1, 3))
    finite = np.isfinite(want)
    assert finite.mean() > 0.5 and np.array_equal(np.isfinite(out), finite)
    assert np.abs(out[finite] - want[finite]).max() < 1e-4


@pytest.mark.parametrize("k", [2, 3])
def test_wireframe_lines_keep_their_output_width(gl_ctx, small, k):
    """Lines are drawn k drawn pixels wide, so the wireframe view shows them as without supersampling: the
    lines' ink (the view's difference from the same view without its lines, the ball and ground alone, summed
    in linear light) within 6 % of the unsupersampled view's. Drawn 1 drawn pixel wide, they had 56 % (k = 2)
    and 39 % (k = 3) of it."""
    from fraytool.render.color import srgb_to_linear

    size = (160, 120)
    rec = small.torn()

    def ink(k: int) -> float:
        spec = _with(small.spec, supersample=k)
        r = Renderer(gl_ctx, size, spec.render.samples, spec.render, spec.camera, small.topology, "only")
        try:
            builder = r.geometry_builder(small.topology)
            views = []
            for lines in (True, False):
                r.draw(builder.build(rec, yarns=False, lines=lines))
                views.append(srgb_to_linear(r.read().astype(np.float64) / 255.0))
        finally:
            r.release()
        return float(np.abs(views[0] - views[1]).sum())

    one, many = ink(1), ink(k)
    assert one > 100.0 and 0.94 < many / one < 1.06, (one, many)


def test_a_weave_under_two_pixels_comes_nearer_its_4x_picture(gl_ctx):
    """The far field's view of a weave at 1.2 px a crossing, 40 degrees over the cloth: with supersample 2
    the yarns stay yarns down to 1.5 output pixels and each pixel holds 4 x 4 samples; its aliasing error
    (blurred RMS against the frame drawn with yarns at 4x) falls by at least a quarter."""
    pc = PosedCloth(FLAT)
    size = (160, 90)
    spec = _view(pc.spec, 40.0, 20.0, 1.8, size[1])
    ref = _reference(gl_ctx, spec, pc, pc.rest, size)
    errors = [blurred_rms(_draw(gl_ctx, _with(spec, supersample=k), pc, pc.rest, size)[0], ref) for k in (1, 2)]
    assert errors[1] < 0.75 * errors[0], errors


def test_a_frame_too_large_for_the_context_is_a_clear_error(gl_ctx, small):
    """Refused before any GL allocation, naming the resolution, the supersample and the drawn size."""
    limit = int(gl_ctx.info["GL_MAX_TEXTURE_SIZE"])
    side = limit // 2 + 2
    spec = _with(small.spec, supersample=2)
    with pytest.raises(InputError, match=rf"resolution = \[{side}, 2\] and supersample = 2 draws {2 * side}x4 "
                                         rf"pixels; this GL context draws at most {limit} a side: lower supersample"):
        Renderer(gl_ctx, (side, 2), 0, spec.render, spec.camera, small.topology)


def test_render_refuses_a_frame_too_large_before_simulating(tmp_path):
    from helpers import small_scene_text

    scene = tmp_path / "s.toml"
    scene.write_text(small_scene_text(frames=2))
    run = subprocess.run([sys.executable, "-m", "fraytool", "render", str(scene), "--resolution", "6000x16",
                          "--supersample", "3", "--no-mp4", "--png", "-o", str(tmp_path / "out")],
                         capture_output=True, text=True)
    assert run.returncode == 2 and "resolution = [6000, 16] and supersample = 3 draws 18000x48 pixels" in run.stderr
    assert not (tmp_path / "out" / "frames").exists(), "it simulated first"


@pytest.mark.parametrize("value", ["5", "0", "2.5", "two"])
def test_supersample_out_of_range_is_refused_on_the_command_line(value):
    run = subprocess.run([sys.executable, "-m", "fraytool", "render", "drape", "--supersample", value, "--no-mp4",
                          "--png", "-o", "/nonexistent/x"], capture_output=True, text=True)
    assert run.returncode == 2 and f"--supersample {value}: expected an integer from 1 to 4" in run.stderr, run.stderr


@pytest.mark.parametrize("command", [["check", "--set", "render.supersample=4"],
                                     ["batch", "--supersample", "4", "-o", "OUT"]])
def test_check_and_batch_refuse_a_frame_too_large_before_running(tmp_path, command):
    """`fraytool check` and `fraytool batch` (before a cluster starts) refuse what `render` refuses."""
    from helpers import small_scene_text

    scene = tmp_path / "s.toml"
    scene.write_text(small_scene_text(frames=2))
    rest = [str(tmp_path / "out") if a == "OUT" else a for a in command[1:]]
    run = subprocess.run([sys.executable, "-m", "fraytool", command[0], str(scene), *rest,
                          "--set", "render.resolution=[4200,360]"], capture_output=True, text=True)
    assert run.returncode == 2, run.stderr
    assert "resolution = [4200, 360] and supersample = 4 draws 16800x1440 pixels; this GL context draws at most" \
        in run.stderr, run.stderr
    assert not (tmp_path / "out").exists()
