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
    store = FrameStore(out_dir)
    survey = store.survey(scene_hash(spec) if spec is not None else None)
    problems = list(survey.problems)
    png_dir = out_dir / "png"
    pngs = sorted(png_dir.glob("*.png")) if png_dir.is_dir() else []
    problems += [f"{p}: damaged PNG (unreadable or a chunk CRC fails)" for p in pngs if png_settings(p) is None]
    problems += [f"{p}: partial {suffix[1:].upper()} of a killed render (removed by the next render)"
                 for suffix in (".mp4", ".mov") for p in sorted(out_dir.glob(f".*.partial-*{suffix}"))]
    for folder in (store.dir, png_dir, out_dir / "exr", out_dir):
        if folder.is_dir():
            problems += [f"{p}: temp file of a killed write (removed by the next run)"
                         for p in sorted(folder.iterdir()) if is_temp_name(p.name) and dead_writer(p)]
    report = {"folder": str(out_dir), "frames_verified": survey.good_frames,
              "frames_counted": int(survey.manifest["frames_complete"]) if survey.manifest else None,
              "checkpoint_frame": survey.checkpoint_frame, "pngs": len(pngs), "problems": problems,
              "intact": not problems}
    if as_json:
        print(json.dumps(report))
    else:
        for line in problems:
            print(f"fraytool: damaged: {line}", file=sys.stderr)
        state = "intact" if not problems else f"{len(problems)} problem(s); `fraytool simulate --resume` " \
                                              "or `fraytool render` re-simulates what is damaged"
        print(f"{out_dir}: {survey.good_frames} frames verify, {len(pngs)} PNGs: {state}")
    return 0 if not problems else 1
