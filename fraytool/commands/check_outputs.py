"""`fraytool check --outputs DIR [SCENE]`: is an output folder intact?

Checks the frame store (manifest checksum, topology, every counted frame's checksum and frame
number, the checkpoint; with a scene, that they belong to it), that it holds every frame the run was
planned for (or, with a scene, every frame the scene asks for), every PNG (chunk CRCs) and that each
PNG folder holds one set (one size, bit depth and channel count), and names stale temp files. A batch
job folder (job.json) is checked shot by shot. Prints one line per problem; exit 0 when everything
verifies, 1 otherwise. `fraytool simulate --resume` or `fraytool render` repairs what it names.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Optional

from fraytool.errors import InputError
from fraytool.files import not_a_regular_file
from fraytool.io.frame_record import dead_writer, is_temp_name
from fraytool.io.frame_store import FrameStore
from fraytool.render.encode import png_settings
from fraytool.scene import SceneSpec, scene_hash


def check_outputs(out_dir: Path, spec: Optional[SceneSpec] = None, as_json: bool = False) -> int:
    out_dir = Path(out_dir)
    if not out_dir.is_dir():
        raise InputError(f"--outputs {out_dir}: not a folder")
    if (out_dir / "job.json").is_file() and not (out_dir / "frames").exists():
        return _check_job(out_dir, as_json)
    if not (out_dir / "frames").exists() and not any(
            any(out_dir.glob(pattern)) for pattern in ("png*/", "exr*/", "*.mp4", "*.mov")):
        raise InputError(f"--outputs {out_dir}: not a shot's output folder (no frames/, png/, exr/ or video in it; "
                         "a render writes them, by default under outputs/<scene>/)")
    report = folder_report(out_dir, spec)
    if as_json:
        print(json.dumps(report))
    else:
        _print_report(report)
    return 0 if report["intact"] else 1


def _check_job(job_dir: Path, as_json: bool) -> int:
    """A batch job folder: every shot folder (a folder with frames/) checked on its own."""
    shots = sorted(d for d in job_dir.iterdir() if d.is_dir() and (d / "frames").exists())
    if not shots:
        raise InputError(f"--outputs {job_dir}: a batch job folder (job.json) where no shot has frames yet")
    reports = [folder_report(d, None) for d in shots]
    intact = all(r["intact"] for r in reports)
    if as_json:
        print(json.dumps({"job": str(job_dir), "shots": reports, "intact": intact}))
    else:
        for r in reports:
            _print_report(r)
        bad = [Path(r["folder"]).name for r in reports if not r["intact"]]
        print(f"{job_dir}: {len(reports)} shot(s) checked: "
              + ("intact" if intact else f"problems in {', '.join(bad)}"))
    return 0 if intact else 1


def _print_report(report: dict) -> None:
    for line in report["problems"]:
        print(f"fraytool: damaged: {line}", file=sys.stderr)
    problems = report["problems"]
    state = "intact" if not problems else f"{len(problems)} problem(s); `fraytool simulate --resume` " \
                                          "or `fraytool render` re-simulates what is damaged or missing"
    print(f"{report['folder']}: {report['frames_verified']} frames verify; {report['pngs']} PNGs, "
          f"{report['exrs']} EXRs, {report['videos']} videos checked: {state}")


def folder_report(out_dir: Path, spec: Optional[SceneSpec]) -> dict:
    """The check of one output folder, as the --json report."""
    store = FrameStore(out_dir)
    survey = store.survey(scene_hash(spec) if spec is not None else None)
    problems = list(survey.problems)
    planned = None
    if survey.manifest is not None:
        planned = int(survey.manifest.get("frames_planned", 0) or 0)
        if spec is not None:
            planned = max(planned, spec.time.frames)
        complete = int(survey.manifest["frames_complete"])
        if complete < planned:
            problems.append(f"{store.dir}: incomplete: frames {complete}-{planned - 1} of {planned} are missing "
                            f"(a run stopped at frame {complete}; `fraytool simulate --resume` finishes it)")
    png_dirs = sorted(d for d in out_dir.glob("png*") if d.is_dir())      # png/, png_wireframe/, png_beside/
    exr_dirs = sorted(d for d in out_dir.glob("exr*") if d.is_dir())
    special = [(p, why) for d in (store.dir, *png_dirs, *exr_dirs, out_dir) if d.is_dir() for p in sorted(d.iterdir())
               if not p.is_dir() for why in [not_a_regular_file(p)] if why is not None and why != "no such file"]
    problems += [f"{p}: {why}" for p, why in special if not any(str(p) in line for line in problems)]
    skip = {p for p, _ in special}
    pngs = [p for d in png_dirs for p in sorted(d.glob("*.png")) if p not in skip]
    exrs = [p for d in exr_dirs for p in sorted(d.glob("*.exr")) if p not in skip]
    problems += [f"{p}: damaged PNG (unreadable or a chunk CRC fails)" for p in pngs if png_settings(p) is None]
    for d in png_dirs:
        problems += mixed_png_sets(d)
    if exrs:
        from fraytool.render.exr import exr_settings

        problems += [f"{p}: damaged EXR (unreadable, truncated or without R, G, B, A)" for p in exrs
                     if exr_settings(p) is None]
    problems += [f"{p}: partial {suffix[1:].upper()} of a killed render (removed by the next render)"
                 for suffix in (".mp4", ".mov") for p in sorted(out_dir.glob(f".*.partial-*{suffix}"))]
    videos = [p for suffix in (".mp4", ".mov") for p in sorted(out_dir.glob(f"*{suffix}")) if p not in skip]
    problems += [f"{p}: damaged video ({why})" for p in videos for why in [_video_problem(p)] if why]
    for folder in (store.dir, *png_dirs, *exr_dirs, out_dir):
        if folder.is_dir():
            problems += [f"{p}: temp file of a killed write (removed by the next run)"
                         for p in sorted(folder.iterdir()) if is_temp_name(p.name) and dead_writer(p)]
    return {"folder": str(out_dir), "frames_verified": survey.good_frames,
            "frames_counted": int(survey.manifest["frames_complete"]) if survey.manifest else None,
            "frames_planned": planned, "checkpoint_frame": survey.checkpoint_frame, "pngs": len(pngs),
            "exrs": len(exrs), "videos": len(videos), "problems": problems, "intact": not problems}


PNG_COLOUR_CHANNELS = {0: 1, 2: 3, 3: 1, 4: 2, 6: 4}
"""PNG colour type -> channels (grey, RGB, palette, grey + alpha, RGBA)."""


def png_header(path: Path) -> Optional[tuple[int, int, int, int]]:
    """(width, height, bit depth, channels) from a PNG's IHDR chunk, or None if it has none."""
    import struct

    if not_a_regular_file(path) is not None:
        return None
    try:
        with open(path, "rb") as f:
            head = f.read(29)
    except OSError:
        return None
    if len(head) < 29 or head[:8] != b"\x89PNG\r\n\x1a\n" or head[12:16] != b"IHDR":
        return None
    width, height, depth, colour = struct.unpack(">IIBB", head[16:26])
    return width, height, depth, PNG_COLOUR_CHANNELS.get(colour, 0)


def mixed_png_sets(folder: Path) -> list[str]:
    """One line when the PNGs of `folder` are of more than one size, bit depth or channel count (frames of
    two renders side by side), naming how many of each."""
    kinds: dict = {}
    for p in sorted(folder.glob("*.png")):
        h = png_header(p)
        if h is not None:
            kinds.setdefault(h, []).append(p.name)
    if len(kinds) < 2:
        return []
    names = {1: "grey", 2: "grey+alpha", 3: "RGB", 4: "RGBA"}
    parts = [f"{len(v)} of {w}x{h} {d}-bit {names.get(c, f'{c}-channel')} (e.g. {v[0]})"
             for (w, h, d, c), v in sorted(kinds.items(), key=lambda kv: -len(kv[1]))]
    return [f"{folder}: PNGs of {len(kinds)} different renders mixed: " + "; ".join(parts)
            + f" ({MIXED_PNGS_FIX})"]


MIXED_PNGS_FIX = ("a frame range rendered at other settings into the folder of an earlier render: render every "
                  "frame at one setting, which replaces the others, or remove one set")


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
