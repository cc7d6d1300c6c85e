"""PNG and MP4 output: the MP4 is probed with the ffmpeg binary imageio-ffmpeg ships; writes are atomic."""
from __future__ import annotations

import os
import re
import subprocess

import imageio_ffmpeg
import numpy as np
import pytest

from fraytool.errors import InputError
from fraytool.render.encode import (
    Mp4Writer,
    partial_mp4_path,
    png_settings,
    read_png,
    remove_stale_partials,
    write_png,
)


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
    with Mp4Writer(path, (64, 48), 24) as w:
        for _ in range(3):
            w.write(red)
    exe = imageio_ffmpeg.get_ffmpeg_exe()
    info = subprocess.run([exe, "-hide_banner", "-i", str(path)], capture_output=True, text=True).stderr
    assert "yuv420p(tv, bt709" in info, info
    raw = subprocess.run([exe, "-v", "error", "-i", str(path), "-vf", "scale=in_color_matrix=bt709:in_range=tv",
                          "-frames:v", "1", "-f", "rawvideo", "-pix_fmt", "rgb24", "-"], capture_output=True).stdout
    back = np.frombuffer(raw, np.uint8).reshape(48, 64, 3)[20:28, 28:36].astype(int)
    assert np.abs(back - [200, 0, 0]).max() <= 4, back.mean(axis=(0, 1))


@pytest.mark.parametrize("fps", [24.0, 25.0])
def test_mp4_is_h264_yuv420p_with_size_fps_and_frame_count(tmp_path, fps):
    path = tmp_path / "clip.mp4"
    with Mp4Writer(path, (64, 48), fps) as w:
        for f in _frames(7):
            w.write(f)
    p = probe(path)
    assert p == {"codec": "h264", "pix_fmt": "yuv420p", "size": (64, 48), "fps": fps, "frames": 7}
    data = path.read_bytes()
    assert data.index(b"moov") < data.index(b"mdat")             # +faststart: index first
    assert not list(tmp_path.glob(".*partial*"))                 # temp file renamed away


def test_odd_sizes_are_refused_clearly(tmp_path):
    with pytest.raises(InputError, match="even width and height.*66x48"):
        Mp4Writer(tmp_path / "x.mp4", (65, 48), 24)
    assert not list(tmp_path.iterdir())


def test_interrupted_encode_leaves_no_file_and_keeps_the_old_one(tmp_path):
    path = tmp_path / "clip.mp4"
    path.write_bytes(b"previous finished video")
    with pytest.raises(KeyboardInterrupt):
        with Mp4Writer(path, (64, 48), 24) as w:
            for f in _frames(3):
                w.write(f)
            raise KeyboardInterrupt
    assert path.read_bytes() == b"previous finished video"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["clip.mp4"]


def test_stale_partials_of_dead_runs_are_removed(tmp_path):
    path = tmp_path / "clip.mp4"
    mine = partial_mp4_path(path)
    dead = mine.with_name(mine.name.replace(f"-{os.getpid()}.mp4", "-999999999.mp4"))
    other_host = tmp_path / ".clip.partial-elsewhere-999999999.mp4"
    for p in (mine, dead, other_host):
        p.write_bytes(b"x")
    remove_stale_partials(path)
    assert not dead.exists() and mine.exists() and other_host.exists()


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
