"""What `fraytool batch` runs: Shots, from scene files, a job file (TOML), --set and --wedge.

A job file:

    [job]
    name = "seeds"            # default: the file's stem; job.json and the shot folders go to -o or outputs/<name>
    chunk_frames = 24         # frames per render task (default 24)

    [render]                  # defaults for every shot (each shot may override them in its own table)
    resolution = [640, 360]
    samples = 4
    wireframe = "off"         # "off", "only", "beside"
    frames = "0:48"           # START:END[:STEP]; default: the whole scene
    motion_blur = 0.5         # shutter, a fraction of a frame (as --motion-blur; 0: off, the default)
    motion_samples = 8        # sub-frames per blurred frame (as --motion-samples)
    supersample = 1           # drawn pixels per output pixel along each axis, 1-4 (as --supersample)

    [[shots]]
    scene = "fig7_square_grab"                  # a path (relative to the job file) or a shipped name
    set = { "cloth.tearing.break_strain" = 0.3 } # --set overrides (quoted dotted keys)
    wedge = { "scene.seed" = [1, 2, 3, 4] }      # one shot per value, plus a contact sheet
    render = { resolution = [320, 180] }

A wedge (job file or `--wedge KEY=V1,V2,...`, ranges `KEY=1..8` for integers and `KEY=0.1..0.3:0.1`)
expands one scene into one shot per value, named `<scene>_<last key part>-<value>`, each in its own
folder; the values are set with the scene's name, so every output file has its own name.
"""
from __future__ import annotations

import math
import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Optional, Sequence

from fraytool.errors import FraytoolError, InputError
from fraytool.scene.overrides import parse_assignment, parse_value

DEFAULT_CHUNK_FRAMES = 24
MAX_WEDGE_VALUES = 1000
_JOB_KEYS = {"name", "chunk_frames"}
_RENDER_KEYS = {"resolution", "samples", "wireframe", "frames", "alpha", "depth", "exr", "codec", "fit",
                "motion_blur", "motion_samples", "supersample"}
_SHOT_KEYS = {"scene", "set", "wedge", "render", "name"}


@dataclass(frozen=True)
class RenderOptions:
    resolution: Optional[tuple[int, int]] = None
    samples: Optional[int] = None
    wireframe: Optional[str] = None
    """"off", "only", "beside"; None: not given (off)."""
    frames: Optional[str] = None
    """START:END[:STEP] or None for the whole scene."""
    alpha: Optional[bool] = None
    """Transparent background (as `fraytool render --alpha`); None: not given (off)."""
    depth: Optional[int] = None
    """PNG bits, 8 or 16 (as `--depth`); None: not given (8)."""
    exr: Optional[bool] = None
    """Also an EXR sequence (as `--exr`); None: not given (off)."""
    codec: Optional[str] = None
    """Video codec, "h264" or "prores" (as `--codec`); None: not given (h264). ProRes makes the PNGs
    16-bit RGBA (the join encodes the .mov from them)."""
    fit: Optional[bool] = None
    """Frame the cloth over the whole shot (as `--fit`); None: not given (the scene's [camera] fit)."""
    motion_blur: Optional[float] = None
    """Shutter as a fraction of a frame (as `--motion-blur`); None: not given (0, off)."""
    motion_samples: Optional[int] = None
    """Sub-frames per blurred frame (as `--motion-samples`); None: not given (8)."""
    supersample: Optional[int] = None
    """Drawn pixels per output pixel along each axis (as `--supersample`); None: the scene's [render] supersample."""


@dataclass(frozen=True)
class Shot:
    name: str
    """Folder name under the job folder, and the scene name of its files."""
    scene: str
    """Scene path or shipped name, as given."""
    sets: tuple[tuple[str, Any], ...]
    render: RenderOptions
    group: str = ""
    """Wedge group (the scene's own name) for the contact sheet; "" when not wedged."""
    label: str = ""
    """The wedged value, e.g. "seed=3", written on the contact sheet."""
    error: Optional[str] = None
    """Set when the shot is invalid (bad scene): reported, never run."""


@dataclass
class Job:
    name: str
    shots: list[Shot] = field(default_factory=list)
    chunk_frames: int = DEFAULT_CHUNK_FRAMES


def parse_wedge(text: str, flag: str = "--wedge") -> tuple[str, list[Any]]:
    """'KEY=V1,V2,...' or 'KEY=A..B' (integers, inclusive) or 'KEY=A..B:STEP' -> (key, values)."""
    key, value = parse_assignment(text, flag)
    raw = text.partition("=")[2].strip()
    m = re.fullmatch(r"(-?[0-9.e+-]+)\.\.(-?[0-9.e+-]+)(?::([0-9.e+-]+))?", raw)
    if m:
        a, b, step = (parse_value(x) if x is not None else None for x in m.groups())
        if not all(isinstance(v, (int, float)) for v in (a, b)) or (step is not None and not isinstance(step, (int, float))):
            raise InputError(f"{flag} {text}: a range is A..B or A..B:STEP with numbers")
        if step is None:
            if not (isinstance(a, int) and isinstance(b, int)):
                raise InputError(f"{flag} {text}: a range without :STEP needs integers")
            step = 1
        if step <= 0 or b < a:
            raise InputError(f"{flag} {text}: a range needs A <= B and STEP > 0")
        count = int(math.floor((b - a) / step + 1e-9)) + 1
        if count > MAX_WEDGE_VALUES:
            raise InputError(f"{flag} {text}: {count} values; at most {MAX_WEDGE_VALUES}")
        values = [a + k * step for k in range(count)]
        values = [round(v, 12) if isinstance(v, float) else v for v in values]
    elif isinstance(value, list):
        values = value
    elif (dashed := re.fullmatch(r"\s*(-?\d+)\s*-\s*(-?\d+)\s*", raw)) and not key.endswith("name"):
        # 1-3 for a number: a range meant (a name may be "1-3")
        raise InputError(f"{flag} {text}: a range is written A..B (e.g. {key}={dashed[1]}..{dashed[2]}); "
                         f"a list is V1,V2,...")
    else:
        values = [parse_value(v.strip()) for v in _split_top(raw)]
    if not values:
        raise InputError(f"{flag} {text}: no values")
    return key, values


def _split_top(raw: str) -> list[str]:
    """Split on commas outside brackets (so vector values stay whole)."""
    parts, depth, cur = [], 0, ""
    for ch in raw:
        depth += ch in "[{"
        depth -= ch in "]}"
        if ch == "," and depth == 0:
            parts.append(cur)
            cur = ""
        else:
            cur += ch
    parts.append(cur)
    return [p for p in parts if p.strip()]


def _value_text(v: Any) -> str:
    text = str(v).lower() if isinstance(v, bool) else (f"{v:g}" if isinstance(v, float) else str(v))
    return re.sub(r"[^A-Za-z0-9._-]+", "_", text).strip("_.") or "v"


def expand(scene: str, sets: Sequence[tuple[str, Any]], wedges: Sequence[tuple[str, list[Any]]],
           render: RenderOptions, name: Optional[str] = None) -> list[Shot]:
    """One shot, or one per combination of wedge values, with its name and overrides."""
    from fraytool.scene import load_scene

    if Path(scene).is_file():
        scene = str(Path(scene).resolve())  # remote workers run elsewhere
    try:
        base = name or load_scene(scene, list(sets)).name
    except FraytoolError as exc:
        return [Shot(name=name or Path(scene).stem, scene=scene, sets=tuple(sets), render=render, error=str(exc))]
    combos: list[list[tuple[str, Any]]] = [[]]
    for key, values in wedges:
        combos = [c + [(key, v)] for c in combos for v in values]
    shots = []
    for combo in combos:
        shot_name = base + "".join(f"_{k.split('.')[-1]}-{_value_text(v)}" for k, v in combo)
        label = ", ".join(f"{k.split('.')[-1]}={v}" for k, v in combo)
        all_sets = tuple(sets) + tuple(combo) + (("scene.name", shot_name),)
        error = None
        try:
            load_scene(scene, list(all_sets))
        except FraytoolError as exc:
            error = str(exc)
        shots.append(Shot(name=shot_name, scene=scene, sets=all_sets, render=render,
                          group=base if wedges else "", label=label, error=error))
    return shots


def _render_options(table: dict, where: str, base: RenderOptions) -> RenderOptions:
    if not isinstance(table, dict):
        raise InputError(f"{where}: must be a table")
    unknown = set(table) - _RENDER_KEYS
    if unknown:
        raise InputError(f"{where}: unknown key {sorted(unknown)[0]!r}; allowed keys: {', '.join(sorted(_RENDER_KEYS))}")
    from fraytool.render.motion_blur import parse_samples, parse_shutter
    from fraytool.render.options import check_samples, check_supersample, checked_key, parse_resolution

    def integer(key: str, value):
        if value is not None and (isinstance(value, bool) or not isinstance(value, int)):
            raise InputError(f"{where} {key} = {value!r}: a whole number")
        return value

    codec = table.get("codec", base.codec)
    if codec not in ("h264", "prores", None):
        raise InputError(f'{where} codec = {codec!r}: "h264" or "prores"')
    res = table.get("resolution", base.resolution)
    if res is not None:  # the ranges are `fraytool render`'s own (fraytool.render.options), checked by its checks
        if not (isinstance(res, (list, tuple)) and len(res) == 2 and all(isinstance(v, int) and not isinstance(v, bool)
                                                                          for v in res)):
            raise InputError(f"{where} resolution = {res!r}: an array of 2 whole numbers [width, height]")
        res = checked_key(where, "resolution", lambda r: parse_resolution(f"{r[0]}x{r[1]}", need_even=codec != "prores",
                                                                          no_mp4_hint=False), list(res))
    samples = table.get("samples", base.samples)
    samples = checked_key(where, "samples", check_samples, integer("samples", samples))
    wire = table.get("wireframe", base.wireframe)
    if wire not in ("off", "only", "beside", None):
        raise InputError(f'{where} wireframe = {wire!r}: one of "off", "only", "beside"')
    frames = table.get("frames", base.frames)
    if frames is not None and not isinstance(frames, str):
        raise InputError(f'{where} frames = {frames!r}: a string "START:END[:STEP]"')
    flags = {}
    for key in ("alpha", "exr", "fit"):
        value = table.get(key, getattr(base, key))
        if value is not None and not isinstance(value, bool):
            raise InputError(f"{where} {key} = {value!r}: true or false")
        flags[key] = value
    depth = table.get("depth", base.depth)
    if depth is not None and (isinstance(depth, bool) or depth not in (8, 16)):
        raise InputError(f"{where} depth = {depth!r}: 8 or 16 (bits per PNG channel)")
    blur = table.get("motion_blur", base.motion_blur)
    if blur is not None:
        if isinstance(blur, bool) or not isinstance(blur, (int, float)):
            raise InputError(f"{where} motion_blur = {blur!r}: a number")
        blur = checked_key(where, "motion_blur", parse_shutter, blur)
    blur_samples = table.get("motion_samples", base.motion_samples)
    if blur_samples is not None:
        blur_samples = checked_key(where, "motion_samples", parse_samples, integer("motion_samples", blur_samples))
    supersample = table.get("supersample", base.supersample)
    if supersample is not None:
        supersample = checked_key(where, "supersample", check_supersample, integer("supersample", supersample))
    return check_render_options(RenderOptions(res, samples, wire, frames, flags["alpha"], depth, flags["exr"],
                                              codec, flags["fit"], blur, blur_samples, supersample), where)


def check_render_options(opts: RenderOptions, where: str, flags: bool = False) -> RenderOptions:
    """Options that contradict each other are bad input: ProRes in a batch is encoded from the PNG
    sequence, so its PNGs are 16-bit (``depth = 8`` would make a 10-bit ProRes of 8-bit pixels).
    `flags`: name them as command-line flags."""
    if opts.codec == "prores" and opts.depth == 8:
        what = "--codec prores with --depth 8" if flags else 'codec = "prores" with depth = 8'
        fix = "leave --depth out or give 16" if flags else "leave depth out or set 16"
        raise InputError(f"{where}: {what}: a batch encodes the ProRes .mov from the PNG sequence, which is then "
                         f"16-bit RGBA; {fix}")
    return opts


def load_job(path: Path, sets: Sequence[tuple[str, Any]] = (), wedges: Sequence[tuple[str, list[Any]]] = (),
             render: RenderOptions = RenderOptions(), chunk_frames: Optional[int] = None) -> Job:
    """A job file (TOML), with command-line --set, --wedge and render options applied to every shot."""
    path = Path(path)
    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise InputError(f"{path}: cannot read job file: {exc.strerror}") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError, RecursionError) as exc:
        raise InputError(f"{path}: not a valid TOML job file: {str(exc).splitlines()[0]}") from None
    unknown = set(doc) - {"job", "render", "shots"}
    if unknown:
        raise InputError(f"{path}: unknown table [{sorted(unknown)[0]}]; allowed: [job], [render], [[shots]]")
    head = doc.get("job", {})
    if not isinstance(head, dict):
        raise InputError(f"{path}: [job] must be a table with the keys {', '.join(sorted(_JOB_KEYS))}")
    if set(head) - _JOB_KEYS:
        raise InputError(f"{path}: [job] {sorted(set(head) - _JOB_KEYS)[0]}: unknown key; allowed keys: "
                         f"{', '.join(sorted(_JOB_KEYS))}")
    name = head.get("name", path.stem)
    check_job_name(name, f"{path}: [job] name")
    chunk = chunk_frames or head.get("chunk_frames", DEFAULT_CHUNK_FRAMES)
    if not isinstance(chunk, int) or not 1 <= chunk <= 100000:
        raise InputError(f"{path}: [job] chunk_frames = {chunk!r}: an integer from 1 to 100000")
    defaults = _render_options(doc.get("render", {}), f"{path}: [render]", RenderOptions())
    defaults = _merge(defaults, render)
    shots_raw = doc.get("shots", [])
    if not isinstance(shots_raw, list) or not shots_raw or not all(isinstance(s, dict) for s in shots_raw):
        raise InputError(f"{path}: needs at least one [[shots]] table with a scene")
    job = Job(name=name, chunk_frames=chunk)
    for i, raw in enumerate(shots_raw):
        where = f"{path}: [shots.{i}]"
        unknown = sorted(set(raw) - _SHOT_KEYS)
        if unknown:
            raise InputError(f"{where}: unknown key {unknown[0]!r}; allowed keys: {', '.join(sorted(_SHOT_KEYS))} "
                             "(render options go in render = {{ ... }})")
        if not isinstance(raw.get("scene"), str):
            raise InputError(f"{where}: needs scene = \"...\" (a scene file or a shipped scene name)")
        scene = raw["scene"]
        if not Path(scene).is_absolute() and (path.parent / scene).exists():
            scene = str(path.parent / scene)
        shot_sets = list(_table_items(raw.get("set", {}), f"{where} set")) + list(sets)
        shot_wedges = [(k, v) if isinstance(v, list) else parse_wedge(f"{k}={v}", f"{where} wedge")
                       for k, v in _table_items(raw.get("wedge", {}), f"{where} wedge")]
        shot_wedges += list(wedges)
        opts = _render_options(raw.get("render", {}), f"{where} render", defaults)
        if raw.get("name") is not None:
            check_job_name(raw["name"], f"{where} name")
        job.shots += expand(scene, shot_sets, shot_wedges, _merge(opts, render), raw.get("name"))
    return job


def _table_items(table: Any, where: str) -> list[tuple[str, Any]]:
    if not isinstance(table, dict):
        raise InputError(f"{where}: must be an inline table of \"dotted.key\" = value")
    return list(_flatten(table))


def _flatten(table: dict, prefix: str = ""):
    for k, v in table.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict):
            yield from _flatten(v, key + ".")
        else:
            yield key, v


def _merge(base: RenderOptions, cli: RenderOptions) -> RenderOptions:
    """Command-line render options win over the job file's."""
    def pick(key):
        value = getattr(cli, key)
        return value if value is not None else getattr(base, key)

    return check_render_options(
        RenderOptions(cli.resolution or base.resolution, pick("samples"), pick("wireframe"), cli.frames or base.frames,
                      pick("alpha"), pick("depth"), pick("exr"), pick("codec"), pick("fit"),
                      pick("motion_blur"), pick("motion_samples"), pick("supersample")),
        "render options (job file and command line)")


def check_job_name(name: Any, where: str) -> None:
    """A job's name is a folder name, never a path (the rules of [scene] name)."""
    from fraytool.scene.rules import scene_name_problems

    if not isinstance(name, str) or scene_name_problems(name, from_file_name=False):
        raise InputError(f"{where} = {str(name)[:120]!r}: letters, digits, '-', '_', '.' (not leading), at most 100 "
                         "characters; a name, never a path")


def unique_names(shots: list[Shot]) -> None:
    seen: dict[str, int] = {}
    for s in shots:
        seen[s.name] = seen.get(s.name, 0) + 1
    dup = [n for n, c in seen.items() if c > 1]
    if dup:
        raise InputError(f"two shots are named {dup[0]!r}: give them a name (job file: name = ...) or other values")
