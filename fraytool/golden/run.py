"""Update and check one scene's golden (used by `fraytool golden` and by fraytool.testing)."""
from __future__ import annotations

import os
import shlex
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional, Sequence, TextIO

from fraytool.errors import InputError, SceneError
from fraytool.golden import store
from fraytool.golden.capture import capture, default_frames
from fraytool.scene import load_scene
from fraytool.golden.compare import FrameVerdict, judge
from fraytool.scene.spec import SceneSpec


def parse_frames(text: Optional[str], spec: SceneSpec) -> list[int]:
    """--frames 0,35,71 (a list; default: the scene's [golden] frames, else first, middle and last)."""
    if not text:
        return default_frames(spec)
    try:
        frames = sorted({int(f) for f in text.split(",") if f.strip()})
    except ValueError:
        raise InputError(f"--frames {text!r}: expected frame numbers separated by commas, e.g. 0,35,71 (golden "
                         "frames are a list, not a range)") from None
    bad = [f for f in frames if not 0 <= f < spec.time.frames]
    if bad or not frames:
        raise InputError(f"--frames {text!r}: frames must lie in 0..{spec.time.frames - 1} ([time] frames = "
                         f"{spec.time.frames})")
    return frames


def load_for_golden(scene: str, sets: list[str]) -> SceneSpec:
    from fraytool.scene.overrides import parse_assignment
    from fraytool.sim.memory import admission_problems

    spec = load_scene(scene, [parse_assignment(a) for a in sets])
    problems = admission_problems(spec, force=False)
    if problems:
        raise SceneError(problems)
    return spec


def recorded_sets(golden_dir: Path, scene_name: str) -> list[str]:
    """The --set overrides a scene's golden was made with (its golden.json); [] without a readable golden."""
    import json

    from fraytool.files import regular_files_only

    try:
        meta = json.loads(regular_files_only(Path(golden_dir) / scene_name / store.METADATA).read_text())
        sets = meta["settings"]["set"]
    except (OSError, ValueError, KeyError, TypeError):
        return []
    return [str(s) for s in sets] if isinstance(sets, list) else []


def sets_for_check(recorded: Sequence[str], sets: Sequence[str]) -> list[str]:
    """A check applies the golden's recorded --set first, then its own on top (a later one wins), so a golden
    made at `--set render.resolution=[640,360]` is checked at that size without repeating it. A given set
    that repeats the value the recorded ones leave its key at is not added again (the settings then match
    the golden's)."""
    def key(assignment: str) -> str:
        return assignment.split("=", 1)[0].strip()

    last = {key(a): a for a in recorded}
    return list(recorded) + [a for a in sets if last.get(key(a)) != a]


def load_for_check(scene: str, golden_dir: Path, sets: Sequence[str]) -> tuple[SceneSpec, list[str]]:
    """The scene as its golden check renders it, and the --set list that makes it (sets_for_check). The
    scene is admitted (memory, meshes) only as checked: a golden kept at a smaller --set size is checked
    at that size on a machine that could not run the scene as written."""
    from fraytool.errors import FraytoolError
    from fraytool.scene.overrides import parse_assignment

    name = load_scene(scene, [parse_assignment(a) for a in sets]).name
    recorded = recorded_sets(golden_dir, name)
    effective = sets_for_check(recorded, sets)
    try:
        return load_for_golden(scene, effective), effective
    except FraytoolError as exc:
        if not recorded:
            raise
        where = Path(golden_dir) / name / store.METADATA
        raise InputError(f"{exc} (the golden's own --set {' '.join(recorded)}, recorded in {where}, applies "
                         "first: make the golden again if a key was renamed)") from None


def update_command_line(scene: str, golden_dir: Path, sets: list[str]) -> str:
    """The command that makes a missing golden (quoted for a shell)."""
    flags = "".join(f" --set {shlex.quote(s)}" for s in sets)
    return f"fraytool golden update {shlex.quote(scene)} --dir {shlex.quote(str(golden_dir))}{flags}"


def work_dir(root: Optional[Path], spec: SceneSpec) -> Path:
    """Where a golden run's frames are simulated: <root>/<scene>/<scene hash> (default root outputs/golden)."""
    from fraytool.scene.load import scene_hash

    return Path(root or Path("outputs") / "golden") / spec.name / scene_hash(spec)


@dataclass
class SceneCheck:
    scene: str
    golden_dir: Path
    verdicts: list[FrameVerdict] = field(default_factory=list)
    images: dict = field(default_factory=dict)
    """frame -> (golden image, new image), uint16 (H, W, 3)."""
    differences: list[str] = field(default_factory=list)
    """Metadata that differs between the golden and this check (version, scene hash, settings, renderer, CPU)."""


def update_scene(spec: SceneSpec, golden_dir: Path, frames: Sequence[int], sets: Sequence[str] = (),
                 work_root: Optional[Path] = None, stream: TextIO = sys.stderr) -> Path:
    captured = capture(spec, list(frames), work_dir(work_root, spec), stream=stream)
    return store.write(Path(golden_dir), spec, captured, list(sets))


def check_scene(spec: SceneSpec, golden_dir: Path, frames: Optional[Sequence[int]], command: str,
                sets: Sequence[str] = (), work_root: Optional[Path] = None, stream: TextIO = sys.stderr) -> SceneCheck:
    """Render the golden's frames (or `frames`, which it must hold) again and judge each against it."""
    from fraytool.errors import InputError

    meta, golden = store.read(Path(golden_dir), spec, command)
    chosen = sorted(golden) if not frames else list(frames)
    missing = [f for f in chosen if f not in golden]
    if missing:
        keep = sorted(set(golden) | set(chosen))    # the update rewrites the golden: keep the frames it has
        raise InputError(f"{store.scene_dir(golden_dir, spec)}: the golden has no frame "
                         f"{', '.join(map(str, missing))}: make it with `{command} --frames "
                         f"{','.join(map(str, keep))}`")
    captured = capture(spec, chosen, work_dir(work_root, spec), stream=stream)
    thickness = float(meta.get("thickness_m", spec.cloth.thickness_m))
    out = SceneCheck(spec.name, store.scene_dir(golden_dir, spec))
    for f in captured.frames:
        new = {"image": f.image, "points": f.points_m, "offsets": f.offsets, "torn_springs": f.torn_springs}
        verdict = judge(f.frame, golden[f.frame], new, spec.golden, thickness)
        at = verdict.figures.pop("moved_most_point_m", None)
        pixel = project_to_pixel(spec, at, f.time_s) if at is not None else None
        if pixel is not None:
            verdict.figures["moved_most_pixel"] = pixel
        out.verdicts.append(verdict)
        out.images[f.frame] = (golden[f.frame]["image"], f.image)
    out.differences = store.settings_differences(meta, spec, list(sets), captured.renderer)
    return out


def project_to_pixel(spec: SceneSpec, point_m, time_s: float = 0.0) -> Optional[list[int]]:
    """The pixel (x right, y down, of the scene's resolution) where the camera sees `point_m` at time_s (a
    moving camera's pose then: the frame's); None behind the camera or outside the picture."""
    import numpy as np

    from fraytool.render.camera import Camera

    width, height = spec.render.resolution
    clip = Camera(spec.camera, time_s).view_proj(width / height) @ np.append(np.asarray(point_m, float), 1.0)
    if clip[3] <= 0.0:
        return None
    x = (clip[0] / clip[3] + 1.0) * 0.5 * width
    y = (1.0 - clip[1] / clip[3]) * 0.5 * height
    if not (0.0 <= x < width and 0.0 <= y < height):
        return None
    return [int(x), int(y)]


def farm_task(scene: str, sets: Sequence, golden_dir: str, work_root: Optional[str], report_dir: Optional[str],
              update: bool) -> dict:
    """One shot of `fraytool batch --golden-check / --golden-update` on a Dask worker: update the shot's golden,
    or check it and write its part of the report (images) into report_dir. Returns the report entry
    ({scene, frames: [{frame, status, figures, reasons, images}], ...}) or {scene, error}."""
    import json

    from fraytool.errors import FraytoolError
    from fraytool.golden.report import Report
    from fraytool.threads import set_up_threads

    set_up_threads(1)
    text_sets = [f"{k}={json.dumps(v)}" for k, v in sets]
    work = Path(work_root) if work_root else None
    try:
        if update:
            spec = load_scene(scene, list(sets))
        else:   # the golden's recorded --set first, as `fraytool golden check`
            spec, text_sets = load_for_check(scene, Path(golden_dir), text_sets)
        with open(os.devnull, "w") as quiet:  # a worker has no terminal: no progress
            if update:
                update_scene(spec, Path(golden_dir), default_frames(spec), text_sets, work, stream=quiet)
                return {"scene": spec.name, "updated": True, "frames": []}
            result = check_scene(spec, Path(golden_dir), None,
                                 update_command_line(scene, Path(golden_dir), text_sets), text_sets, work, stream=quiet)
    except FraytoolError as exc:
        return {"scene": scene, "error": str(exc).splitlines()[0]}
    report = Report(Path(report_dir) if report_dir else None)
    report.add(spec.name, result.golden_dir, result.verdicts, result.images, result.differences, spec.golden.fail)
    return report.scenes[0]
