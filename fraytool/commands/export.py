"""`fraytool export SCENE --usd OUT.usd`: simulate (or reuse frames of the same scene hash) and write the
yarns and bodies as USD (fraytool.export.usd).

Order of work, so that mistakes fail fast: the USD library and every flag (InputError, exit 2) -> make
sure the frame records exist (as `fraytool render` does) -> write the file.
"""
from __future__ import annotations

import sys
from pathlib import Path
from typing import Optional, TextIO

from fraytool.commands.render import ensure_frames
from fraytool.errors import SceneError
from fraytool.io.lock import OutputLock
from fraytool.progress import Progress
from fraytool.render.options import FrameRange, parse_frame_range
from fraytool.scene import load_scene


def export_command(args, stream: Optional[TextIO] = None) -> int:
    stream = stream or sys.stderr
    from fraytool.export.usd import check_usd_path, require_usd, write_usd

    require_usd()
    usd_path = check_usd_path(args.usd)
    from fraytool.scene.overrides import parse_assignment

    spec = load_scene(args.scene, [parse_assignment(a) for a in getattr(args, "sets", None) or ()])
    from fraytool.sim.memory import admission_problems

    problems = admission_problems(spec, force=bool(getattr(args, "force", False)))
    if problems:
        raise SceneError(problems)
    if getattr(args, "frames", None):
        frames = parse_frame_range(args.frames, spec.time.frames)
    else:
        frames = FrameRange(0, spec.time.frames, 1)
    from fraytool.sim.run import default_out_dir

    out = Path(args.out) if getattr(args, "out", None) else default_out_dir(spec)
    with OutputLock(out, "export", wait_stream=stream):
        store = ensure_frames(spec, out, frames.end, stream)
        topology = store.load_topology()
        bar = Progress(len(frames), spec.name, stream=stream, stage="export")
        try:
            records = (store.load_frame(f) for f in frames.frames())
            path = write_usd(usd_path, spec, topology, records, on_frame=bar.update)
        finally:
            bar.close()
    print(f"fraytool: exported {len(frames)} frames to {path}", file=stream)
    return 0
