"""Simulate a scene and draw chosen frames for a golden: 16-bit sRGB images (no alpha), the centre-line
points of every yarn piece, and the torn structural springs (fraytool.golden)."""
from __future__ import annotations

import platform
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional, Sequence, TextIO

import numpy as np

from fraytool.kinds import STRUCT_WARP, STRUCT_WEFT
from fraytool.scene.spec import SceneSpec


@dataclass
class FrameCapture:
    frame: int
    image: np.ndarray
    """sRGB, 16 bits per channel, shape (H, W, 3), uint16."""
    points_m: np.ndarray
    """Control points of every yarn piece [m], shape (N, 3), float32 (fraytool.render.yarns)."""
    offsets: np.ndarray
    """Piece p owns points offsets[p]:offsets[p+1], shape (K + 1,), int64."""
    torn_springs: int
    """Structural springs torn by the frame (not alive, not cut before or by scissors)."""
    time_s: float = 0.0
    """The frame record's simulated time [s]: a moving camera's pose when the frame was drawn."""


@dataclass
class Capture:
    frames: list[FrameCapture] = field(default_factory=list)
    renderer: str = ""
    """GL_RENDERER and GL_VERSION of the context that drew the frames."""


def default_frames(spec: SceneSpec) -> list[int]:
    """The scene's [golden] frames, else its first, middle and last."""
    if spec.golden.frames:
        return sorted(set(spec.golden.frames))
    last = spec.time.frames - 1
    return sorted({0, last // 2, last})


def machine() -> str:
    """The CPU the frames were made on (metadata; a golden made elsewhere may differ in the last bits)."""
    name = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                name = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return name


def capture(spec: SceneSpec, frames: Sequence[int], work_dir: Path, stream: TextIO = sys.stderr,
            progress: Optional[bool] = None) -> Capture:
    """Simulate `spec` into work_dir (resuming frames already there) up to the last frame asked, and draw
    `frames` with one renderer. `progress`: None follows --progress (a bar on a terminal, quiet otherwise)."""
    from fraytool.render.color import encode_premultiplied_linear
    from fraytool.render.context import create_context, gl_strings
    from fraytool.render.renderer import Renderer
    from fraytool.render.yarns import yarn_pieces
    from fraytool.sim.run import simulate_to_disk
    from fraytool.io.frame_store import FrameStore

    store = FrameStore(Path(work_dir))
    survey = store.survey()
    if survey.good_frames < max(frames) + 1 or not survey.clean:
        simulate_to_disk(spec, Path(work_dir), frames=max(frames) + 1, resume=survey.good_frames > 0,
                         stream=stream, progress=progress)
    topology = store.load_topology()
    kind = np.asarray(topology["spring_kind"])
    structural = (kind == STRUCT_WEFT) | (kind == STRUCT_WARP)
    cut = np.asarray(topology["spring_precut"], bool) | np.isfinite(np.asarray(topology["spring_cut_time_s"]))
    out = Capture()
    ctx = create_context()
    try:
        out.renderer = gl_strings(ctx)
        renderer = Renderer(ctx, tuple(spec.render.resolution), spec.render.samples, spec.render, spec.camera,
                            topology, target="float", panels_spec=spec.all_panels)
        builder = renderer.geometry_builder(topology)
        try:
            for f in frames:
                record = store.load_frame(f)
                renderer.draw(builder.build(record))
                image = encode_premultiplied_linear(renderer.read_linear(), 16, False)
                pieces = yarn_pieces(topology, record.particle_position_m, record.crossing_yarn_level,
                                     record.spring_alive)
                torn = int((structural & ~np.asarray(record.spring_alive, bool) & ~cut).sum())
                out.frames.append(FrameCapture(f, np.ascontiguousarray(image[..., :3]),
                                               pieces.points.astype(np.float32), pieces.offsets, torn,
                                               float(record.time_s)))
        finally:
            renderer.release()
    finally:
        ctx.release()
    return out
