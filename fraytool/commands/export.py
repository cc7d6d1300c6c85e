"""`fraytool export SCENE --usd OUT.usd`: simulate (or reuse frames of the same scene hash) and write the
yarns and bodies as USD (fraytool.export.usd).

Order of work, so that mistakes fail fast: the USD library and every flag (InputError, exit 2) -> make
sure the frame records exist (as `fraytool render` does; the whole shot when [camera] fit = true) -> fit
the camera if asked -> write the file.
"""
from __future__ import annotations

import sys
from typing import Optional, TextIO

from fraytool.commands.render import ensure_frames, fitted_line
from fraytool.commands.target import load_target
from fraytool.errors import InputError
from fraytool.io.lock import OutputLock
from fraytool.progress import Progress
from fraytool.render.options import FrameRange, parse_frame_range


def export_command(args, stream: Optional[TextIO] = None) -> int:
    stream = stream or sys.stderr
    from fraytool.export.usd import check_usd_path, require_usd, write_usd

    require_usd()
    usd_path = check_usd_path(args.usd)
    target = load_target(args.scene, getattr(args, "sets", None) or (), force=bool(getattr(args, "force", False)))
    spec = target.spec
    _check_camera(spec)
    if getattr(args, "frames", None):
        frames = parse_frame_range(args.frames, spec.time.frames, shot_folder=target.out_dir is not None)
    else:
        frames = FrameRange(0, spec.time.frames, 1)
    out = target.output_dir(getattr(args, "out", None))
    with OutputLock(out, "export", wait_stream=stream):
        needed = _frames_needed(spec, frames)
        store = ensure_frames(spec, out, needed, stream, target.model, target.digest, target.frame_sources())
        if spec.camera.fit:
            spec = _with_fitted_camera(spec, store, stream)
        topology = store.load_topology()
        bar = Progress(len(frames), spec.name, stream=stream, stage="export")
        try:
            from fraytool.export.velocities import FrameSource

            source = FrameSource(range(needed), store.load_frame)
            records = (source.get(f) for f in frames.frames())
            path = write_usd(usd_path, spec, topology, records, on_frame=bar.update, frames=source)
        finally:
            bar.close()
    print(f"fraytool: exported {len(frames)} frames to {path}", file=stream)
    return 0


def _frames_needed(spec, frames: FrameRange) -> int:
    """How many frame records (0 .. n-1) the export reads: the whole shot for a fitted camera (as
    `fraytool render --fit` frames it), else the exported range and the frame after it, which the
    velocities of the last exported frame difference with (fraytool.export.velocities)."""
    if spec.camera.fit:
        return spec.time.frames
    return min(frames.end + 1, spec.time.frames)


def _with_fitted_camera(spec, store, stream: TextIO):
    """The scene with the camera `fraytool render` uses for [camera] fit = true (fraytool.render.fit)."""
    import dataclasses

    from fraytool.render.fit import fitted_camera

    camera = fitted_camera(spec, store)
    print(f"fraytool: fit: {fitted_line(camera)}", file=stream)
    return dataclasses.replace(spec, camera=camera)


def _check_camera(spec) -> None:
    """InputError (exit 2) before any simulating when the USD camera cannot be made (the renderer's
    Camera: an up vector along the view direction)."""
    from fraytool.render.camera import check_camera

    try:
        check_camera(spec.camera)
    except InputError as exc:
        raise InputError(f"{spec.source}: [camera]: {exc}") from None
