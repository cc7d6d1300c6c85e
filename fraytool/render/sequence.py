"""Rendering a range of frames to PNG and/or MP4, resuming what an interrupted run finished.

Resume rule: a PNG at its final name is complete (written atomically); if its embedded settings
digest and size match the job, the frame is not rendered again. The MP4 cannot be appended to, so
it is rebuilt in the same pass: each frame is fed to ffmpeg either from its kept PNG (decoded) or
freshly rendered. Without --png there is nothing to keep, and an interrupted MP4-only render starts
over. The MP4 is encoded into a temp file and renamed only once complete (fraytool.render.encode).
"""
from __future__ import annotations

import hashlib

import sys
import time
from dataclasses import dataclass, field
from typing import Optional, TextIO

import moderngl

from fraytool.io.frame_record import sweep_temp_files
from fraytool.io.frame_store import FrameStore
from fraytool.progress import Progress
from fraytool.render.encode import Mp4Writer, png_settings, read_png, write_png
from fraytool.render.geometry import GeometryBuilder, YarnStyle
from fraytool.render.job import RenderJob
from fraytool.render.renderer import Renderer


@dataclass
class RenderResult:
    frames: int = 0
    rendered: int = 0
    reused: int = 0
    mp4: Optional[str] = None
    png_dir: Optional[str] = None
    stage_s: dict = field(default_factory=lambda: {"geometry": 0.0, "draw_readback": 0.0, "encode": 0.0})


def frame_digest(job_digest: str, store: FrameStore, frame: int) -> str:
    """Digest of one PNG's pixels: the job's settings and the bytes of the frame record it draws,
    so a re-simulated frame (same scene, another fraytool) is drawn again, never reused stale."""
    h = hashlib.sha256(job_digest.encode())
    h.update(store.frame_path(frame).read_bytes())
    return h.hexdigest()[:16]


def reusable_png(job: RenderJob, frame: int, digest: str) -> bool:
    """True if the frame's PNG exists, is complete and was drawn with exactly these settings."""
    info = png_settings(job.png_path(frame))
    return info is not None and info == (digest, job.size)


def render_job(job: RenderJob, ctx: moderngl.Context, store: FrameStore, stream: TextIO = sys.stderr,
               progress: Optional[bool] = None) -> RenderResult:
    """Render job.frames from the frame records in `store`; returns counts and stage times."""
    topology = store.load_topology()
    if job.png:
        sweep_temp_files(job.png_dir)  # PNGs of a killed render (the caller holds the folder's lock)
    W, H = job.size
    renderer = Renderer(ctx, job.size, job.samples, job.spec.render, job.spec.camera, topology, job.wireframe,
                        alpha=job.alpha)
    digest = job.digest(renderer.samples)
    builder = GeometryBuilder(topology, YarnStyle.from_spec(job.spec.render, topology), renderer.camera, H)
    want_yarns = job.wireframe != "only"
    want_lines = job.wireframe != "off"
    result = RenderResult(png_dir=str(job.png_dir) if job.png else None)
    writer: Optional[Mp4Writer] = None
    frames = job.frames.frames()
    bar = Progress(len(frames), job.spec.name, stream=stream, enabled=progress, stage="render")
    try:
        if job.mp4:
            writer = Mp4Writer(job.mp4_path, job.size, job.spec.time.fps, crf=job.spec.output.crf,
                               background_srgb=job.spec.render.background)
        for i, frame in enumerate(frames):
            t0 = time.perf_counter()
            png_digest = frame_digest(digest, store, frame) if job.png else ""
            if job.png and reusable_png(job, frame, png_digest):
                image = read_png(job.png_path(frame)) if writer is not None else None
                result.reused += 1
                t2 = time.perf_counter()
            else:
                record = store.load_frame(frame)
                geom = builder.build(record, yarns=want_yarns, lines=want_lines)
                t1 = time.perf_counter()
                image = renderer.render(geom)
                t2 = time.perf_counter()
                result.stage_s["geometry"] += t1 - t0
                result.stage_s["draw_readback"] += t2 - t1
                if job.png:
                    write_png(job.png_path(frame), image, png_digest)
                result.rendered += 1
            if writer is not None:
                writer.write(image)
            result.stage_s["encode"] += time.perf_counter() - t2
            result.frames += 1
            bar.update(i + 1, f"frame {frame}")
        if writer is not None:
            t3 = time.perf_counter()
            result.mp4 = str(writer.close())
            result.stage_s["encode"] += time.perf_counter() - t3
            writer = None
    finally:
        if writer is not None:
            writer.abort()
        bar.close()
        renderer.release()
    return result
