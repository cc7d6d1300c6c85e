"""The work of one farm task, run on a Dask worker (or in-process): plain functions of plain,
picklable arguments that return a small status dict. Every task is idempotent and resumes what an
earlier, killed attempt left: the simulation continues from its checkpoint, a chunk keeps the PNGs
that verify, the join re-encodes from the PNGs. So a task the scheduler retries on another worker
gives the same bytes as an uninterrupted single-process `fraytool render`."""
from __future__ import annotations

import os
import socket
import time
from dataclasses import replace
from pathlib import Path

from fraytool.farm.shots import Shot
from fraytool.render.options import FrameRange


def _where() -> str:
    return f"{socket.gethostname()}:{os.getpid()}"


ATTEMPT_TOPIC = "fraytool-farm-attempt"
"""The Dask event topic on which a farm task tells the client that an attempt started or raised
(farm/watch.py listens): the client sees every attempt, also those the scheduler retries on its own
and those whose worker dies."""


def one_line(exc: BaseException) -> str:
    """An exception as one line: its type and the first line of its message (at most 300 characters)."""
    text = str(exc).strip().splitlines()
    return f"{type(exc).__name__}: {text[0][:300]}" if text else type(exc).__name__


def _dask_worker():
    """The Dask worker running this task, or None when the task runs in-process (tests, a debugger)."""
    from distributed import get_worker

    try:
        return get_worker()
    except ValueError:
        return None


def _tell(worker, message: dict) -> None:
    """Send one attempt event to the client (nothing to tell outside a worker)."""
    if worker is not None:
        worker.log_event(ATTEMPT_TOPIC, message)


def run_attempt(key: str, work, *args) -> dict:
    """Run `work(*args)` as one attempt of the farm task `key`: the client is told when it starts (on
    which worker) and, if it raises, the error, before the exception goes on to the scheduler (which
    may retry it). Returns work's result dict with an "attempt" entry: worker, process, start, end
    (epoch seconds) - the runner takes it out into job.json's attempts."""
    worker = _dask_worker()
    address = worker.address if worker is not None else "in-process"
    start = time.time()
    _tell(worker, {"key": key, "event": "start", "time": start, "worker": address, "process": _where()})
    try:
        result = work(*args)
    except Exception as exc:
        _tell(worker, {"key": key, "event": "error", "time": time.time(), "worker": address, "error": one_line(exc)})
        raise
    attempt = {"worker": address, "process": _where(), "start": start, "end": time.time()}
    return {**result, "attempt": attempt}


def task_info(t0: float) -> dict:
    """Seconds since t0 and the worker (host:pid), for job.json."""
    return {"seconds": time.time() - t0, "worker": _where()}


def load_shot(shot: Shot):
    from fraytool.scene import load_scene

    return load_scene(shot.scene, list(shot.sets))


def render_job_for(shot: Shot, out_dir: Path, frames: FrameRange):
    """The RenderJob `fraytool render` would make for this shot (PNG on), restricted to `frames`."""
    from fraytool.render.job import build_job
    from fraytool.render.options import RenderRequest

    spec = load_shot(shot)
    r = shot.render
    prores = r.codec == "prores"
    request = RenderRequest(png=True, video=True, out=str(out_dir), frames=r.frames, resolution=r.resolution,
                            samples=r.samples, wireframe=r.wireframe, alpha=bool(r.alpha),
                            depth=16 if prores else r.depth, exr=bool(r.exr), codec=r.codec or "h264",
                            fit=bool(r.fit), motion_blur=r.motion_blur, motion_samples=r.motion_samples,
                            supersample=r.supersample)
    job = build_job(spec, request, out_dir)
    return job, replace(job, frames=frames)


def shot_frames(shot: Shot, out_dir: Path) -> FrameRange:
    job, _ = render_job_for(shot, out_dir, FrameRange(0, 1))
    return job.frames


def frames_to_simulate(shot: Shot, out_dir: Path) -> int:
    """Frames the shot's simulation task runs: up to the end of its frame range (with motion blur the
    frame after it too, as `fraytool render` reads), or the whole scene when the camera is fitted (--fit,
    [camera] fit), as the fit covers the whole shot."""
    from fraytool.render.motion_blur import frames_needed

    job, _ = render_job_for(shot, out_dir, FrameRange(0, 1))
    return job.spec.time.frames if job.spec.camera.fit else frames_needed(job)


def one_thread() -> None:
    """A farm task simulates on one thread: every worker has its core (a remote worker started without
    NUMBA_NUM_THREADS=1 would otherwise run the parallel kernels on every core of its machine, as many
    times as it has worker processes). The frames are the same on any number of threads."""
    from fraytool.threads import use_threads

    use_threads(1)


def simulate_task(shot: Shot, out_dir: str, frames_needed: int) -> dict:
    """Simulate (or continue) the shot's frames 0..frames_needed-1 into out_dir/frames."""
    from fraytool.sim.run import simulate_to_disk

    from fraytool.io.frame_store import FrameStore
    from fraytool.scene import scene_hash

    from fraytool.resident_memory import map_large_blocks

    t0 = time.time()
    one_thread()
    map_large_blocks()  # else a worker process keeps what its tasks freed resident (resident_memory)
    spec = load_shot(shot)
    store = FrameStore(Path(out_dir))
    # continue (or repair) this shot's own frames; frames of other settings are replaced
    resume = store.manifest() is None or store.matches(scene_hash(spec))
    summary = simulate_to_disk(spec, Path(out_dir), frames=frames_needed, resume=resume, progress=False)
    return {"task": "simulate", "seconds": time.time() - t0, "worker": _where(),
            "frames": summary["frames"], "broken_springs": summary.get("broken_springs")}


def render_chunk_task(shot: Shot, out_dir: str, start: int, end: int, step: int, _after=None) -> dict:
    """Render frames start..end-1 (every step) of the shot to its PNG sequence (and EXRs with exr)."""
    from fraytool.io.frame_store import FrameStore
    from fraytool.render.context import create_context
    from fraytool.render.fit import fitted_job
    from fraytool.render.sequence import render_job

    t0 = time.time()
    _, job = render_job_for(shot, Path(out_dir), FrameRange(start, end, step))
    job = replace(job, video=False, png=True)
    store = FrameStore(Path(out_dir))
    if job.spec.camera.fit:  # over the whole shot, simulated before any chunk: every chunk gets this camera
        job = fitted_job(job, store)
    ctx = create_context()
    try:
        result = render_job(job, ctx, store, progress=False)
    finally:
        ctx.release()
    return {"task": f"render {start}-{end}", "seconds": time.time() - t0, "worker": _where(),
            "rendered": result.rendered, "reused": result.reused}


def _read_png16_as_8bit(path: Path):
    """A 16-bit PNG of ours, rounded to 8 bits per channel (uint8)."""
    import numpy as np

    from fraytool.render.png16 import read_png16

    image = read_png16(path).astype(np.uint32)
    return ((image * 255 + 32767) // 65535).astype(np.uint8)


def join_task(shot: Shot, out_dir: str, _after=None) -> dict:
    """Encode the shot's video (the MP4, or the ProRes .mov) from its PNG sequence: the same pixels
    `fraytool render` encodes (ProRes from 16-bit RGBA PNGs, as render encodes it from 16 bits). An
    H.264 MP4 from 16-bit PNGs gets them rounded to 8 bits (Pillow's own reading drops the low byte,
    which put a quarter of the values one step below render's; rounded, a value differs only where
    the colour lies within 1/514 of a step's midpoint)."""
    from fraytool.render.encode import VIDEO_SUFFIX, VideoWriter, read_png
    from fraytool.render.png16 import read_png16

    t0 = time.time()
    job, _ = render_job_for(shot, Path(out_dir), FrameRange(0, 1))
    if job.png_bits == 16:
        read = read_png16 if job.codec == "prores" else _read_png16_as_8bit
    else:
        read = read_png
    with VideoWriter(job.video_path, job.size, job.spec.time.fps, crf=job.spec.output.crf,
                     background_srgb=job.spec.render.background, codec=job.codec) as writer:
        for frame in job.frames.frames():
            writer.write(read(job.png_path(frame)))
    for suffix in set(VIDEO_SUFFIX.values()) - {job.video_path.suffix}:
        # the other codec's video of an earlier run of this shot no longer matches its PNGs: remove it
        job.video_path.with_suffix(suffix).unlink(missing_ok=True)
    out = {"task": "join", "seconds": time.time() - t0, "worker": _where(), "video": str(job.video_path),
           "png_dir": str(job.png_dir)}
    if job.exr:
        out["exr_dir"] = str(job.exr_dir)
    return out
