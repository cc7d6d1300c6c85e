"""Writing rendered frames: PNG files (Pillow; 16-bit ones: fraytool.render.png16) and video through
the ffmpeg that imageio-ffmpeg ships: H.264 in an MP4 (the default) or ProRes 4444 with alpha in a
QuickTime .mov (`--codec prores`).

Both are atomic: a PNG is written to a temp file in the same folder and renamed over its final
name; a video is encoded into a hidden temp file beside the final one (".NAME.partial-HOST-PID.mp4",
".mov") and renamed only when ffmpeg has finished and the file is complete, so a killed render never
leaves a truncated PNG or a half-written video where a finished one should be.

Each PNG carries the digest of the settings it was rendered with (a tEXt chunk), which is how an
interrupted render knows which frames it can keep (fraytool.render.sequence).

H.264: libx264, yuv420p (plays everywhere), the scene's fps, `-movflags +faststart` (index at the
front, so players can start before the download ends). yuv420p halves the chroma resolution, so
both image sides must be even: odd sizes are refused with an InputError rather than padded, so
that the video has exactly the size the user asked for. Frames with alpha are composited over the
background colour (H.264 has no alpha).

ProRes 4444 (prores_ks, profile 4444, yuva444p10le): 10-bit colour without chroma subsampling (any
size) and an alpha plane, for compositing; frames are sent to ffmpeg as 16-bit RGBA, straight alpha
(ffmpeg and ProRes keep colour and alpha separate). Both codecs are tagged BT.709, limited range.
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
    from fraytool.files import is_regular_file

    if not is_regular_file(path):
        return None
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


VIDEO_CODECS = ("h264", "prores")
"""`--codec` values: H.264 in an MP4, or ProRes 4444 with alpha in a QuickTime .mov."""
VIDEO_SUFFIX = {"h264": ".mp4", "prores": ".mov"}
"""File name ending of each codec's video."""


def partial_path(path: Path) -> Path:
    """Temp file a video (or another file an outside library writes) is written into before the final
    rename: .NAME.partial-HOST-PID.SUFFIX, with the final name's suffix (which picks the format)."""
    path = Path(path)
    return path.with_name(f".{path.stem}.partial-{host_tag()}-{os.getpid()}{path.suffix}")


def remove_stale_partials(path: Path) -> None:
    """Delete temp files of `path` left by killed runs on this host (never another machine's, on a
    shared folder, and never a live process's)."""
    path = Path(path)
    for p in path.parent.glob(f".{path.stem}.partial-{host_tag()}-*{path.suffix}"):
        pid = p.name[:len(p.name) - len(path.suffix)].rsplit("-", 1)[-1]
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


class VideoWriter:
    """Stream frames into a video through an ffmpeg child (the binary imageio-ffmpeg ships): H.264 in
    an MP4 or ProRes 4444 with alpha in a .mov (`codec`, see the module docstring). `close()` publishes
    it, `abort()` (or an exception in a `with` block) removes the temp file and leaves any previous
    video untouched. The child dies with fraytool (PR_SET_PDEATHSIG on Linux)."""

    def __init__(self, path: Path, size: tuple[int, int], fps: float, crf: int = 18, preset: str = X264_PRESET,
                 background_srgb=(0.0, 0.0, 0.0), codec: str = "h264"):
        """H.264: frames with alpha (H, W, 4) are composited over `background_srgb`; `crf` and `preset`
        set its quality and speed. ProRes: frames without alpha are opaque."""
        if codec not in VIDEO_CODECS:
            raise ValueError(f"codec must be one of {VIDEO_CODECS}, got {codec!r}")
        if codec == "h264":
            check_even(size)
        self.codec = codec
        self.background_srgb = tuple(background_srgb)
        self.path = Path(path)
        self.size = (int(size[0]), int(size[1]))
        self.path.parent.mkdir(parents=True, exist_ok=True)
        remove_stale_partials(self.path)
        self.tmp = partial_path(self.path)
        self.frames = 0
        rate = Fraction(fps).limit_denominator(1001)
        if codec == "h264":
            pix_in, pix_out = "rgb24", "yuv420p"
            encode = ["-vcodec", "libx264", "-pix_fmt", pix_out, "-crf", str(int(crf)), "-preset", preset,
                      "-movflags", "+faststart", "-f", "mp4"]
        else:
            pix_in, pix_out = "rgba64le", "yuva444p10le"
            encode = ["-vcodec", "prores_ks", "-profile:v", "4444", "-pix_fmt", pix_out, "-alpha_bits", "16",
                      "-vendor", "apl0", "-movflags", "+faststart", "-f", "mov"]
        # RGB -> Y'CbCr with the BT.709 matrix, limited range, and the frames tagged BT.709 (matrix,
        # primaries, transfer): the tags of the output options alone no longer reach the file with
        # newer ffmpeg, the frames' own properties do (tested by decoding)
        convert = (f"scale=out_color_matrix=bt709:out_range=tv,format={pix_out},"
                   "setparams=colorspace=bt709:color_primaries=bt709:color_trc=bt709:range=tv")
        tags = ["-colorspace", "bt709", "-color_primaries", "bt709", "-color_trc", "bt709", "-color_range", "tv"]
        cmd = [imageio_ffmpeg.get_ffmpeg_exe(), "-y", "-hide_banner", "-loglevel", "error",
               "-f", "rawvideo", "-vcodec", "rawvideo", "-s", f"{self.size[0]}x{self.size[1]}", "-pix_fmt", pix_in,
               "-r", f"{rate.numerator}/{rate.denominator}", "-i", "-", "-an", "-vf", convert, *tags, *encode,
               str(self.tmp)]
        self._log = tempfile.TemporaryFile()
        self._proc: Optional[subprocess.Popen] = subprocess.Popen(
            cmd, stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, stderr=self._log,
            preexec_fn=_die_with_parent if sys.platform.startswith("linux") else None)

    def _ffmpeg_said(self) -> str:
        self._log.seek(0)
        lines = self._log.read().decode(errors="replace").strip().splitlines()
        return lines[-1] if lines else "no message"

    def _frame_bytes(self, image: np.ndarray) -> bytes:
        """The raw frame ffmpeg expects: rgb24 (H.264) or rgba64le (ProRes)."""
        h, w = image.shape[:2]
        if (w, h) != self.size or image.dtype not in (np.uint8, np.uint16) or image.shape[2:] not in ((3,), (4,)):
            raise ValueError(f"frame {image.shape} {image.dtype} does not match the video size {self.size}")
        if self.codec == "h264":
            if image.shape[2] == 4:
                from fraytool.render.color import over_background

                image = over_background(image, self.background_srgb)
            if image.dtype == np.uint16:
                image = np.rint(image / 257.0).astype(np.uint8)
            return np.ascontiguousarray(image).tobytes()
        wide = image.astype("<u2") * 257 if image.dtype == np.uint8 else image.astype("<u2")
        if wide.shape[2] == 3:
            wide = np.concatenate([wide, np.full(wide.shape[:2] + (1,), 65535, "<u2")], axis=2)
        return np.ascontiguousarray(wide).tobytes()

    def write(self, image: np.ndarray) -> None:
        """Append a frame: (H, W, 3) RGB or (H, W, 4) straight-alpha RGBA, sRGB, uint8 or uint16."""
        data = self._frame_bytes(image)
        try:
            self._proc.stdin.write(data)
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
            raise RunError(f"{self.path}: ffmpeg did not produce a complete video (disk full or ffmpeg error?)")
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

    def __enter__(self) -> "VideoWriter":
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()
