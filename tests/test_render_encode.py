"""PNG (8 and 16 bit) and video output (H.264 MP4, ProRes 4444 .mov): files are probed and decoded with the
ffmpeg binary imageio-ffmpeg ships; writes are atomic."""
from __future__ import annotations

import os
import re
import subprocess

import imageio_ffmpeg
import numpy as np
import pytest

from fraytool.errors import InputError
from fraytool.render.encode import (
    VideoWriter,
    partial_path,
    png_settings,
    read_png,
    remove_stale_partials,
    write_png,
)
from fraytool.render.png16 import decode_png16, read_png16, write_png16


def probe(path) -> dict:
    """Codec, pixel format, size and fps from `ffmpeg -i`, and the frame count by decoding."""
    exe = imageio_ffmpeg.get_ffmpeg_exe()
    info = subprocess.run([exe, "-hide_banner", "-i", str(path)], capture_output=True, text=True).stderr
    video = next(line for line in info.splitlines() if "Video:" in line)
    m = re.search(r"Video: (\w+).*?, (\w+)(?:\(.*?\))?, (\d+)x(\d+).*?, ([\d.]+) fps", video)
    assert m, video
    decoded = subprocess.run([exe, "-hide_banner", "-i", str(path), "-map", "0:v:0", "-f", "null", "-"],
                             capture_output=True, text=True).stderr
    frames = int(re.findall(r"frame=\s*(\d+)", decoded)[-1])
    return {"codec": m.group(1), "pix_fmt": m.group(2), "size": (int(m.group(3)), int(m.group(4))),
            "fps": float(m.group(5)), "frames": frames}


def _frames(n, w=64, h=48):
    rng = np.random.default_rng(5)
    base = rng.integers(0, 255, (h, w, 3), dtype=np.uint8)
    return [np.roll(base, 2 * k, axis=1) for k in range(n)]


def test_mp4_carries_bt709_tags_and_the_matching_matrix(tmp_path):
    """Tagged BT.709, limited range, and encoded with the BT.709 matrix: a saturated red decodes back
    to red with that matrix (BT.601's would shift it by tens of levels)."""
    path = tmp_path / "clip.mp4"
    red = np.zeros((48, 64, 3), np.uint8)
    red[..., 0] = 200
    with VideoWriter(path, (64, 48), 24) as w:
        for _ in range(3):
            w.write(red)
    exe = imageio_ffmpeg.get_ffmpeg_exe()
    info = subprocess.run([exe, "-hide_banner", "-i", str(path)], capture_output=True, text=True).stderr
    assert "yuv420p(tv, bt709, progressive)" in info, info         # matrix, primaries and transfer all BT.709
    raw = subprocess.run([exe, "-v", "error", "-i", str(path), "-vf", "scale=in_color_matrix=bt709:in_range=tv",
                          "-frames:v", "1", "-f", "rawvideo", "-pix_fmt", "rgb24", "-"], capture_output=True).stdout
    back = np.frombuffer(raw, np.uint8).reshape(48, 64, 3)[20:28, 28:36].astype(int)
    assert np.abs(back - [200, 0, 0]).max() <= 4, back.mean(axis=(0, 1))


@pytest.mark.parametrize("fps", [24.0, 25.0])
def test_mp4_is_h264_yuv420p_with_size_fps_and_frame_count(tmp_path, fps):
    path = tmp_path / "clip.mp4"
    with VideoWriter(path, (64, 48), fps) as w:
        for f in _frames(7):
            w.write(f)
    p = probe(path)
    assert p == {"codec": "h264", "pix_fmt": "yuv420p", "size": (64, 48), "fps": fps, "frames": 7}
    data = path.read_bytes()
    assert data.index(b"moov") < data.index(b"mdat")             # +faststart: index first
    assert not list(tmp_path.glob(".*partial*"))                 # temp file renamed away


def test_odd_sizes_are_refused_clearly(tmp_path):
    with pytest.raises(InputError, match="even width and height.*66x48"):
        VideoWriter(tmp_path / "x.mp4", (65, 48), 24)
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize("codec,suffix", [("h264", ".mp4"), ("prores", ".mov")])
def test_interrupted_encode_leaves_no_file_and_keeps_the_old_one(tmp_path, codec, suffix):
    path = tmp_path / f"clip{suffix}"
    path.write_bytes(b"previous finished video")
    with pytest.raises(KeyboardInterrupt):
        with VideoWriter(path, (64, 48), 24, codec=codec) as w:
            for f in _frames(3):
                w.write(f)
            assert w.tmp.name.startswith(".clip.partial-") and w.tmp.suffix == suffix
            raise KeyboardInterrupt
    assert path.read_bytes() == b"previous finished video"
    assert sorted(p.name for p in tmp_path.iterdir()) == [path.name]


@pytest.mark.parametrize("suffix", [".mp4", ".mov", ".usd"])
def test_stale_partials_of_dead_runs_are_removed(tmp_path, suffix):
    path = tmp_path / f"clip{suffix}"
    mine = partial_path(path)
    dead = mine.with_name(mine.name.replace(f"-{os.getpid()}{suffix}", f"-999999999{suffix}"))
    other_host = tmp_path / f".clip.partial-elsewhere-999999999{suffix}"
    other_kind = tmp_path / ".clip.partial-elsewhere-999999999.xyz"
    for p in (mine, dead, other_host, other_kind):
        p.write_bytes(b"x")
    remove_stale_partials(path)
    assert not dead.exists() and mine.exists() and other_host.exists() and other_kind.exists()


def test_png_is_atomic_tagged_and_round_trips(tmp_path):
    img = _frames(1, 33, 17)[0]                                   # odd sizes are fine for PNG
    path = tmp_path / "png" / "frame_000003.png"
    write_png(path, img, "abc123")
    assert np.array_equal(read_png(path), img)
    assert png_settings(path) == ("abc123", (33, 17))
    assert [p.name for p in path.parent.iterdir()] == ["frame_000003.png"]     # no temp files left
    assert os.stat(path).st_mode & 0o044                           # readable by others (umask), not 0600
    (tmp_path / "bad.png").write_bytes(b"not a png")
    assert png_settings(tmp_path / "bad.png") is None


def decode_rgba64(path, size, frame_filter=()) -> np.ndarray:
    """The first frame of an image or video file as (H, W, 4) uint16, decoded by ffmpeg."""
    raw = subprocess.run([imageio_ffmpeg.get_ffmpeg_exe(), "-v", "error", "-i", str(path), *frame_filter,
                          "-frames:v", "1", "-f", "rawvideo", "-pix_fmt", "rgba64le", "-"],
                         capture_output=True, check=True).stdout
    return np.frombuffer(raw, "<u2").reshape(size[1], size[0], 4)


def test_prores_4444_keeps_colour_and_partial_alpha(tmp_path):
    """ProRes 4444 in a .mov: codec, profile, alpha plane and BT.709 tags as ffmpeg reports them; decoded,
    straight colour comes back to 10-bit precision and alpha (transparent, partial, opaque) to 12 bits.
    Odd sizes are fine (4:4:4 has no chroma subsampling)."""
    rng = np.random.default_rng(3)
    w, h = 33, 17
    frame = np.zeros((h, w, 4), np.uint16)
    frame[..., :3] = rng.integers(0, 65536, (h, w, 3))
    frame[..., :3] = np.repeat(np.repeat(frame[::8, ::8, :3], 8, axis=0), 8, axis=1)[:h, :w]  # flat blocks
    frame[:, :11, 3] = 0
    frame[:, 11:22, 3] = 30000                                    # partial alpha
    frame[:, 22:, 3] = 65535
    path = tmp_path / "clip.mov"
    with VideoWriter(path, (w, h), 24, codec="prores") as writer:
        for _ in range(2):
            writer.write(frame)
    info = subprocess.run([imageio_ffmpeg.get_ffmpeg_exe(), "-hide_banner", "-i", str(path)], capture_output=True,
                          text=True).stderr
    assert "prores (4444)" in info and "yuva444p" in info and "(tv, bt709, progressive)" in info, info
    back = decode_rgba64(path, (w, h)).astype(int)
    alpha = back[..., 3]
    assert alpha[:, :11].max() == 0
    assert np.abs(alpha[:, 11:22] - 30000).max() <= 64
    assert alpha[:, 22:].min() >= 65535 - 32
    err = np.abs(back[:, 22:, :3] - frame[:, 22:, :3].astype(int))   # colour where opaque
    assert np.percentile(err, 90) <= 3 * 64, np.percentile(err, 90)   # a few 10-bit steps (block edges ring)


def test_8bit_frames_feed_prores_and_16bit_frames_feed_h264(tmp_path):
    """Either bit depth goes into either codec: 8-bit frames are widened for ProRes, 16-bit ones rounded
    for H.264, RGB frames are opaque in ProRes."""
    grey8 = np.full((16, 32, 3), 100, np.uint8)
    with VideoWriter(tmp_path / "a.mov", (32, 16), 24, codec="prores") as writer:
        writer.write(grey8)
    back = decode_rgba64(tmp_path / "a.mov", (32, 16)).astype(int)
    assert np.abs(back[..., :3] - 100 * 257).max() <= 2 * 64 and back[..., 3].min() >= 65535 - 32
    with VideoWriter(tmp_path / "b.mp4", (32, 16), 24) as writer:
        writer.write(np.full((16, 32, 3), 100 * 257, np.uint16))
    back = decode_rgba64(tmp_path / "b.mp4", (32, 16), ["-vf", "scale=in_color_matrix=bt709:in_range=tv"])
    assert np.abs(back[..., :3].astype(int) // 257 - 100).max() <= 2


def test_png16_round_trips_and_ffmpeg_decodes_it_exactly(tmp_path):
    """16-bit PNGs (Pillow cannot write them): RGB and RGBA, odd sizes; ffmpeg, an independent decoder,
    reads back exactly the samples written; our reader too; Pillow sees the settings tag and size."""
    from PIL import Image

    rng = np.random.default_rng(9)
    for channels in (3, 4):
        image = rng.integers(0, 65536, (9, 13, channels), dtype=np.uint16)
        path = tmp_path / f"frame_{channels}.png"
        write_png16(path, image, {"fraytool:render-settings": "d1g35t"})
        fmt = "rgb48le" if channels == 3 else "rgba64le"
        raw = subprocess.run([imageio_ffmpeg.get_ffmpeg_exe(), "-v", "error", "-i", str(path), "-f", "rawvideo",
                              "-pix_fmt", fmt, "-"], capture_output=True, check=True).stdout
        assert np.array_equal(np.frombuffer(raw, "<u2").reshape(image.shape), image)
        assert np.array_equal(read_png16(path), image)
        assert png_settings(path) == ("d1g35t", (13, 9))
        with Image.open(path) as img:
            assert img.mode == ("RGB" if channels == 3 else "RGBA")
    data = (tmp_path / "frame_4.png").read_bytes()
    with pytest.raises(ValueError, match="truncated"):
        decode_png16(data[:-30])
    damaged = bytearray(data)
    damaged[60] ^= 0xFF
    with pytest.raises(ValueError):
        decode_png16(bytes(damaged))
