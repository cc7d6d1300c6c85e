"""Read a TOML scene file into a validated SceneSpec.

Every problem (unknown key, wrong type, value out of range, inconsistent combination) becomes one
line "FILE: [table] key = value: what is allowed" in a SceneError, which the CLI prints and turns
into exit code 2. All problems in a file are reported at once.
"""
from __future__ import annotations

import hashlib
import json
import math
import tomllib
from dataclasses import asdict
from pathlib import Path
from typing import Any

from fraytool.errors import SceneError
from fraytool.scene import schema, weave
from fraytool.scene.schema import REQUIRED, Key
from fraytool.scene.spec import (
    AttachmentSpec,
    BodySpec,
    CameraSpec,
    CheckSpec,
    ClothSpec,
    OutputSpec,
    RenderSpec,
    SceneInfo,
    SceneSpec,
    SelfCollisionSpec,
    SpringSpec,
    StrainSpec,
    TearingSpec,
    TimeSpec,
)


class _Problems:
    """Collects error lines for one file."""

    def __init__(self, source: str):
        self.source = source
        self.lines: list[str] = []

    def add(self, where: str, key: str | None, value: Any, allowed: str) -> None:
        if key is None:
            self.lines.append(f"{self.source}: [{where}]: {allowed}")
        else:
            self.lines.append(f"{self.source}: [{where}] {key} = {_show(value)}: {allowed}")


def _show(value: Any) -> str:
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, dict):
        return "{...}"
    return repr(value) if not isinstance(value, (list, tuple)) else json.dumps(value, default=str)


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _convert(key: Key, value: Any) -> tuple[bool, Any]:
    """Convert a TOML value to the key's Python type; (ok, converted)."""
    k = key.kind
    if k == "float":
        if not _is_number(value) or not key.in_range(float(value)):
            return False, None
        return True, float(value)
    if k == "int":
        if not isinstance(value, int) or isinstance(value, bool) or not key.in_range(value):
            return False, None
        return True, int(value)
    if k == "bool":
        return (True, value) if isinstance(value, bool) else (False, None)
    if k == "str":
        if not isinstance(value, str) or (key.choices and value not in key.choices):
            return False, None
        return True, value
    if k in ("vec3", "color"):
        if not isinstance(value, list) or len(value) != 3 or not all(_is_number(v) for v in value):
            return False, None
        out = tuple(float(v) for v in value)
        if not all(math.isfinite(v) for v in out):
            return False, None
        if k == "color" and not all(0.0 <= v <= 1.0 for v in out):
            return False, None
        return True, out
    if k == "int2":
        if not isinstance(value, list) or len(value) != 2:
            return False, None
        if not all(isinstance(v, int) and not isinstance(v, bool) for v in value):
            return False, None
        if not all(key.in_range(v) for v in value):
            return False, None
        return True, (int(value[0]), int(value[1]))
    if k == "path":
        if not isinstance(value, list):
            return False, None
        rows = []
        for row in value:
            if not isinstance(row, list) or len(row) != 4 or not all(_is_number(v) for v in row):
                return False, None
            rows.append(tuple(float(v) for v in row))
        times = [r[0] for r in rows]
        if any(b <= a for a, b in zip(times, times[1:])) or any(t < 0 for t in times):
            return False, None
        return True, tuple(rows)
    if k == "table2d":
        if not isinstance(value, list) or not value:
            return False, None
        width = None
        for row in value:
            if not isinstance(row, list) or not row or not all(v in (0, 1) and not isinstance(v, float) for v in row):
                return False, None
            width = len(row) if width is None else width
            if len(row) != width:
                return False, None
        return True, [[int(v) for v in row] for row in value]
    raise AssertionError(k)


def _read_table(doc: dict, where: str, keys: dict[str, Key], problems: _Problems) -> dict[str, Any]:
    """Validate one table against its schema; returns key -> converted value (defaults filled)."""
    out: dict[str, Any] = {}
    for name, value in doc.items():
        if name not in keys:
            if isinstance(value, dict) and f"{where}.{name}" in schema.TOP:
                continue  # a sub-table, read on its own
            problems.add(where, name, value, "unknown key; allowed keys: " + ", ".join(sorted(keys)))
            continue
        key = keys[name]
        ok, converted = _convert(key, value)
        if not ok:
            problems.add(where, name, value, key.allowed() + (f" ({key.doc})" if key.doc else ""))
            continue
        out[name] = converted
    for name, key in keys.items():
        if name not in out:
            if key.default is REQUIRED:
                if name not in doc:
                    problems.add(where, None, None, f"missing required key `{name}`: {key.allowed()}"
                                 + (f" ({key.doc})" if key.doc else ""))
            else:
                out[name] = key.default
    return out


def _weave_table(cloth: dict, problems: _Problems) -> tuple[tuple[bool, ...], ...]:
    kind = cloth.get("weave", "plain")
    try:
        if kind == "plain":
            return weave.plain()
        if kind == "twill":
            return weave.twill(cloth.get("twill", "2/1"))
        if kind == "satin":
            return weave.satin(cloth.get("satin_shafts", 5))
        if kind == "table":
            if cloth.get("table") is None:
                problems.add("cloth", "weave", kind, 'weave = "table" needs a `table` key: rows of 0/1')
                return weave.plain()
            return weave.from_rows(cloth["table"])
    except ValueError as exc:
        problems.add("cloth", "twill", cloth.get("twill"), str(exc))
    return weave.plain()


def parse_scene(text: str, source: str = "<string>") -> SceneSpec:
    """Parse and validate scene TOML text; raises SceneError listing every problem."""
    problems = _Problems(source)
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SceneError([f"{source}: not valid TOML: {exc}"]) from None

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
    bodies_raw = [(_read_table(b, f"bodies.{i}", schema.BODY, problems), i)
                  for i, b in enumerate(doc.get("bodies", []))]
    att_raw = [(_read_table(a, f"attachments.{i}", schema.ATTACHMENT, problems), i)
               for i, a in enumerate(doc.get("attachments", []))]
    if problems.lines:
        raise SceneError(problems.lines)

    spec = _assemble(values, bodies_raw, att_raw, source, problems)
    if problems.lines:
        raise SceneError(problems.lines)
    return spec


def _assemble(values: dict, bodies_raw: list, att_raw: list, source: str, problems: _Problems) -> SceneSpec:
    s, t, c = values["scene"], values["time"], values["cloth"]
    name = s["name"] or Path(source).stem
    tear = TearingSpec(**values["cloth.tearing"])
    if tear.enabled and tear.yarn_level and tear.transition_strain >= tear.break_strain:
        problems.add("cloth.tearing", "transition_strain", tear.transition_strain,
                     f"must be below break_strain = {tear.break_strain:g} (splitting comes before cutting)")
    cloth = ClothSpec(
        warp_yarns=c["warp_yarns"], weft_yarns=c["weft_yarns"], spacing_m=c["spacing_m"],
        thickness_m=c["thickness_m"], mass_per_crossing_kg=c["mass_per_crossing_kg"],
        origin_m=c["origin_m"], plane=c["plane"], weave=c["weave"],
        weave_table=_weave_table(c, problems), springs=SpringSpec(**values["cloth.springs"]),
        strain=StrainSpec(**values["cloth.strain"]), tearing=tear, twill=c["twill"],
        satin_shafts=c["satin_shafts"],
    )
    if cloth.thickness_m >= cloth.spacing_m:
        problems.add("cloth", "thickness_m", cloth.thickness_m,
                     f"must be below spacing_m = {cloth.spacing_m:g} (yarns would overlap)")

    bodies = []
    names: set[str] = set()
    for b, i in bodies_raw:
        where = f"bodies.{i}"
        if b["name"] in names:
            problems.add(where, "name", b["name"], "must be unique among [[bodies]]")
        names.add(b["name"])
        if b["shape"] == "sphere" and b["radius_m"] is None:
            problems.add(where, None, None, "a sphere needs `radius_m` (> 0)")
        if b["shape"] == "box":
            he = b["half_extents_m"]
            if he is None or min(he) <= 0:
                problems.add(where, "half_extents_m", he, "a box needs half_extents_m: 3 numbers > 0")
        if b["shape"] == "plane":
            if b["motion"] == "dynamic":
                problems.add(where, "motion", b["motion"], 'a plane is "static" or "kinematic"')
            if math.sqrt(sum(v * v for v in b["normal"])) < 1e-12:
                problems.add(where, "normal", list(b["normal"]), "must be a non-zero vector")
        if b["path"] and b["motion"] != "kinematic":
            problems.add(where, "path", "[...]", 'a path needs motion = "kinematic"')
        bodies.append(BodySpec(
            name=b["name"], shape=b["shape"], motion=b["motion"], position_m=b["position_m"],
            radius_m=b["radius_m"] or 0.0, half_extents_m=b["half_extents_m"] or (0.0, 0.0, 0.0),
            normal=b["normal"], rotation_deg=b["rotation_deg"], velocity_m_s=b["velocity_m_s"],
            path=b["path"], mass_kg=b["mass_kg"], gravity=b["gravity"], friction=b["friction"],
            collide=b["collide"], start_s=b["start_s"],
        ))

    attachments = []
    for a, i in att_raw:
        where = f"attachments.{i}"
        if a["body"] not in names:
            problems.add(where, "body", a["body"], "must name one of the [[bodies]]: "
                         + (", ".join(sorted(names)) or "(none defined)"))
        chosen = [k for k in ("edge", "corner", "warp_range", "region_center_m") if a[k] is not None]
        if a["weft_range"] is not None and "warp_range" not in chosen:
            chosen.append("weft_range")
        if len(chosen) != 1:
            problems.add(where, None, None, "give exactly one selection: edge, corner, warp_range + "
                         f"weft_range, or region_center_m + region_radius_m (got {chosen or 'none'})")
        for rk, n in (("warp_range", cloth.warp_yarns), ("weft_range", cloth.weft_yarns)):
            r = a[rk]
            if r is not None and not (0 <= r[0] <= r[1] < n):
                problems.add(where, rk, list(r), f"must be [first, last] with 0 <= first <= last <= {n - 1}")
        if (a["warp_range"] is None) != (a["weft_range"] is None) and "edge" not in chosen and "corner" not in chosen:
            problems.add(where, None, None, "warp_range and weft_range go together")
        if a["region_center_m"] is not None and a["region_radius_m"] <= 0:
            problems.add(where, "region_radius_m", a["region_radius_m"], "must be > 0 with region_center_m")
        attachments.append(AttachmentSpec(**a))

    r = values["render"]
    if r["resolution"][0] % 2 or r["resolution"][1] % 2:
        problems.add("render", "resolution", list(r["resolution"]),
                     "width and height must be even (H.264 with yuv420p needs even sizes)")
    cam = values["camera"]
    if math.dist(cam["position_m"], cam["target_m"]) < 1e-9:
        problems.add("camera", "target_m", list(cam["target_m"]), "must differ from position_m")
    if values["checks"]["frames"] > t["frames"]:
        problems.add("checks", "frames", values["checks"]["frames"], f"must be <= [time] frames = {t['frames']}")

    return SceneSpec(
        source=source,
        scene=SceneInfo(name=name, description=s["description"], seed=s["seed"]),
        time=TimeSpec(**t),
        cloth=cloth,
        gravity_m_s2=values["world"]["gravity_m_s2"],
        bodies=tuple(bodies),
        attachments=tuple(attachments),
        self_collision=SelfCollisionSpec(**values["self_collision"]),
        camera=CameraSpec(**cam),
        render=RenderSpec(**r),
        output=OutputSpec(**values["output"]),
        checks=CheckSpec(**values["checks"]),
    )


def load_scene(path: str | Path) -> SceneSpec:
    """Load a scene file. A bare name or a scenes/... path not found on disk is looked up among the
    scenes shipped with fraytool. Raises SceneError (exit 2) for a missing or invalid file."""
    from fraytool.resources import find_scene

    p = find_scene(path)
    try:
        text = p.read_text(encoding="utf-8")
    except OSError as exc:
        raise SceneError([f"{path}: cannot read scene file: {exc.strerror}"]) from None
    return parse_scene(text, str(path))


def scene_hash(spec: SceneSpec) -> str:
    """Stable digest of everything that affects the simulation (not camera/render/output)."""
    d = asdict(spec)
    for k in ("source", "camera", "render", "output", "checks"):
        d.pop(k)
    d["scene"].pop("description")
    d["time"].pop("frames")  # frame k does not depend on how many follow it
    d["time"].pop("fps")
    d["time"].pop("stability")
    blob = json.dumps(d, sort_keys=True, default=list).encode()
    return hashlib.sha256(blob).hexdigest()[:16]
