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
from fraytool.commands.target import load_target
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
    if getattr(args, "frames", None):
        frames = parse_frame_range(args.frames, spec.time.frames)
    else:
        frames = FrameRange(0, spec.time.frames, 1)
    from fraytool.sim.run import default_out_dir

    out = Path(args.out) if getattr(args, "out", None) else target.out_dir or default_out_dir(spec)
    with OutputLock(out, "export", wait_stream=stream):
        store = ensure_frames(spec, out, frames.end, stream, target.model)
        topology = store.load_topology()
        bar = Progress(len(frames), spec.name, stream=stream, stage="export")
        try:
            records = (store.load_frame(f) for f in frames.frames())
            path = write_usd(usd_path, spec, topology, records, on_frame=bar.update)
        finally:
            bar.close()
    print(f"fraytool: exported {len(frames)} frames to {path}", file=stream)
    return 0
