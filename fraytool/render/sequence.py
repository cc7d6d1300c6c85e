"""Rendering a range of frames to PNG, EXR and/or a video, resuming what an interrupted run finished.

Resume rule: a PNG or EXR at its final name is complete (written atomically); if its embedded settings
digest and size match the job, it is not written again, and a frame whose files are all kept is not
drawn again. The video cannot be appended to, so it is rebuilt in the same pass: each frame is fed to
ffmpeg either from a kept file (a PNG, decoded; an EXR, encoded as a PNG would be; ProRes takes 16-bit
frames, which an 8-bit PNG is too coarse for: then the EXR serves, or the frame is drawn again) or
freshly drawn. Without files there is nothing to keep, and an interrupted video-only render starts
over. The video is encoded into a temp file and renamed only once complete (fraytool.render.encode).

Motion blur (job.motion_blur): a frame is its N sub-frames drawn one after the other into the float
target and averaged in linear light (fraytool.render.motion_blur), then written as any float frame is;
its files' digest also covers the neighbouring record the sub-frames are interpolated with.
"""
from __future__ import annotations

import hashlib
import sys
import time
from dataclasses import dataclass, field
from typing import Optional, TextIO

import moderngl
import numpy as np

from fraytool._numba_cache import first_compile_notice
from fraytool.io.frame_record import sweep_temp_files
from fraytool.io.frame_store import FrameStore
from fraytool.progress import Progress
from fraytool.render.color import encode_premultiplied_linear
from fraytool.render.context import gl_strings
from fraytool.render.encode import PNG_SETTINGS_KEY, VideoWriter, png_settings, read_png, write_png
from fraytool.render.exr import exr_settings, read_exr_rgba, write_exr
from fraytool.render.geometry import GeometryBuilder
from fraytool.render.job import RenderJob
from fraytool.render.motion_blur import neighbour, sub_frame_records
from fraytool.render.png16 import read_png16, write_png16
from fraytool.render.renderer import Renderer


@dataclass
class RenderResult:
    frames: int = 0
    rendered: int = 0
    reused: int = 0
    video: Optional[str] = None
    png_dir: Optional[str] = None
    exr_dir: Optional[str] = None
    stage_s: dict = field(default_factory=lambda: {"geometry": 0.0, "draw_readback": 0.0, "encode": 0.0})


def frame_digest(job_digest: str, store: FrameStore, frame: int, also: Optional[int] = None) -> str:
    """Digest of one frame's pixels: the job's settings and the bytes of the frame record it draws,
    so a re-simulated frame (same scene, another fraytool) is drawn again, never reused stale; `also`:
    the record a motion-blurred frame's sub-frames are interpolated with, hashed after it."""
    h = hashlib.sha256(job_digest.encode())
    h.update(store.frame_path(frame).read_bytes())
    if also is not None:
        h.update(store.frame_path(also).read_bytes())
    return h.hexdigest()[:16]


def reusable_png(job: RenderJob, frame: int, digest: str) -> bool:
    """True if the frame's PNG exists, is complete and was drawn with exactly these settings."""
    info = png_settings(job.png_path(frame))
    return info is not None and info == (digest, job.size)


class _Drawn:
    """One drawn frame, read back once: the float target's linear RGBA (or the 8-bit image), the
    depth for EXR, and the straight-alpha sRGB images at 8 or 16 bits made from them on demand."""

    def __init__(self, renderer: Renderer, depth: bool, linear: Optional[np.ndarray] = None,
                 depth_m: Optional[np.ndarray] = None):
        """Read the renderer back, or (`linear` given: a motion-blurred frame) take its averaged image
        and `depth_m`."""
        self.alpha = renderer.alpha
        self.linear: Optional[np.ndarray] = linear
        self._images: dict[int, np.ndarray] = {}
        if linear is not None:
            self.depth_m = depth_m
            return
        if renderer.target == "float":
            self.linear = renderer.read_linear()
        else:
            self._images[8] = renderer.read()
        self.depth_m = renderer.read_depth_m() if depth else None

    def image(self, bits: int) -> np.ndarray:
        if bits not in self._images:
            self._images[bits] = encode_premultiplied_linear(self.linear, bits, self.alpha)
        return self._images[bits]


class _PngFiles:
    """The PNG sequence of a job, 8 or 16 bits per channel."""

    def __init__(self, job: RenderJob):
        self.job = job

    def reusable(self, frame: int, digest: str) -> bool:
        return reusable_png(self.job, frame, digest)

    def write(self, frame: int, drawn: _Drawn, digest: str) -> None:
        path = self.job.png_path(frame)
        if self.job.png_bits == 16:
            write_png16(path, drawn.image(16), {PNG_SETTINGS_KEY: digest})
        else:
            write_png(path, drawn.image(8), digest)

    def video_image(self, frame: int, bits: int) -> Optional[np.ndarray]:
        """The kept PNG as video input, or None if it has fewer bits than the video needs."""
        if self.job.png_bits < bits:
            return None
        path = self.job.png_path(frame)
        return read_png16(path) if self.job.png_bits == 16 else read_png(path)


class _ExrFiles:
    """The EXR sequence of a job (fraytool.render.exr)."""

    def __init__(self, job: RenderJob):
        self.job = job

    def reusable(self, frame: int, digest: str) -> bool:
        return exr_settings(self.job.exr_path(frame)) == (digest, self.job.size)

    def write(self, frame: int, drawn: _Drawn, digest: str) -> None:
        write_exr(self.job.exr_path(frame), drawn.linear, drawn.depth_m, digest)

    def video_image(self, frame: int, bits: int) -> Optional[np.ndarray]:
        return encode_premultiplied_linear(read_exr_rgba(self.job.exr_path(frame)), bits, self.job.alpha)


def _kept_video_image(files: list, frame: int, bits: int) -> Optional[np.ndarray]:
    """The video input for a frame whose files are all kept: from the first file that has enough bits."""
    for f in files:
        try:
            image = f.video_image(frame, bits)
        except (OSError, ValueError):  # unreadable after all: the frame is drawn again
            image = None
        if image is not None:
            return image
    return None


@dataclass
class _FramePlan:
    """One frame of a render: its files' digest, the files to write, and either the video image from
    kept files or the geometry to draw."""
    file_digest: str
    stale: list
    image: Optional[np.ndarray]
    geom: Optional[object]
    sub_frames: list = field(default_factory=list)
    """Motion blur: the records of the sub-frames after the first (whose geometry is `geom`)."""


def _draw_blurred(renderer: Renderer, builder: GeometryBuilder, p: _FramePlan, depth: bool, build_kw: dict,
                  ahead) -> _Drawn:
    """Draw a frame's sub-frames (p.geom, then p.sub_frames), each one's successor built while the GL draws
    it (and after the last, `ahead()`: the next frame's plan), and average them in linear light. Depth: the
    nearest over the sub-frames (+inf where none drew anything); alpha: the average coverage."""
    total: Optional[np.ndarray] = None
    nearest: Optional[np.ndarray] = None
    geom = p.geom
    count = 1 + len(p.sub_frames)
    for k in range(count):
        renderer.draw(geom)
        if k + 1 < count:
            geom = builder.build(p.sub_frames[k], **build_kw)
        else:
            ahead()
        linear = renderer.read_linear()
        total = linear.astype(np.float64) if total is None else total + linear
        if depth:
            d = renderer.read_depth_m()
            nearest = d if nearest is None else np.minimum(nearest, d)
    p.sub_frames = []
    return _Drawn(renderer, depth, linear=(total / count).astype(np.float32), depth_m=nearest)


def render_job(job: RenderJob, ctx: moderngl.Context, store: FrameStore, stream: TextIO = sys.stderr,
               progress: Optional[bool] = None) -> RenderResult:
    """Render job.frames from the frame records in `store`; returns counts and stage times. The next
    frame's geometry is built while the GL draws the current one (llvmpipe rasterises on its own
    threads until the read-back waits for it), and ffmpeg encodes in its own process."""
    topology = store.load_topology()
    files: list = []
    if job.png:
        sweep_temp_files(job.png_dir)  # PNGs of a killed render (the caller holds the folder's lock)
        files.append(_PngFiles(job))
    if job.exr:
        sweep_temp_files(job.exr_dir)
        files.append(_ExrFiles(job))
    renderer = Renderer(ctx, job.size, job.samples, job.spec.render, job.spec.camera, topology, job.wireframe,
                        alpha=job.alpha, target=job.target, depth=job.exr, panels_spec=job.spec.all_panels)
    digest = job.digest(renderer.samples, gl_strings(ctx))
    builder = renderer.geometry_builder(topology)
    want_yarns = job.wireframe != "only"
    want_lines = job.wireframe != "off"
    build_kw = dict(yarns=want_yarns, lines=want_lines)
    blur = job.motion_blur
    scene_frames = job.spec.time.frames
    loaded: dict[int, object] = {}

    def load(frame: int):
        """Frame records, the last few kept (a blurred frame reads its neighbour, the next frame's own)."""
        if frame not in loaded:
            if len(loaded) >= 3:
                del loaded[min(loaded)]
            loaded[frame] = store.load_frame(frame)
        return loaded[frame]
    video_bits = 16 if job.codec == "prores" else 8
    result = RenderResult(png_dir=str(job.png_dir) if job.png else None,
                          exr_dir=str(job.exr_dir) if job.exr else None)
    writer: Optional[VideoWriter] = None
    frames = job.frames.frames()
    bar = Progress(len(frames), job.spec.name, stream=stream, enabled=progress, stage="render")
    notice = first_compile_notice(bar.message)  # the geometry's kernels compile on a first render
    notice.__enter__()
    try:
        if job.video:
            writer = VideoWriter(job.video_path, job.size, job.spec.time.fps, crf=job.spec.output.crf,
                                 background_srgb=job.spec.render.background, codec=job.codec)
        plans: dict[int, _FramePlan] = {}

        def plan(i: int) -> _FramePlan:
            """What frame i needs (kept files or a draw), its geometry built ahead when drawn."""
            if i not in plans:
                frame = frames[i]
                other = neighbour(frame, scene_frames) if blur is not None else None
                file_digest = frame_digest(digest, store, frame, other) if files else ""
                stale = [f for f in files if not f.reusable(frame, file_digest)]
                image = None
                kept = bool(files) and not stale
                if kept and writer is not None:
                    image = _kept_video_image(files, frame, video_bits)
                    kept = image is not None
                geom, sub_frames = None, []
                if not kept:
                    t = time.perf_counter()
                    if blur is None:
                        record = store.load_frame(frame)
                    else:
                        record, *sub_frames = sub_frame_records(frame, scene_frames, load, blur)
                    geom = builder.build(record, **build_kw)
                    result.stage_s["geometry"] += time.perf_counter() - t
                plans[i] = _FramePlan(file_digest, stale, image, geom, sub_frames)
            return plans[i]

        for i, frame in enumerate(frames):
            p = plan(i)
            image = p.image
            if p.geom is None:
                result.reused += 1
            elif blur is not None:
                t1 = time.perf_counter()
                drawn = _draw_blurred(renderer, builder, p, job.exr, build_kw,
                                      lambda: plan(i + 1) if i + 1 < len(frames) else None)
                image = drawn.image(video_bits) if writer is not None else None
                result.stage_s["draw_readback"] += time.perf_counter() - t1
                for f in p.stale:
                    f.write(frame, drawn, p.file_digest)
                result.rendered += 1
            else:
                t1 = time.perf_counter()
                renderer.draw(p.geom)                  # llvmpipe rasterises on its own threads ...
                if i + 1 < len(frames):
                    t = time.perf_counter()
                    plan(i + 1)                        # ... while the next frame's geometry is built
                    t1 += time.perf_counter() - t      # (counted as geometry, not as drawing)
                drawn = _Drawn(renderer, depth=job.exr)
                image = drawn.image(video_bits) if writer is not None else None
                result.stage_s["draw_readback"] += time.perf_counter() - t1
                for f in p.stale:
                    f.write(frame, drawn, p.file_digest)
                result.rendered += 1
            del plans[i]
            t2 = time.perf_counter()
            if writer is not None:
                writer.write(image)
            result.stage_s["encode"] += time.perf_counter() - t2
            result.frames += 1
            bar.update(i + 1, f"frame {frame}")
        if writer is not None:
            t3 = time.perf_counter()
            result.video = str(writer.close())
            result.stage_s["encode"] += time.perf_counter() - t3
            writer = None
    finally:
        notice.__exit__(None, None, None)
        if writer is not None:
            writer.abort()
        bar.close()
        renderer.release()
    return result
