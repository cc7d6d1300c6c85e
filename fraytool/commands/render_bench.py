"""Render stage timings for `fraytool bench --render`: milliseconds per frame for
- "geometry": frame record -> yarn pieces -> splines -> tubes (NumPy/numba, fraytool.render.geometry);
- "draw": upload, shadow map, GL draw into the multisampled target and resolve, to completion (glFinish);
  ``draw_parts`` splits it (Renderer.part_s: the GL queue is finished before and after each part, so
  the parts add up to about the draw): "shadow_map" (the key light's depth pass), "yarns" (opaque and
  fading yarns), "bodies", "ground", "resolve" (multisample resolve), "other" (upload, clears);
- "readback": reading the resolved image back to the CPU, flipping it (and un-premultiplying with alpha);
- "encode": H.264 MP4 encoding (the default output), per frame of a long shot: the frames are encoded
  once as they are and once three times over (forwards, backwards, forwards: no jump for x264 to
  take as a scene cut), and the difference divided by the extra frames is the figure
  (``video["encode_estimate"]`` "marginal"; when timing noise makes the difference negative, the
  three-pass video's average per frame, "average"); what a video costs once (starting ffmpeg, flushing x264's look-ahead, writing the index:
  ``video["start_finish_ms"]``) is reported apart, as it is spread over a whole shot in a real render.

Stages are timed one after the other (all frames are drawn first, then encoded), so each figure is
what that stage costs on its own and the sum is the per-frame cost of a sequential render. The
first frame is drawn once before timing (numba compilation or cache load, shader compilation).
Size and samples are the scene's ``[render] resolution`` and ``samples`` (so `--set` changes them);
on llvmpipe the draw grows with the pixels and samples as well as the triangles.
Figures are medians over the frames, except encode (above; ffmpeg works ahead of the pipe, so
single-frame figures mean little).
"""
from __future__ import annotations

import dataclasses
import statistics
import tempfile
import time
from pathlib import Path
from typing import Optional

from fraytool.io.frame_store import FrameStore
from fraytool.render.context import create_context
from fraytool.render.encode import VideoWriter
from fraytool.render.renderer import Renderer
from fraytool.scene import scene_hash
from fraytool.scene.spec import SceneSpec

DEFAULT_FRAMES = 10


def _frames_dir(spec: SceneSpec, out_dir: Optional[Path], frames: int, tmp: str) -> FrameStore:
    """A FrameStore holding at least `frames` records of this scene: out_dir (or outputs/<scene>) if
    it already has them, else a fresh simulation in the temporary folder."""
    from fraytool.sim.run import default_out_dir, simulate_to_disk

    for candidate in (out_dir, default_out_dir(spec)):
        if candidate is None:
            continue
        store = FrameStore(Path(candidate))
        if store.matches(scene_hash(spec)) and store.frames_complete() >= frames:
            return store
    target = Path(out_dir) if out_dir is not None else Path(tmp)
    simulate_to_disk(spec, target, frames=frames, progress=False)
    return FrameStore(target)


def render_stage_timings(spec: SceneSpec, out_dir: Optional[Path] = None, frames: int = DEFAULT_FRAMES,
                         resolution: Optional[tuple[int, int]] = None, samples: Optional[int] = None,
                         parts: Optional[dict[str, float]] = None,
                         video: Optional[dict[str, float]] = None) -> dict[str, float]:
    """Milliseconds per frame of the render stages for the first `frames` frames of `spec`, at
    `resolution` and `samples` (default: the scene's). `parts`, if given, receives the median
    milliseconds per frame of the draw's parts, and `video` the once-per-video encoding cost
    (module docstring)."""
    resolution = tuple(resolution or spec.render.resolution)
    samples = spec.render.samples if samples is None else int(samples)
    spec = dataclasses.replace(spec, render=dataclasses.replace(spec.render, resolution=resolution,
                                                                samples=samples))
    frames = max(1, min(frames, spec.time.frames))
    W, H = resolution
    with tempfile.TemporaryDirectory(prefix="fraytool-bench-render-") as tmp:
        store = _frames_dir(spec, out_dir, frames, tmp)
        topology = store.load_topology()
        records = [store.load_frame(f) for f in range(frames)]
        ctx = create_context()
        try:
            renderer = Renderer(ctx, (W, H), samples, spec.render, spec.camera, topology,
                                panels_spec=spec.all_panels)
            builder = renderer.geometry_builder(topology)
            renderer.render(builder.build(records[0]))  # warm-up: numba, shaders, buffers
            geometry_s, draw_s, read_s, images = [], [], [], []
            for record in records:
                t0 = time.perf_counter()
                geom = builder.build(record)
                t1 = time.perf_counter()
                renderer.draw(geom)
                ctx.finish()  # llvmpipe draws asynchronously: wait, so the read-back is timed alone
                t2 = time.perf_counter()
                images.append(renderer.read())
                t3 = time.perf_counter()
                geometry_s.append(t1 - t0)
                draw_s.append(t2 - t1)
                read_s.append(t3 - t2)
                del geom  # (kept, every frame's arrays would be fresh memory: page faults a render never has)
            if parts is not None:  # timed apart: finishing the queue between parts costs a little
                per_frame = []
                for record in records:
                    geom = builder.build(record)
                    renderer.part_s = {}
                    t0 = time.perf_counter()
                    renderer.draw(geom)
                    ctx.finish()
                    total = time.perf_counter() - t0
                    renderer.part_s["other"] = total - sum(renderer.part_s.values())
                    per_frame.append(renderer.part_s)
                renderer.part_s = None
                for name in dict.fromkeys(n for p in per_frame for n in p):  # every part any frame had
                    parts[name] = 1e3 * statistics.median(p.get(name, 0.0) for p in per_frame)
            renderer.release()
        finally:
            ctx.release()
        n = len(images)
        once = _encode_seconds(Path(tmp) / "once.mp4", images, (W, H), spec, repeat=1)
        thrice = _encode_seconds(Path(tmp) / "thrice.mp4", images, (W, H), spec, repeat=3)
        encode_s, estimate = (thrice - once) / (2 * n), "marginal"
        if encode_s <= 0.0:  # timing noise larger than the frames' cost: the whole-video average instead
            encode_s, estimate = thrice / (3 * n), "average"
        if video is not None:
            video["start_finish_ms"] = 1e3 * max(once - n * encode_s, 0.0)
            video["encode_estimate"] = estimate
    return {
        "geometry": 1e3 * statistics.median(geometry_s),
        "draw": 1e3 * statistics.median(draw_s),
        "readback": 1e3 * statistics.median(read_s),
        "encode": 1e3 * encode_s,
    }


def _encode_seconds(path: Path, images: list, size: tuple[int, int], spec: SceneSpec, repeat: int) -> float:
    """Wall time to encode `images` `repeat` times over (every other pass backwards, so the video never
    jumps) into one H.264 MP4, ffmpeg start to file closed."""
    t0 = time.perf_counter()
    with VideoWriter(path, size, spec.time.fps, crf=spec.output.crf) as writer:
        for k in range(repeat):
            for image in (images if k % 2 == 0 else images[::-1]):
                writer.write(image)
    return time.perf_counter() - t0
