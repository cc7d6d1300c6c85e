"""Read a TOML scene file into a validated SceneSpec.

Every problem (unknown key, wrong type, value out of range, inconsistent combination) becomes one
line "FILE: [table] key = value: what is allowed" in a SceneError, which the CLI prints and turns
into exit code 2. All problems in a file are reported at once.
"""
from __future__ import annotations

import difflib

import hashlib
import json
import re
import tomllib
from dataclasses import asdict, replace
from pathlib import Path
from typing import Any, Optional, Sequence

from fraytool.errors import SceneError
from fraytool.scene import panel_shape, rules, schema
from fraytool.scene.keys import REQUIRED, Key, show
from fraytool.scene.overrides import apply_overrides, describe
from fraytool.scene.spec import (
    AttachmentSpec,
    CutSpec,
    BodySpec,
    CameraSpec,
    CheckSpec,
    ClothSpec,
    GoldenSpec,
    OutputSpec,
    RenderSpec,
    SceneInfo,
    SceneSpec,
    SelfCollisionSpec,
    SpringSpec,
    StrainSpec,
    MultiresSpec,
    TearingSpec,
    SeamSpec,
    TimeSpec,
    WeakLineSpec,
)


class _Problems:
    """Collects error lines for one file."""

    def __init__(self, source: str):
        self.source = source
        self.lines: list[str] = []
        self.several_panels = False
        """[[cloth]] written more than once: the first panel's tables are named [cloth.0], [cloth.0.springs],
        ..., as the others are [cloth.1], ... (and as --set names them), not [cloth], which reads as any."""

    def add(self, where: str, key: str | None, value: Any, allowed: str, show_chars: Optional[int] = None) -> None:
        """One problem line; `show_chars` echoes the value at most that long (default: as long as it
        fits, see MESSAGE_CHARS)."""
        parts = where.split(".")
        if self.several_panels and parts[0] == "cloth" and (len(parts) == 1 or not parts[1].isdigit()):
            where = ".".join(["cloth", "0", *parts[1:]])
        if show_chars is not None:
            self.lines.append(f"{self.source}: [{where}] {key} = {show(value, show_chars)}: {allowed}")
            return
        if key is None:
            self.lines.append(f"{self.source}: [{where}]: {allowed}")
            return
        line = f"{self.source}: [{where}] {key} = {show(value)}: {allowed}"
        if len(line) > MESSAGE_CHARS and len(show(value)) > SHORT_SHOW_CHARS + 8:
            line = f"{self.source}: [{where}] {key} = {show(value, SHORT_SHOW_CHARS)}: {allowed}"  # a long value
        self.lines.append(line)

    def extend(self, where: str, problems: list[rules.Problem]) -> None:
        for key, value, allowed in problems:
            self.add(where, key, value, allowed)


UNKNOWN_SHOW_CHARS = 12
"""An unknown key's value matters least: echoed at most this long."""
MESSAGE_CHARS = 180
"""A problem line longer than this (with "fraytool: error: " in front) echoes a long value (cut at
keys.SHOW_MAX_CHARS = 80 characters otherwise) at SHORT_SHOW_CHARS, so that the explanation fits."""
SHORT_SHOW_CHARS = 24


def allowed_keys(name: str, keys, tables=()) -> str:
    """What an unknown key's message says of the allowed ones: all of a short table (at most 6), else the
    closest one, a key's or a sub-table's (`tables`), if one is close (a misspelling: difflib's ratio at
    least 0.6), and where they are all listed (a message line stays under 200 characters)."""
    names = sorted(keys)
    if len(names) <= 6:
        return "allowed keys: " + ", ".join(names)
    close = difflib.get_close_matches(str(name), names + sorted(tables), n=1, cutoff=0.6)
    if not close:
        return "the keys of this table: docs/scene-format.md"
    return f"did you mean {close[0]}? (docs/scene-format.md)"


def _read_table(doc: dict, where: str, keys: dict[str, Key], problems: _Problems) -> dict[str, Any]:
    """Validate one table against its schema; returns key -> converted value (defaults filled)."""
    out: dict[str, Any] = {}
    for name, value in doc.items():
        if name not in keys:
            base = re.sub(r"^cloth\.\d+$", "cloth", where)  # panel k of [[cloth]] has [cloth]'s sub-tables
            if isinstance(value, dict) and f"{base}.{name}" in schema.TOP:
                continue  # a sub-table, read on its own
            tables = sorted(t.split(".")[-1] for t in schema.TOP if t.startswith(base + ".") and
                            t.count(".") == base.count(".") + 1)
            parts = [allowed_keys(name, keys, tables if isinstance(value, dict) else ())]
            if tables:  # a table given where a key goes: the sub-tables first
                sub = "sub-tables: " + ", ".join(tables)
                parts = [sub] + parts if isinstance(value, dict) else parts + [sub]
            problems.add(where, name, value, "unknown key; " + "; ".join(parts), UNKNOWN_SHOW_CHARS)
            continue
        key = keys[name]
        ok, converted = key.convert(value)
        if not ok:
            problems.add(where, name, value, key.explain())
            continue
        out[name] = converted
    for name, key in keys.items():
        if name not in out:
            if key.default is REQUIRED:
                if name not in doc:
                    problems.add(where, None, None, f"missing required key `{name}`: {key.explain()}")
            else:
                out[name] = key.default
    return out


MAX_SCENE_BYTES = 16 * 2**20
"""Largest scene file (16 MiB): far above any real scene, far below what the TOML parser chokes on."""
MAX_KEY_DEPTH = 16
"""Most parts of a dotted key or table header (a scene uses at most 3)."""
_KEY_PART = re.compile(r'^\s*\[{0,2}\s*([A-Za-z0-9_\-."' + "'" + r' ]+?)\s*(?:\]{1,2}\s*$|=)')


def text_problem(text: str) -> Optional[str]:
    """Why scene text is refused before parsing (too large, keys nested too deeply), or None. The
    TOML parser's memory grows with the depth of a dotted key much faster than the file."""
    if len(text) > MAX_SCENE_BYTES:
        return f"{len(text)} characters: larger than any scene ({MAX_SCENE_BYTES} at most)"
    for number, line in enumerate(text.splitlines(), 1):
        m = _KEY_PART.match(line)
        if m and m.group(1).count(".") >= MAX_KEY_DEPTH:
            return (f"line {number}: a key or table nested {m.group(1).count('.') + 1} levels deep; "
                    f"a scene nests at most 3 (at most {MAX_KEY_DEPTH} accepted)")
    return None


def parse_scene(text: str, source: str = "<string>", overrides: Sequence[tuple[str, Any]] = (),
                source_file: str = "") -> SceneSpec:
    """Parse and validate scene TOML text, with `overrides` ((dotted key, value), as from --set,
    fraytool.scene.overrides) applied first; raises SceneError listing every problem."""
    too_big = text_problem(text)
    if too_big:
        raise SceneError([f"{source}: {too_big}"])
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SceneError([f"{source}: not valid TOML: {exc}"]) from None
    except ValueError as exc:  # e.g. an integer literal longer than Python converts (4300 digits)
        raise SceneError([f"{source}: not valid TOML: {str(exc).splitlines()[0][:200]}"]) from None
    except RecursionError:
        raise SceneError([f"{source}: not a scene: arrays or tables nested too deeply for the TOML "
                          "parser (a scene nests at most 3 levels)"]) from None
    stem = Path(source).stem  # the default scene name
    scene_file = source_file or ("" if source.startswith("<") else source)  # (before the overrides' note)
    if overrides:
        apply_overrides(doc, overrides)
        source += describe(overrides)
    problems = _Problems(source)
    more_panels: list = []
    if isinstance(doc.get("cloth"), list) and doc["cloth"] and all(isinstance(v, dict) for v in doc["cloth"]):
        doc["cloth"], more_panels = doc["cloth"][0], doc["cloth"][1:]  # [[cloth]]: several panels
        problems.several_panels = bool(more_panels)

    for name, value in doc.items():
        if name not in schema.TOP:
            problems.add(name, None, None, "unknown table; allowed tables: "
                         + ", ".join(sorted(k for k in schema.TOP if "." not in k)))
        elif name in schema.ARRAY_TABLES:
            if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
                problems.add(name, None, None, f"must be an array of tables, written [[{name}]]")
        elif not isinstance(value, dict):
            problems.add(name, None, None, f"must be a table, written [{name}]")
    for name in schema.REQUIRED_TABLES:
        node: Any = doc
        for part in name.split("."):
            node = node.get(part) if isinstance(node, dict) else None
        if not isinstance(node, dict):
            problems.add(name, None, None, "missing required table")
    if problems.lines:
        raise SceneError(problems.lines)

    def table(path: str) -> dict:
        node: Any = doc
        for part in path.split("."):
            node = node.get(part, {}) if isinstance(node, dict) else {}
        if not isinstance(node, dict):
            problems.add(path, None, None, f"must be a table, written [{path}]")
            return {}
        return node

    values = {path: _read_table(table(path), path, keys, problems)
              for path, keys in schema.TOP.items() if path not in schema.ARRAY_TABLES}
    bodies_raw = [(_read_table(b, f"bodies.{i}", schema.TOP["bodies"], problems), i)
                  for i, b in enumerate(doc.get("bodies", []))]
    att_raw = [(_read_table(a, f"attachments.{i}", schema.TOP["attachments"], problems), i)
               for i, a in enumerate(doc.get("attachments", []))]
    cut_raw = [(_read_table(c, f"cuts.{i}", schema.TOP["cuts"], problems), i)
               for i, c in enumerate(doc.get("cuts", []))]
    weak_raw = [(_read_table(w, f"weak_lines.{i}", schema.TOP["weak_lines"], problems), i)
                for i, w in enumerate(doc.get("weak_lines", []))]
    seam_raw = [(_read_table(w, f"seams.{i}", schema.TOP["seams"], problems), i)
                for i, w in enumerate(doc.get("seams", []))]
    panels_raw = []
    for k, panel in enumerate(more_panels, 1):
        raw = {"cloth": _read_table(panel, f"cloth.{k}", schema.TOP["cloth"], problems)}
        for sub in ("springs", "strain", "tearing", "multires"):
            node = panel.get(sub)
            raw[f"cloth.{sub}"] = (_read_table(node, f"cloth.{k}.{sub}", schema.TOP[f"cloth.{sub}"], problems)
                                   if isinstance(node, dict) else None)
        panels_raw.append(raw)
    if problems.lines:
        raise SceneError(problems.lines)

    spec = _assemble(values, bodies_raw, att_raw, cut_raw, source, problems, stem, scene_file, weak_raw,
                     panels_raw, seam_raw)
    if problems.lines:
        raise SceneError(problems.lines)
    return spec


def _panel(where: str, c: dict, springs: dict, strain: StrainSpec, tear: TearingSpec, multires: MultiresSpec,
           problems: _Problems, scene_file: str) -> tuple[ClothSpec, Optional[tuple[int, int]]]:
    """One [cloth] panel from its checked keys, with its shape's and tear map's problems; and its grid size
    (warp_yarns, weft_yarns), None if its shape has problems."""
    table, weave_problems = rules.weave_table(c["weave"], c["twill"], c["satin_shafts"], c["table"])
    problems.extend(where, weave_problems)
    cloth = ClothSpec(**{k: v for k, v in c.items() if k != "table"}, weave_table=table,
                      springs=SpringSpec(**springs), strain=strain, tearing=tear, multires=multires)
    shape_rules = rules.cloth_shape_problems(cloth.warp_yarns, cloth.weft_yarns, cloth.outline_m, cloth.mask,
                                             cloth.mask_size_m, cloth.grain_deg)
    problems.extend(where, shape_rules)
    problems.extend(where, rules.wrap_problems(cloth.spacing_m, cloth.wrap_radius_m))
    if not shape_rules:
        problems.extend(where, panel_shape.shape_problems(cloth, scene_file))
    grid = panel_shape.grid_size(cloth, scene_file) if not shape_rules else None
    problems.extend(where, rules.tear_map_problems(cloth.tear_map, cloth.tear_map_strain))
    if cloth.tear_map and grid is not None and not rules.tear_map_problems(cloth.tear_map, cloth.tear_map_strain):
        problems.extend(where, panel_shape.tear_map_problems(cloth, scene_file))
    return cloth, grid


def seam_problems(seam: SeamSpec, a: ClothSpec, b: ClothSpec, scene_file: str = "") -> list[rules.Problem]:
    """[[seams]]: segments that exist on their panels' outlines, of about the same length (within 25 %)."""
    from fraytool.scene.panel_shape import PanelShapeError, panel_shape as shape_of

    out: list[rules.Problem] = []
    lengths = []
    for side, panel, k in (("a", a, seam.segment_a), ("b", b, seam.segment_b)):
        try:
            outline = shape_of(panel, scene_file).outline_uv_m
        except PanelShapeError:
            return []  # the panel's own problem is reported
        if k >= len(outline):
            out.append((f"segment_{side}", k, f"panel {panel.name!r} has segments 0 to {len(outline) - 1} "
                                              "(segment k runs from outline point k to k + 1)"))
            continue
        lengths.append(float(((outline[(k + 1) % len(outline)] - outline[k]) ** 2).sum() ** 0.5))
    if len(lengths) == 2 and max(lengths) > 1.25 * min(lengths):
        out.append(("segment_b", seam.segment_b, f"is {lengths[1]:.4g} m long and segment_a {lengths[0]:.4g} m: "
                                                 "a seam joins edges within 25 % of each other's length"))
    if lengths and seam.stitch_spacing_m > lengths[0]:
        out.append(("stitch_spacing_m", seam.stitch_spacing_m, f"must be at most segment_a's length "
                                                               f"{lengths[0]:.4g} m (one stitch at least)"))
    if (seam.panel_a, seam.segment_a) == (seam.panel_b, seam.segment_b):
        out.append(("segment_b", seam.segment_b, "sews a segment to itself: give two different edges"))
    return out


def _assemble(values: dict, bodies_raw: list, att_raw: list, cut_raw: list, source: str,
              problems: _Problems, stem: str, scene_file: str = "", weak_raw: Sequence = (),
              panels_raw: Sequence = (), seam_raw: Sequence = ()) -> SceneSpec:
    """Build the SceneSpec from checked tables, applying the rules that tie keys together."""
    s, t, c = values["scene"], values["time"], values["cloth"]
    name = s["name"] or stem
    problems.extend("scene", rules.scene_name_problems(name, from_file_name=not s["name"]))
    tear = TearingSpec(**values["cloth.tearing"])
    problems.extend("cloth.tearing", rules.tearing_problems(tear))
    strain = StrainSpec(**values["cloth.strain"])
    problems.extend("cloth.strain", rules.strain_problems(strain))
    multires = MultiresSpec(**values["cloth.multires"])
    problems.extend("cloth.multires", rules.multires_problems(multires))
    cloth, first_grid = _panel("cloth", c, values["cloth.springs"], strain, tear, multires, problems, scene_file)
    problems.extend("cloth", rules.cloth_problems(cloth.spacing_m, cloth.thickness_m))
    panels, grids = [], {(cloth.name or "cloth"): first_grid}
    for k, raw in enumerate(panels_raw, 1):
        where = f"cloth.{k}"
        shared = {"strain": (raw["cloth.strain"], strain, StrainSpec), "tearing": (raw["cloth.tearing"], tear, TearingSpec),
                  "multires": (raw["cloth.multires"], multires, MultiresSpec)}
        own = {}
        for sub, (given, first, kind) in shared.items():
            own[sub] = first if given is None else kind(**given)
            if own[sub] != first:
                problems.add(f"{where}.{sub}", None, None, f"every panel shares the first panel's [cloth.{sub}] "
                                                            "(one solver): leave it out or make it the same")
        if raw["cloth.springs"] is None:
            problems.add(f"{where}.springs", None, None, "missing required table")
            continue
        panel, grid = _panel(where, raw["cloth"], raw["cloth.springs"], strain, tear, multires, problems, scene_file)
        panel = replace(panel, name=panel.name or f"cloth{k}")
        for key in ("spacing_m", "thickness_m"):
            if getattr(panel, key) != getattr(cloth, key):
                problems.add(where, key, getattr(panel, key), f"every panel shares the first panel's {key} = "
                                                             f"{getattr(cloth, key):g} (one yarn model)")
        if panel.springs.damping != cloth.springs.damping:
            problems.add(f"{where}.springs", "damping", panel.springs.damping,
                         f"every panel shares the first panel's damping = {cloth.springs.damping:g}")
        if panel.name in grids:
            problems.add(where, "name", panel.name, "must be unique among the [[cloth]] panels")
        grids[panel.name] = grid
        panels.append(panel)
    cloth = replace(cloth, name=cloth.name or "cloth")
    if multires.factor > 1:
        for where, panel in [("cloth", cloth)] + [(f"cloth.{k}", p) for k, p in enumerate(panels, 1)]:
            for key in ("drag_normal", "drag_tangential"):
                if getattr(panel, key):
                    problems.add(where, key, getattr(panel, key), "air drag acts at yarn resolution: leave it out "
                                 "or set [cloth.multires] factor = 1 (docs/wind.md)")

    def panel_grid(where: str, panel_name: str, key: str = "panel") -> tuple[int, int]:
        """(warp_yarns, weft_yarns) of the panel a table names in `key` ("": the first)."""
        if panel_name and panel_name not in grids:
            problems.add(where, key, panel_name, "must name one of the [[cloth]] panels: " + ", ".join(grids))
        grid = grids.get(panel_name or cloth.name) or first_grid
        return grid or (2, 2)

    bodies = []
    names: set[str] = set()
    for b, i in bodies_raw:
        body = BodySpec(**b)
        problems.extend(f"bodies.{i}", rules.body_name_problems(body.name, names) + rules.body_problems(body))
        if body.shape == "mesh" and body.file:
            from fraytool.scene.mesh_files import file_problems

            problems.extend(f"bodies.{i}", file_problems(body.file, body.prim, scene_file))
        names.add(body.name)
        bodies.append(body)

    attachments = []
    for a, i in att_raw:
        att = AttachmentSpec(**a)
        problems.extend(f"attachments.{i}", rules.attachment_problems(att, names, *panel_grid(f"attachments.{i}", att.panel)))
        attachments.append(att)

    cuts = []
    for c_raw, i in cut_raw:
        cut = CutSpec(**c_raw)
        problems.extend(f"cuts.{i}", rules.cut_problems(cut, *panel_grid(f"cuts.{i}", cut.panel)))
        cuts.append(cut)

    if any(c.path_m for c in cuts) and not tear.enabled:
        problems.add("cuts", None, None, "scissors (path_m) cut in the tearing stage: set [cloth.tearing] "
                                         "enabled = true")
    weak_lines = []
    for w_raw, i in weak_raw:
        w = WeakLineSpec(**w_raw)
        panel_grid(f"weak_lines.{i}", w.panel)
        problems.extend(f"weak_lines.{i}", rules.weak_line_problems(w))
        weak_lines.append(w)
    all_panels = {p.name: p for p in [cloth] + panels}
    seams = []
    for s_raw, i in seam_raw:
        seam = SeamSpec(**s_raw)
        for side in ("a", "b"):
            panel_grid(f"seams.{i}", getattr(seam, f"panel_{side}"), f"panel_{side}")
        if seam.panel_a in all_panels and seam.panel_b in all_panels and not problems.lines:
            problems.extend(f"seams.{i}", seam_problems(seam, all_panels[seam.panel_a], all_panels[seam.panel_b],
                                                        scene_file))
        if all(isinstance(t.get(k), (int, float)) for k in ("frames", "steps_per_frame", "step_s")):
            shot_s = t["frames"] * t["steps_per_frame"] * t["step_s"]
            if seam.sew_s > shot_s:
                problems.extend(f"seams.{i}", [("sew_s", seam.sew_s, f"must end within the shot ({t['frames']} "
                                                f"frames of {t['steps_per_frame']} steps of {t['step_s']:g} s = "
                                                f"{shot_s:.4g} s)")])
        seams.append(seam)

    render, camera = RenderSpec(**values["render"]), CameraSpec(**values["camera"])
    problems.extend("render", rules.render_problems(render))
    problems.extend("camera", rules.camera_problems(camera))
    problems.extend("checks", rules.checks_problems(values["checks"]["frames"], t["frames"]))

    return SceneSpec(
        source=source,
        source_file=scene_file,
        scene=SceneInfo(name=name, description=s["description"], seed=s["seed"]),
        time=TimeSpec(**t),
        cloth=cloth,
        gravity_m_s2=values["world"]["gravity_m_s2"],
        **{k: values["world"][k] for k in _WORLD_KEYS if k != "gravity_m_s2"},
        bodies=tuple(bodies),
        attachments=tuple(attachments),
        cuts=tuple(cuts),
        weak_lines=tuple(weak_lines),
        panels=tuple(panels),
        seams=tuple(seams),
        self_collision=SelfCollisionSpec(**values["self_collision"]),
        camera=camera,
        render=render,
        output=OutputSpec(**values["output"]),
        checks=CheckSpec(**values["checks"]),
        golden=GoldenSpec(**values["golden"]),
    )


def load_scene(path: str | Path, overrides: Sequence[tuple[str, Any]] = ()) -> SceneSpec:
    """Load a scene file. A bare name or a scenes/... path not found on disk is looked up among the
    scenes shipped with fraytool. Raises SceneError (exit 2) for a missing or invalid file."""
    from fraytool.resources import find_scene

    p = find_scene(path)
    try:
        text = p.read_text(encoding="utf-8")
    except OSError as exc:
        raise SceneError([f"{path}: cannot read scene file: {exc.strerror}"]) from None
    except UnicodeDecodeError as exc:
        line = p.read_bytes()[: exc.start].count(b"\n") + 1
        raise SceneError([f"{path}: not UTF-8 text (byte 0x{exc.object[exc.start]:02x} at line {line}); "
                          "TOML scene files are UTF-8"]) from None
    return parse_scene(text, str(path), overrides, source_file=str(p))


SIM_REVISION = 2
"""Raised when a change of the solver changes the frames a scene gives; part of scene_hash, so frames
simulated by an older solver are neither resumed nor reused but simulated again. 2: rigid contact
before the strain limit in scenes that tear (docs/tearing.md). (1, implicit: everything before.)"""


MESH_REVISION = 2
"""Part of scene_hash for scenes with a mesh body: raised when mesh contact changes their frames. 2: the
friction's limit is the push over all passes (a mass's second pass no longer drops it)."""


def scene_hash(spec: SceneSpec) -> str:
    """Stable digest of everything that affects the simulation (not camera/render/output), and of the
    solver revision (SIM_REVISION): the keys of simulation_keys."""
    d = _simulation_dict(spec)
    if "panels" in d:
        d["panels"] = [[p.name for p in spec.all_panels], d["panels"]]  # seams and attachments name them
    d["sim_revision"] = SIM_REVISION
    if any(b.shape == "mesh" for b in spec.bodies):
        d["mesh_revision"] = MESH_REVISION
    blob = json.dumps(d, sort_keys=True, default=list).encode()
    return hashlib.sha256(blob).hexdigest()[:16]


def simulation_keys(spec: SceneSpec) -> dict:
    """The scene keys the frames depend on, flattened to `table.key` (`bodies.0.radius_m`) -> value as JSON
    reads it back (a file key: the digest of its bytes): what scene_hash digests, so that a run can say which
    key made it simulate again (fraytool.scene.key_changes)."""
    flat: dict = {}

    def walk(prefix: str, value) -> None:
        if isinstance(value, dict):
            for k, v in value.items():
                walk(f"{prefix}.{k}" if prefix else str(k), v)
        elif isinstance(value, (list, tuple)) and value and all(isinstance(v, dict) for v in value):
            for i, v in enumerate(value):
                walk(f"{prefix}.{i}", v)
        else:
            flat[prefix] = value

    walk("", json.loads(json.dumps(_simulation_dict(spec), default=list)))
    return {_toml_key(k, bool(spec.panels)): v for k, v in flat.items()}


def _toml_key(key: str, several_panels: bool) -> str:
    """A SceneSpec path as the scene file writes it: gravity is [world]'s; with several [[cloth]] panels the
    first is cloth.0 and SceneSpec.panels[k] is cloth.(k + 1)."""
    head, _, rest = key.partition(".")
    if head in _WORLD_KEYS:
        return "world." + key
    if head == "cloth" and several_panels:
        return "cloth.0." + rest
    if head == "panels":
        index, _, rest = rest.partition(".")
        return f"cloth.{int(index) + 1}" + (f".{rest}" if rest else "")
    return key


def _simulation_dict(spec: SceneSpec) -> dict:
    """The scene as a dict of what affects the simulation, keys at their defaults left out where a digest
    predates them (scene_hash)."""
    d = asdict(spec)
    for k in ("source", "source_file", "camera", "render", "output", "checks", "golden"):
        d.pop(k)
    d["scene"].pop("description")
    if not d["cuts"]:
        d.pop("cuts")  # scenes without cuts keep the digest they had before cuts existed
    for raw in d.get("cuts", []):
        if not raw["path_m"]:  # snips keep the digest they had before scissors existed
            for k in ("path_m", "start_s", "end_s"):
                raw.pop(k)
    for raw, panel in zip([d["cloth"]] + list(d["panels"]), spec.all_panels):
        for k in ("name", "warp_color", "weft_color"):  # names and colours change no frame
            raw.pop(k)
        for k, default in _PANEL_KEY_DEFAULTS.items():  # cloths without them keep the digest they had before
            if raw[k] == default:
                raw.pop(k)
        if raw.get("plane") == "yz":  # the weft now runs along y, as documented (it ran along z): new frames
            raw["plane"] = "yz:weft-y"
        for k in ("mask", "tear_map"):
            if raw.get(k):
                raw[k] = _file_digest(panel_shape.resolve(getattr(panel, k), spec.source_file))
    for table in ("panels", "seams", "weak_lines"):
        if not getattr(spec, table):
            d.pop(table)
    for table in ("attachments", "cuts", "weak_lines"):
        for raw in d.get(table, []):
            if raw["panel"] == "":  # on the first panel, as before panels had names
                raw.pop("panel")
    for k, default in _WORLD_KEY_DEFAULTS.items():  # scenes without a pre-roll or air keep the digest they had
        if d[k] == default:
            d.pop(k)
    d["time"].pop("frames")  # frame k does not depend on how many follow it
    d["time"].pop("fps")
    d["time"].pop("stability")
    for body, raw in zip(spec.bodies, d["bodies"]):
        for k, default in _BODY_KEY_DEFAULTS.items():  # bodies that do not turn keep the digest they had before
            if raw[k] == default:
                raw.pop(k)
        if body.shape != "mesh":  # bodies of other kinds keep the digest they had before meshes existed
            for k in ("file", "prim", "scale", "frame_time_s", "sequence_start_s"):
                raw.pop(k, None)  # (sequence_start_s at its default is gone already)
        else:
            raw["file"] = _mesh_digest(body.file, spec.source_file)  # the mesh, not where it lies
    return d


def key_changes(before: dict, after: dict, limit: int = 8) -> list[str]:
    """The keys of two simulation_keys records that differ, one line each as a scene file writes them:
    `world.gravity_m_s2: [0.0, -9.81, 0.0] -> [0.0, -8.5, 0.0]` (a file key: `its contents changed`); at
    most `limit` lines, then how many more."""
    from fraytool.scene.keys import show

    def shown(v) -> str:
        return "(unset)" if v is _UNSET else show(v, 60)

    lines = []
    for key in sorted(set(before) | set(after)):
        was, now = before.get(key, _UNSET), after.get(key, _UNSET)
        if was == now:
            continue
        if _is_digest(was) and _is_digest(now):
            lines.append(f"{key}: its file's contents changed")
        else:
            lines.append(f"{key}: {shown(was)} -> {shown(now)}")
    if len(lines) > limit:
        lines = lines[:limit] + [f"and {len(lines) - limit} more keys"]
    return lines


_UNSET = object()


def _is_digest(value) -> bool:
    return isinstance(value, str) and len(value) == 64 and all(c in "0123456789abcdef" for c in value)


_PANEL_KEY_DEFAULTS = {k: schema.TOP["cloth"][k].default for k in
                       ("outline_m", "mask", "mask_size_m", "grain_deg", "edge", "tear_map", "tear_map_strain",
                        "rotation_deg", "wrap_radius_m", "drag_normal", "drag_tangential")}
"""[cloth] keys of shaped panels, left out of the digest at their defaults."""
_WORLD_KEYS = tuple(schema.TOP["world"])
"""The [world] table's keys (SceneSpec's own)."""
_WORLD_KEY_DEFAULTS = {k: schema.TOP["world"][k].default for k in _WORLD_KEYS if k != "gravity_m_s2"}
"""[world] keys added after gravity, left out of the digest at their defaults."""
_BODY_KEY_DEFAULTS = {k: schema.TOP["bodies"][k].default for k in
                      ("path_rotation_deg", "path_quaternion", "interpolation", "sequence_start_s")}
"""[[bodies]] keys of turning and smooth paths, left out of the digest at their defaults."""


def _file_digest(path: Path) -> str:
    try:
        return hashlib.sha256(path.read_bytes()).hexdigest()
    except OSError:
        return str(path)  # not readable: loading the scene has said so


def _mesh_digest(file: str, scene_file: str) -> str:
    """Digest of a mesh body's files' bytes (a sequence: all of them, in order)."""
    from fraytool.scene.mesh_files import MeshFileError, is_sequence, resolve, sequence_files

    path = resolve(file, scene_file)
    h = hashlib.sha256()
    try:
        for f in (sequence_files(path) if is_sequence(path) else [path]):
            h.update(f.read_bytes())
    except (MeshFileError, OSError):
        return file  # not readable: loading the scene has said so
    return h.hexdigest()
