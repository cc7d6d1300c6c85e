"""Writing rendered frames: PNG files (Pillow) and H.264 MP4 (the ffmpeg that imageio-ffmpeg ships).

Both are atomic: a PNG is written to a temp file in the same folder and renamed over its final
name; an MP4 is encoded into a hidden temp file beside the final one (".NAME.partial-HOST-PID.mp4") and
renamed only when ffmpeg has finished and the file is complete, so a killed render never leaves a
truncated PNG or a half-written MP4 where a finished one should be.

Each PNG carries the digest of the settings it was rendered with (a tEXt chunk), which is how an
interrupted render knows which frames it can keep (fraytool.render.sequence).

MP4: libx264, yuv420p (plays everywhere), the scene's fps, `-movflags +faststart` (index at the
front, so players can start before the download ends). yuv420p halves the chroma resolution, so
both image sides must be even: odd sizes are refused with an InputError rather than padded, so
that the video has exactly the size the user asked for.
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import tempfile
from fractions import Fraction
from pathlib import Path
from typing import Optional

import imageio_ffmpeg
import numpy as np
from PIL import Image, PngImagePlugin

from fraytool.errors import InputError, RunError
from fraytool.io.frame_record import atomic_write_bytes, host_tag
from fraytool.io.lock import pid_alive

PNG_SETTINGS_KEY = "fraytool:render-settings"
"""tEXt key holding the digest of the settings a PNG was rendered with."""
PNG_COMPRESS_LEVEL = 3
"""zlib level: 3 is about 3x faster than Pillow's default 6 for a few percent more bytes."""
X264_PRESET = "veryfast"
"""x264 speed preset: keeps encoding well inside the frame budget on 2 cores; quality is set by CRF."""


def check_even(size: tuple[int, int], what: str = "MP4 size") -> None:
    """Refuse odd widths or heights (yuv420p needs even sides)."""
    w, h = size
    if w % 2 or h % 2:
        raise InputError(f"{what} {w}x{h}: H.264 with yuv420p needs an even width and height; "
                         f"use e.g. {w + w % 2}x{h + h % 2}")


def write_png(path: Path, image: np.ndarray, settings_digest: str = "") -> None:
    """Write an (H, W, 3) RGB or (H, W, 4) straight-alpha RGBA uint8 image as PNG atomically, tagged
    with `settings_digest`."""
    img = Image.fromarray(np.ascontiguousarray(image), mode="RGBA" if image.shape[2] == 4 else "RGB")
    info = PngImagePlugin.PngInfo()
    if settings_digest:
        info.add_text(PNG_SETTINGS_KEY, settings_digest)
    atomic_write_bytes(Path(path), lambda f: img.save(f, format="PNG", pnginfo=info,
                                                      compress_level=PNG_COMPRESS_LEVEL))


def png_settings(path: Path) -> Optional[tuple[str, tuple[int, int]]]:
    """(settings digest, (width, height)) of a PNG written by write_png, or None if unreadable."""
    try:
        with Image.open(path) as img:
            img.verify()  # chunk CRCs: a damaged PNG is drawn again, never reused
        with Image.open(path) as img:
            return img.text.get(PNG_SETTINGS_KEY, ""), img.size
    except (OSError, ValueError, SyntaxError, RuntimeError):
        return None


def read_png(path: Path) -> np.ndarray:
    """An (H, W, 3) uint8 image, or (H, W, 4) for a PNG with alpha."""
    with Image.open(path) as img:
        return np.asarray(img.convert("RGBA" if img.mode in ("RGBA", "LA") else "RGB"))


def partial_mp4_path(path: Path) -> Path:
    """Temp file the MP4 is encoded into before the final rename: .NAME.partial-HOST-PID.mp4."""
    path = Path(path)
    return path.with_name(f".{path.stem}.partial-{host_tag()}-{os.getpid()}.mp4")


def remove_stale_partials(path: Path) -> None:
    """Delete temp MP4s of `path` left by killed runs on this host (never another machine's, on a
    shared folder, and never a live process's)."""
    path = Path(path)
    for p in path.parent.glob(f".{path.stem}.partial-{host_tag()}-*.mp4"):
        pid = p.name.rsplit("-", 1)[-1].split(".")[0]
        if pid.isdigit() and not pid_alive(int(pid)):
            try:
                p.unlink()
            except FileNotFoundError:
                pass


def _die_with_parent() -> None:  # pragma: no cover - runs in the child between fork and exec
    """Linux: the child gets SIGKILL when the thread that started it dies, so a `kill -9` of fraytool
    never leaves ffmpeg finishing a partial MP4 behind it."""
    try:
        import ctypes

        ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        pass


class Mp4Writer:
    """Stream frames into an H.264 MP4 through an ffmpeg child (the binary imageio-ffmpeg ships);
    `close()` publishes it, `abort()` (or an exception in a `with` block) removes the temp file and
    leaves any previous MP4 untouched. The child dies with fraytool (PR_SET_PDEATHSIG on Linux)."""

    def __init__(self, path: Path, size: tuple[int, int], fps: float, crf: int = 18, preset: str = X264_PRESET,
                 background_srgb=(0.0, 0.0, 0.0)):
        """Frames with alpha (H, W, 4) are composited over `background_srgb` (H.264 has no alpha)."""
        check_even(size)
        self.background_srgb = tuple(background_srgb)
        self.path = Path(path)
        self.size = (int(size[0]), int(size[1]))
        self.path.parent.mkdir(parents=True, exist_ok=True)
        remove_stale_partials(self.path)
        self.tmp = partial_mp4_path(self.path)
        self.frames = 0
        rate = Fraction(fps).limit_denominator(1001)
        cmd = [imageio_ffmpeg.get_ffmpeg_exe(), "-y", "-hide_banner", "-loglevel", "error",
               "-f", "rawvideo", "-vcodec", "rawvideo", "-s", f"{self.size[0]}x{self.size[1]}", "-pix_fmt", "rgb24",
               "-r", f"{rate.numerator}/{rate.denominator}", "-i", "-", "-an",
               # tagged BT.709, limited range; ffmpeg converts rgb24 with the tagged matrix (tested)
               "-colorspace", "bt709", "-color_primaries", "bt709", "-color_trc", "bt709", "-color_range", "tv",
               "-vcodec", "libx264", "-pix_fmt", "yuv420p", "-crf", str(int(crf)), "-preset", preset,
               "-movflags", "+faststart", "-f", "mp4", str(self.tmp)]
        self._log = tempfile.TemporaryFile()
        self._proc: Optional[subprocess.Popen] = subprocess.Popen(
            cmd, stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, stderr=self._log,
            preexec_fn=_die_with_parent if sys.platform.startswith("linux") else None)

    def _ffmpeg_said(self) -> str:
        self._log.seek(0)
        lines = self._log.read().decode(errors="replace").strip().splitlines()
        return lines[-1] if lines else "no message"

    def write(self, image: np.ndarray) -> None:
        if image.ndim == 3 and image.shape[2] == 4:
            from fraytool.render.color import over_background

            image = over_background(image, self.background_srgb)
        h, w = image.shape[:2]
        if (w, h) != self.size or image.dtype != np.uint8 or image.shape[2:] != (3,):
            raise ValueError(f"frame {image.shape} {image.dtype} does not match the video size {self.size}")
        try:
            self._proc.stdin.write(np.ascontiguousarray(image).tobytes())
        except (OSError, ValueError):
            self._proc.wait()
            said = self._ffmpeg_said()
            self.abort()
            raise RunError(f"{self.path}: ffmpeg stopped while encoding: {said}") from None
        self.frames += 1

    def close(self) -> Path:
        """Finish encoding and rename the temp file to the final name."""
        if self._proc is None:
            return self.path
        if self.frames == 0:
            self.abort()
            raise RunError(f"{self.path}: no frames to encode")
        proc, self._proc = self._proc, None
        try:
            proc.stdin.close()
        except OSError:
            pass
        code = proc.wait()
        if code != 0:
            said = self._ffmpeg_said()
            self._unlink_tmp()
            raise RunError(f"{self.path}: ffmpeg failed (exit {code}): {said}")
        # with +faststart the index atom, moov, sits at the front of a complete file
        try:
            with open(self.tmp, "rb+") as f:
                head = f.read(1 << 16)
                os.fsync(f.fileno())
        except FileNotFoundError:
            head = b""
        if b"moov" not in head:
            self._unlink_tmp()
            raise RunError(f"{self.path}: ffmpeg did not produce a complete MP4 (disk full or ffmpeg error?)")
        os.replace(self.tmp, self.path)
        return self.path

    def abort(self) -> None:
        """Stop ffmpeg at once (no waiting for queued frames) and delete the temp file."""
        if self._proc is not None:
            proc, self._proc = self._proc, None
            proc.kill()
            try:
                proc.stdin.close()
            except OSError:
                pass
            proc.wait()
        self._unlink_tmp()

    def _unlink_tmp(self) -> None:
        try:
            self.tmp.unlink()
        except FileNotFoundError:
            pass

    def __enter__(self) -> "Mp4Writer":
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()
