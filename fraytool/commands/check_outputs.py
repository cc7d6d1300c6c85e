"""`fraytool check --outputs DIR [SCENE]`: is an output folder intact?

Checks the frame store (manifest checksum, topology, every counted frame's checksum and frame
number, the checkpoint; with a scene, that they belong to it) and every PNG (chunk CRCs), and names
stale temp files. Prints one line per problem; exit 0 when everything verifies, 1 otherwise.
`fraytool simulate --resume` or `fraytool render` repairs what it names by re-simulating.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Optional

from fraytool.errors import InputError
from fraytool.io.frame_record import dead_writer, is_temp_name
from fraytool.io.frame_store import FrameStore
from fraytool.render.encode import png_settings
from fraytool.scene import SceneSpec, scene_hash


def check_outputs(out_dir: Path, spec: Optional[SceneSpec] = None, as_json: bool = False) -> int:
    out_dir = Path(out_dir)
    if not out_dir.is_dir():
        raise InputError(f"--outputs {out_dir}: not a folder")
    if (out_dir / "job.json").is_file() and not (out_dir / "frames").exists():
        shots = sorted(d.name for d in out_dir.iterdir() if (d / "frames").is_dir())
        raise InputError(f"--outputs {out_dir}: a batch job folder (job.json); check each shot's folder, "
                         + (f"e.g. --outputs {out_dir / shots[0]} (shots: {', '.join(shots)})" if shots
                            else "none has frames yet"))
    store = FrameStore(out_dir)
    survey = store.survey(scene_hash(spec) if spec is not None else None)
    problems = list(survey.problems)
    png_dirs = sorted(d for d in out_dir.glob("png*") if d.is_dir())      # png/, png_wireframe/, png_beside/
    exr_dirs = sorted(d for d in out_dir.glob("exr*") if d.is_dir())
    pngs = [p for d in png_dirs for p in sorted(d.glob("*.png"))]
    exrs = [p for d in exr_dirs for p in sorted(d.glob("*.exr"))]
    problems += [f"{p}: damaged PNG (unreadable or a chunk CRC fails)" for p in pngs if png_settings(p) is None]
    if exrs:
        from fraytool.render.exr import exr_settings

        problems += [f"{p}: damaged EXR (unreadable, truncated or without R, G, B, A)" for p in exrs
                     if exr_settings(p) is None]
    problems += [f"{p}: partial {suffix[1:].upper()} of a killed render (removed by the next render)"
                 for suffix in (".mp4", ".mov") for p in sorted(out_dir.glob(f".*.partial-*{suffix}"))]
    videos = [p for suffix in (".mp4", ".mov") for p in sorted(out_dir.glob(f"*{suffix}"))]
    problems += [f"{p}: damaged video ({why})" for p in videos for why in [_video_problem(p)] if why]
    for folder in (store.dir, *png_dirs, *exr_dirs, out_dir):
        if folder.is_dir():
            problems += [f"{p}: temp file of a killed write (removed by the next run)"
                         for p in sorted(folder.iterdir()) if is_temp_name(p.name) and dead_writer(p)]
    report = {"folder": str(out_dir), "frames_verified": survey.good_frames,
              "frames_counted": int(survey.manifest["frames_complete"]) if survey.manifest else None,
              "checkpoint_frame": survey.checkpoint_frame, "pngs": len(pngs), "exrs": len(exrs),
              "videos": len(videos), "problems": problems,
              "intact": not problems}
    if as_json:
        print(json.dumps(report))
    else:
        for line in problems:
            print(f"fraytool: damaged: {line}", file=sys.stderr)
        state = "intact" if not problems else f"{len(problems)} problem(s); `fraytool simulate --resume` " \
                                              "or `fraytool render` re-simulates what is damaged"
        print(f"{out_dir}: {survey.good_frames} frames verify; {len(pngs)} PNGs, {len(exrs)} EXRs, "
              f"{len(videos)} videos checked: {state}")
    return 0 if not problems else 1


def _video_problem(path: Path) -> Optional[str]:
    """Why an MP4 / MOV is not complete, or None: its top-level atoms (ISO base media file format:
    32-bit size, 4-character type; size 1 = a 64-bit size follows, 0 = to the end of the file) must
    tile the file exactly, and a `moov` (the index) must be among them. A file cut short by a full
    disk or a kill ends inside an atom."""
    import struct

    size = path.stat().st_size
    seen, pos = set(), 0
    with open(path, "rb") as f:
        while pos < size:
            f.seek(pos)
            head = f.read(16)
            if len(head) < 8:
                return "ends inside an atom header"
            length, kind = struct.unpack(">I4s", head[:8])
            if length == 1:
                if len(head) < 16:
                    return "ends inside an atom header"
                length = struct.unpack(">Q", head[8:16])[0]
            elif length == 0:
                length = size - pos
            if length < 8 or pos + length > size:
                return f"truncated: the {kind.decode('latin-1')!r} atom at byte {pos} runs past the end"
            seen.add(kind)
            pos += length
    return None if b"moov" in seen else "no index (moov atom)"
