"""`fraytool render --motion-blur SHUTTER --motion-samples N` (issue 34, item 4; docs/rendering.md "Motion blur").

A ball of known radius flies across a square-on camera at a known constant speed (kinematic, gravity off,
the cloth far out of view); its streak in the image is checked against the camera's own geometry:
diameter + speed x shutter x frame time, in pixels at the ball's distance.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from fraytool.commands.main import main
from fraytool.render.color import encode_premultiplied_linear
from fraytool.render.exr import read_exr, read_exr_rgba
from fraytool.render.job import build_job
from fraytool.render.motion_blur import MotionBlur, interpolate_rotation
from fraytool.scene import parse_scene

RADIUS_M = 0.02
SPEED_M_S = 8.0
FRAME_S = 0.005            # step_s x steps_per_frame: the time between frame records
DISTANCE_M = 0.5           # camera to the ball's path
FOV_DEG = 30.0
W, H = 160, 90
SAMPLES = 8

SCENE = """
[scene]
name = "mb_ball"
seed = 1

[time]
step_s = 0.001
steps_per_frame = 5
frames = 3
fps = 24

[world]
gravity_m_s2 = [0.0, 0.0, 0.0]

[cloth]                      # far out of view
warp_yarns = 4
weft_yarns = 4
spacing_m = 0.01
thickness_m = 0.001
mass_per_crossing_kg = 1.0e-4
origin_m = [5.0, 5.0, 5.0]
plane = "xz"
weave = "plain"

[cloth.springs]
structural_n_per_m = 20.0
bend_n_per_m = 0.5
shear_n_per_m = 2.0
damping = 0.0

[[bodies]]
name = "ball"
shape = "sphere"
motion = "kinematic"
radius_m = {radius}
position_m = [-0.05, 0.0, 0.0]
velocity_m_s = [{speed}, 0.0, 0.0]
collide = false

[camera]
position_m = [0.0, 0.0, {distance}]
target_m = [0.0, 0.0, 0.0]
fov_deg = {fov}

[render]
resolution = [{w}, {h}]
samples = 4
ground_plane = false
"""

PIXELS_PER_M = H / (2.0 * DISTANCE_M * math.tan(math.radians(FOV_DEG) / 2.0))
"""Image pixels per metre in the plane of the ball's path (square-on camera)."""


def write_scene(folder: Path, speed: float = SPEED_M_S) -> Path:
    path = folder / "mb_ball.toml"
    path.write_text(SCENE.format(radius=RADIUS_M, speed=speed, distance=DISTANCE_M, fov=FOV_DEG, w=W, h=H))
    return path


def render(scene: Path, out: Path, *flags: str) -> None:
    assert main(["render", str(scene), "-o", str(out), "--png", "--no-mp4", *flags]) == 0


def png(out: Path, frame: int) -> np.ndarray:
    return np.asarray(Image.open(out / "png" / f"frame_{frame:06d}.png"))


def extent_px(alpha_row: np.ndarray, level: float) -> float:
    """Length [px] of the run of a row where the alpha (0..1) exceeds `level`, its ends interpolated
    linearly between pixel centres (sub-pixel)."""
    above = np.nonzero(alpha_row > level)[0]
    lo, hi = above.min(), above.max()
    assert np.all(alpha_row[lo:hi + 1] > level), "the streak has a gap"
    left = lo - (alpha_row[lo] - level) / (alpha_row[lo] - alpha_row[lo - 1])
    right = hi + (alpha_row[hi] - level) / (alpha_row[hi] - alpha_row[hi + 1])
    return float(right - left)


def centre_row(image: np.ndarray) -> np.ndarray:
    return image[H // 2 - 1: H // 2 + 1, :, 3].astype(np.float64).mean(axis=0) / 255.0


@pytest.fixture(scope="module")
def ball(tmp_path_factory):
    folder = tmp_path_factory.mktemp("mb")
    return write_scene(folder), folder / "out"


def test_a_moving_ball_leaves_a_streak_of_speed_times_shutter(ball):
    scene, out = ball
    render(scene, out, "--alpha", "--frames", "0:3")
    sharp = {f: png(out, f) for f in range(3)}
    diameter = extent_px(centre_row(sharp[1]), 0.5)
    assert diameter == pytest.approx(2 * RADIUS_M * PIXELS_PER_M, abs=1.0)
    for shutter in (0.5, 1.0):
        render(scene, out, "--alpha", "--frames", "0:3", "--motion-blur", str(shutter),
               "--motion-samples", str(SAMPLES))
        streak = SPEED_M_S * shutter * FRAME_S * PIXELS_PER_M
        assert streak > 6                                            # the streak is well above a pixel
        for f in range(3):  # frame 2 is the scene's last: its motion continues that from frame 1
            image = png(out, f)
            # the streak's ends are covered by one sub-frame of N: half of that is the edge of the ball
            measured = extent_px(centre_row(image), 0.5 / SAMPLES)
            assert measured == pytest.approx(diameter + streak, abs=1.0), (shutter, f)
            # it starts where the sharp ball is (the shutter opens on the frame) and trails ahead of it
            left_sharp = np.nonzero(centre_row(sharp[f]) > 0.5)[0].min()
            left_blur = np.nonzero(centre_row(image) > 0.5 / SAMPLES)[0].min()
            assert abs(int(left_blur) - int(left_sharp)) <= 1


def test_motion_blur_0_is_todays_frames_byte_for_byte(ball, tmp_path):
    scene, _ = ball
    plain, zero = tmp_path / "plain", tmp_path / "zero"
    render(scene, plain, "--frames", "1:2")
    render(scene, zero, "--frames", "1:2", "--motion-blur", "0", "--motion-samples", "4")
    assert (plain / "png" / "frame_000001.png").read_bytes() == (zero / "png" / "frame_000001.png").read_bytes()
    spec = parse_scene(scene.read_text(), str(scene))
    default = build_job(spec, _args(), tmp_path)
    assert default.motion_blur is None and default.target == "srgb8"
    for shutter in ("0", "0.0"):
        assert build_job(spec, _args(motion_blur=shutter), tmp_path).digest(4) == default.digest(4)


def test_a_still_scene_blurred_is_the_sharp_image(tmp_path):
    scene = write_scene(tmp_path, speed=0.0)
    sharp, blurred = tmp_path / "sharp", tmp_path / "blurred"
    render(scene, sharp, "--frames", "1:2")
    render(scene, blurred, "--frames", "1:2", "--motion-blur", "1", "--motion-samples", "5")
    a = png(sharp, 1).astype(int)
    b = png(blurred, 1).astype(int)
    assert a.shape == b.shape == (H, W, 3)
    assert np.abs(a - b).max() <= 1                      # averaged in linear light: not darker, not brighter
    assert (a != b).mean() < 0.01


def test_exr_and_png_are_blurred_alike(ball, tmp_path):
    scene, _ = ball
    out = tmp_path / "both"
    render(scene, out, "--alpha", "--exr", "--frames", "1:2", "--motion-blur", "0.5", "--motion-samples", "4")
    image = png(out, 1)
    exr = out / "exr" / "frame_000001.exr"
    encoded = encode_premultiplied_linear(read_exr_rgba(exr), 8, True)
    assert np.abs(encoded.astype(int) - image.astype(int)).max() <= 1
    streak = SPEED_M_S * 0.5 * FRAME_S * PIXELS_PER_M
    row = read_exr_rgba(exr)[H // 2 - 1: H // 2 + 1, :, 3].astype(np.float64).mean(axis=0)
    assert extent_px(row, 0.5 / 4) == pytest.approx(2 * RADIUS_M * PIXELS_PER_M + streak, abs=1.0)
    # depth: the nearest over the sub-frames, so along the streak (also where only the last sub-frames
    # reach, far from the ball at the frame's time) every pixel with coverage has one
    z = read_exr(exr)["Z"]
    alpha = read_exr_rgba(exr)[..., 3]
    covered = alpha[H // 2] > 0
    assert np.all(np.isfinite(z[H // 2][covered])) and np.all(np.isinf(z[alpha == 0]))
    assert covered.sum() > 2 * RADIUS_M * PIXELS_PER_M + streak - 1
    assert np.nanmin(z) == pytest.approx(DISTANCE_M - RADIUS_M, abs=2e-3)


@pytest.mark.parametrize("flags,needle", [
    (["--motion-blur", "1.5"], "--motion-blur '1.5': expected a number from 0 to 1"),
    (["--motion-blur", "-0.1"], "--motion-blur '-0.1': expected a number from 0 to 1"),
    (["--motion-blur", "half"], "--motion-blur 'half': expected a number from 0 to 1"),
    (["--motion-blur", "nan"], "--motion-blur 'nan': expected a number from 0 to 1"),
    (["--motion-blur", "0.5", "--motion-samples", "1"], "--motion-samples '1': expected a whole number from 2 to 64"),
    (["--motion-blur", "0.5", "--motion-samples", "65"], "--motion-samples '65': expected a whole number from 2 to 64"),
    (["--motion-samples", "x"], "--motion-samples 'x': expected a whole number from 2 to 64"),
])
def test_bad_motion_blur_flags_exit_2(ball, tmp_path, capsys, flags, needle):
    scene, _ = ball
    assert main(["render", str(scene), "-o", str(tmp_path), "--png", "--no-mp4", *flags]) == 2
    err = capsys.readouterr().err
    assert needle in err and "Traceback" not in err
    assert not (tmp_path / "frames").exists()                    # nothing simulated


def test_the_digest_follows_shutter_and_samples(ball, tmp_path):
    scene, _ = ball
    spec = parse_scene(scene.read_text(), str(scene))
    digests = {build_job(spec, _args(**kw), tmp_path).digest(4)
               for kw in ({}, dict(motion_blur="0.5"), dict(motion_blur="0.25"),
                          dict(motion_blur="0.5", motion_samples="16"))}
    assert len(digests) == 4
    job = build_job(spec, _args(motion_blur="0.5"), tmp_path)
    assert job.motion_blur == MotionBlur(0.5, 8) and job.target == "float"


def test_blurred_frames_are_kept_only_for_the_same_settings(ball, tmp_path):
    scene, _ = ball
    out = tmp_path / "keep"
    render(scene, out, "--frames", "1:2", "--motion-blur", "0.5", "--motion-samples", "4")
    first = (out / "png" / "frame_000001.png").read_bytes()
    render(scene, out, "--frames", "1:2", "--motion-blur", "0.5", "--motion-samples", "4")
    assert (out / "png" / "frame_000001.png").read_bytes() == first          # kept
    render(scene, out, "--frames", "1:2", "--motion-blur", "1", "--motion-samples", "4")
    assert (out / "png" / "frame_000001.png").read_bytes() != first          # drawn again


def test_sub_frame_rotations_are_slerped():
    def about_z(deg):
        c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
        return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])

    assert np.allclose(interpolate_rotation(about_z(0), about_z(90), 0.5), about_z(45), atol=1e-9)
    assert np.allclose(interpolate_rotation(about_z(10), about_z(30), 1.5), about_z(40), atol=1e-9)  # extrapolated
    assert np.allclose(interpolate_rotation(about_z(170), about_z(-170), 0.5), about_z(180), atol=1e-9)  # short way


def _args(**kw):
    from fraytool.render.options import RenderRequest

    return RenderRequest(png=True, video=False, **kw)


def test_the_python_api_renders_with_motion_blur(ball, tmp_path):
    from fraytool import api

    scene, _ = ball
    out = api.render(scene, out_dir=tmp_path / "api", frames="1:2", png=True, video=False, motion_blur=0.5,
                     motion_samples=SAMPLES, alpha=True)
    streak = SPEED_M_S * 0.5 * FRAME_S * PIXELS_PER_M
    assert extent_px(centre_row(png(out, 1)), 0.5 / SAMPLES) == pytest.approx(
        2 * RADIUS_M * PIXELS_PER_M + streak, abs=1.0)


def test_the_farm_renders_the_same_blurred_frames_as_render(ball, tmp_path):
    """A batch shot with motion blur (its tasks run in-process, as a worker runs them): the simulation
    task also runs the frame after the range, and the chunk's PNG is byte for byte `fraytool render`'s."""
    from fraytool.errors import InputError
    from fraytool.farm import tasks
    from fraytool.farm.shots import RenderOptions, expand, load_job

    scene, _ = ball
    (shot,) = expand(str(scene), [], [], RenderOptions(frames="0:2", motion_blur=0.5, motion_samples=4))
    (sharp,) = expand(str(scene), [], [], RenderOptions(frames="0:2"))
    out = tmp_path / "shot"
    assert (tasks.frames_to_simulate(shot, out), tasks.frames_to_simulate(sharp, out)) == (3, 2)
    tasks.simulate_task(shot, str(out), tasks.frames_to_simulate(shot, out))
    tasks.render_chunk_task(shot, str(out), 0, 2, 1)
    ref = tmp_path / "ref"
    render(scene, ref, "--frames", "0:2", "--motion-blur", "0.5", "--motion-samples", "4")
    for k in range(2):
        name = f"frame_{k:06d}.png"
        assert (out / "png" / name).read_bytes() == (ref / "png" / name).read_bytes(), name
    job = tmp_path / "job.toml"
    job.write_text(f'[render]\nmotion_blur = 0.25\nmotion_samples = 6\n[[shots]]\nscene = "{scene}"\n')
    (loaded,) = load_job(job).shots
    assert (loaded.render.motion_blur, loaded.render.motion_samples) == (0.25, 6)
    for bad, needle in (("motion_blur = 2", "motion_blur = 2: expected a number from 0 to 1"),
                        ("motion_samples = 1", "motion_samples = 1: expected a whole number from 2 to 64")):
        job.write_text(f'[render]\n{bad}\n[[shots]]\nscene = "{scene}"\n')
        with pytest.raises(InputError, match=needle):
            load_job(job)


def test_bad_batch_motion_blur_flags_exit_2(capsys):
    assert main(["batch", "drape", "--motion-blur", "3"]) == 2
    assert "--motion-blur '3': expected a number from 0 to 1" in capsys.readouterr().err
