"""Rules that tie several scene keys together (each key's own type and range is in its Key).

Every rule takes already-converted values and returns the problems it finds as
(key, value, what is allowed), with key None for a problem of the table as a whole. The TOML loader
prefixes each problem with the file and the table; ModelBuilder with the method that was called.
So a scene built in code is held to exactly the rules of a scene file.
"""
from __future__ import annotations

import math
import re
from typing import Any, Iterable, Optional

from fraytool.scene import weave as weaves
from fraytool.scene.spec import (AttachmentSpec, BodySpec, CameraSpec, CutSpec, MultiresSpec, RenderSpec,
                                 StrainSpec, TearingSpec)

Problem = tuple[Optional[str], Any, str]
"""(key or None for the whole table, the value, what is allowed)."""
WeaveTable = tuple[tuple[bool, ...], ...]


def weave_table(weave: str, twill: str, satin_shafts: int,
                table: Optional[list[list[int]]]) -> tuple[WeaveTable, list[Problem]]:
    """The weave repeat of a [cloth] table (plain if the keys are inconsistent, with the problem)."""
    try:
        if weave == "twill":
            return weaves.twill(twill), []
        if weave == "satin":
            return weaves.satin(satin_shafts), []
        if weave == "table":
            if table is None:
                return weaves.plain(), [("weave", weave, 'weave = "table" needs a `table` key: rows of 0/1')]
            return weaves.from_rows(table), []
    except ValueError as exc:
        return weaves.plain(), [("twill", twill, str(exc))]
    return weaves.plain(), []


def cloth_problems(spacing_m: float, thickness_m: float) -> list[Problem]:
    """[cloth]: the two masses of a couple must fit between neighbouring yarns."""
    if thickness_m >= spacing_m:
        return [("thickness_m", thickness_m, f"must be below spacing_m = {spacing_m:g} (yarns would overlap)")]
    return []


def wrap_problems(spacing_m: float, wrap_radius_m: float) -> list[Problem]:
    """[cloth] wrap_radius_m: a cylinder at least four yarn spacings round (neighbouring crossings a quarter
    turn apart at most); tighter, neighbours fold onto each other (one full turn puts them on one point)."""
    if 0.0 < wrap_radius_m < spacing_m * 2.0 / math.pi:
        return [("wrap_radius_m", wrap_radius_m, f"must be 0 (flat) or at least {spacing_m * 2.0 / math.pi:.6g} "
                                                 f"(2 spacing_m / pi: four crossings round the cylinder)")]
    return []


def cloth_shape_problems(warp_yarns: int, weft_yarns: int, outline_m, mask: str, mask_size_m,
                         grain_deg: float) -> list[Problem]:
    """[cloth]: a rectangle of warp_yarns x weft_yarns, or a shape (outline_m or mask) that sets the grid."""
    out: list[Problem] = []
    shaped = bool(outline_m) or bool(mask)
    if outline_m and mask:
        out.append(("mask", mask, "give outline_m or mask, not both"))
    if not shaped:
        for k, v in (("warp_yarns", warp_yarns), ("weft_yarns", weft_yarns)):
            if v < 2:
                out.append((k, v, "must be an integer >= 2 (or give outline_m or mask: the shape sets the grid)")
                           if v else (None, None, f"`{k}` is missing or 0: a rectangle needs an integer >= 2 "
                                                   "(or give outline_m or mask: the shape sets the grid)"))
        if grain_deg != 0.0:
            out.append(("grain_deg", grain_deg, "turns the weave of a shaped panel (outline_m or mask); a "
                                                "rectangle turns with its plane"))
    else:
        for k, v in (("warp_yarns", warp_yarns), ("weft_yarns", weft_yarns)):
            if v:
                out.append((k, v, "leave it out with outline_m or mask: the shape sets the grid"))
    if mask and not (mask_size_m[0] > 0 and mask_size_m[1] > 0):
        out.append(("mask_size_m", list(mask_size_m), "with mask: the width and height the image covers, both > 0 [m]"))
    return out


def strain_problems(s: StrainSpec) -> list[Problem]:
    """[cloth.strain]: the dashpot past the limit belongs to the compliant limit."""
    if s.damping_ratio > 0.0 and s.stiffness_n_per_m == 0.0:
        return [("damping_ratio", s.damping_ratio,
                 "needs stiffness_n_per_m > 0 (a hard limit leaves no stretch past it to damp)")]
    return []


def tearing_problems(t: TearingSpec) -> list[Problem]:
    """[cloth.tearing]: yarn-level tearing splits a crossing before it cuts the spring."""
    if t.enabled and t.yarn_level and t.transition_strain >= t.break_strain:
        return [("transition_strain", t.transition_strain,
                 f"must be below break_strain = {t.break_strain:g} (splitting comes before cutting)")]
    return []


def multires_problems(m: MultiresSpec) -> list[Problem]:
    """[cloth.multires]: cells of factor x factor yarn spacings, factor a power of two up to 8."""
    if m.factor not in (1, 2, 4, 8):
        return [("factor", m.factor, "must be 1, 2, 4 or 8")]
    return []


def body_name_problems(name: str, taken: Iterable[str]) -> list[Problem]:
    """[[bodies]]: attachments find a body by its name."""
    return [("name", name, "must be unique among [[bodies]]")] if name in taken else []


def body_problems(b: BodySpec) -> list[Problem]:
    """[[bodies]]: the keys a shape needs, and motions it allows."""
    out: list[Problem] = []
    if b.shape == "sphere" and b.radius_m <= 0:
        out.append((None, None, "a sphere needs `radius_m` (> 0)"))
    if b.shape == "box":
        if not any(b.half_extents_m):
            out.append((None, None, "a box needs `half_extents_m` (3 numbers > 0)"))
        elif min(b.half_extents_m) <= 0:
            out.append(("half_extents_m", b.half_extents_m, "a box needs half_extents_m: 3 numbers > 0"))
    if b.shape == "plane":
        if b.motion == "dynamic":
            out.append(("motion", b.motion, 'a plane is "static" or "kinematic"'))
        if max(abs(v) for v in b.normal) == 0.0:
            out.append(("normal", b.normal, "must be a non-zero vector"))
    if b.shape == "mesh":
        if not b.file:
            out.append((None, None, 'a mesh needs `file` (OBJ, PLY, STL, glTF/GLB or USD, relative to the scene file)'))
        if b.motion == "dynamic":
            out.append(("motion", b.motion, 'a mesh is "static" or "kinematic" (it moves the cloth, the cloth '
                        'does not move it)'))
    else:
        for name, default in (("file", ""), ("prim", ""), ("scale", (1.0, 1.0, 1.0)), ("frame_time_s", 0.0),
                              ("sequence_start_s", 0.0)):
            if getattr(b, name) != default:
                value = getattr(b, name)
                out.append((name, list(value) if isinstance(value, tuple) else value,
                            f"is for meshes; a {b.shape} does not use it"))
    if b.path and b.motion != "kinematic":
        out.append(("path", "[...]", 'a path needs motion = "kinematic"'))
    out.extend(orientation_key_problems(b))
    # a size key of another shape would be silently ignored: say so instead
    if b.shape != "sphere" and b.radius_m > 0:
        out.append(("radius_m", b.radius_m, f'is for spheres; a {b.shape} does not use it'
                    + (" (its size is half_extents_m)" if b.shape == "box" else "")))
    if b.shape != "box" and any(b.half_extents_m):
        out.append(("half_extents_m", list(b.half_extents_m), f"is for boxes; a {b.shape} does not use it"))
    if b.shape != "plane" and tuple(b.normal) != (0.0, 1.0, 0.0):
        out.append(("normal", list(b.normal), f"is for planes; a {b.shape} does not use it (turn it with rotation_deg)"))
    return out


def orientation_key_problems(b: BodySpec) -> list[Problem]:
    """[[bodies]]: orientation keys (path_rotation_deg or path_quaternion, not both) turn a kinematic body
    instead of its fixed rotation_deg; interpolation = "catmull_rom" runs through 2 keys or more."""
    out: list[Problem] = []
    given = [k for k in ("path_rotation_deg", "path_quaternion") if getattr(b, k)]
    if len(given) == 2:
        out.append(("path_quaternion", "[...]", "give path_rotation_deg (Euler angles) or path_quaternion, not both"))
    if given and b.motion != "kinematic":
        out.append((given[0], "[...]", 'orientation keys need motion = "kinematic"'))
    if given and any(b.rotation_deg):
        out.append(("rotation_deg", list(b.rotation_deg), f"is the fixed orientation; {given[0]} sets the "
                                                          "orientation: key it there"))
    if b.interpolation == "catmull_rom":
        keyed = [k for k in ("path", "path_rotation_deg", "path_quaternion") if getattr(b, k)]
        if not keyed:
            out.append(("interpolation", b.interpolation, "is for path and orientation keys (path_rotation_deg "
                                                          "or path_quaternion): give some"))
        for k in keyed:
            if len(getattr(b, k)) < 2:
                out.append((k, [list(r) for r in getattr(b, k)], 'needs at least 2 keys with interpolation = '
                                                                  '"catmull_rom"'))
    return out


def attachment_problems(a: AttachmentSpec, body_names: Iterable[str], warp_yarns: int,
                        weft_yarns: int) -> list[Problem]:
    """[[attachments]]: a known body, exactly one selection, indices inside the grid."""
    out: list[Problem] = []
    names = set(body_names)
    if a.body not in names:
        out.append(("body", a.body,
                    "must name one of the [[bodies]]: " + (_some(sorted(names)) or "(none defined)")))
    chosen = [k for k in ("edge", "corner", "warp_range", "region_center_m") if getattr(a, k) is not None]
    if a.weft_range is not None and "warp_range" not in chosen:
        chosen.append("weft_range")
    if len(chosen) != 1:
        out.append((None, None, "give exactly one selection: edge, corner, warp_range + "
                    f"weft_range, or region_center_m + region_radius_m (got {chosen or 'none'})"))
    for rk, n in (("warp_range", warp_yarns), ("weft_range", weft_yarns)):
        r = getattr(a, rk)
        if r is not None and not (0 <= r[0] <= r[1] < n):
            out.append((rk, list(r), f"must be [first, last] with 0 <= first <= last <= {n - 1}"))
    if (a.warp_range is None) != (a.weft_range is None) and "edge" not in chosen and "corner" not in chosen:
        out.append((None, None, "warp_range and weft_range go together"))
    if a.region_center_m is not None and a.region_radius_m <= 0:
        out.append(("region_radius_m", a.region_radius_m, "must be > 0 with region_center_m"))
    return out


SCENE_NAME = re.compile(r"[A-Za-z0-9_-][A-Za-z0-9._-]{0,99}")


def scene_name_problems(name: str, from_file_name: bool) -> list[Problem]:
    """[scene] name names the output folder and files, so it is a name, never a path: letters, digits,
    "-", "_" and "." (not first), at most 100 characters."""
    if SCENE_NAME.fullmatch(name):
        return []
    shown = name if len(name) <= 60 else name[:57] + "..."
    allowed = ('must be letters, digits, "-", "_" and "." (not first), 1 to 100 characters: it names the '
               "output folder and files, never a path")
    if from_file_name:
        allowed += " (taken from the file name; set [scene] name)"
    return [("name", shown, allowed)]


def cut_problems(c: CutSpec, warp_yarns: int, weft_yarns: int) -> list[Problem]:
    """[[cuts]]: a snip (start and end within one spacing of the grid, -1 <= i <= warp_yarns, likewise j,
    and apart) or scissors (path_m of 2 points or more, end_s not before start_s)."""
    out: list[Problem] = []
    if c.path_m:
        if c.start is not None or c.end is not None:
            out.append(("path_m", "[...]", "give path_m (scissors) or start and end (a snip), not both"))
        if len(c.path_m) < 2:
            out.append(("path_m", [list(p) for p in c.path_m], "needs at least 2 points [u, v]"))
        if c.end_s < c.start_s:
            out.append(("end_s", c.end_s, f"must not be before start_s = {c.start_s:g}"))
        return out
    if c.start is None or c.end is None:
        return [(None, None, "give start and end (a snip, in yarn indices) or path_m with start_s and end_s "
                             "(scissors)")]
    if c.start_s or c.end_s:
        out.append(("start_s", c.start_s, "start_s and end_s time scissors along path_m; a snip along start-end "
                                          "is there from the first frame"))
    for name, (i, j) in (("start", c.start), ("end", c.end)):
        if not (-1.0 <= i <= warp_yarns and -1.0 <= j <= weft_yarns):
            out.append((name, [i, j], f"must be [i, j] with -1 <= i <= {warp_yarns} and -1 <= j <= {weft_yarns} "
                                      "(yarn indices, within one spacing of the cloth)"))
    if c.start == c.end:
        out.append(("end", list(c.end), "must differ from start (a cut is a line)"))
    return out


def weak_line_problems(w) -> list[Problem]:
    """[[weak_lines]]: a polyline of at least 2 points."""
    if len(w.points_m) < 2:
        return [("points_m", [list(p) for p in w.points_m], "needs at least 2 points [u, v] (a line)")]
    return []


def tear_map_problems(tear_map: str, tear_map_strain) -> list[Problem]:
    """[cloth] tear_map needs the strains it maps to."""
    if tear_map and not (tear_map_strain[0] > 0 and tear_map_strain[1] > 0):
        return [("tear_map_strain", list(tear_map_strain), "with tear_map: the mean break strain at black and "
                                                           "at white, both > 0")]
    return []


def render_problems(r: RenderSpec) -> list[Problem]:
    out: list[Problem] = []
    for name in ("light_direction", "fill_direction"):
        if math.hypot(*getattr(r, name)) < 1e-9:
            out.append((name, list(getattr(r, name)), "must not be the zero vector (it is a direction)"))
    return out


def camera_problems(c: CameraSpec) -> list[Problem]:
    if math.dist(c.position_m, c.target_m) < 1e-9:
        return [("target_m", list(c.target_m), "must differ from position_m")]
    return []


def checks_problems(check_frames: int, frames: int) -> list[Problem]:
    if check_frames > frames:
        return [("frames", check_frames, f"must be <= [time] frames = {frames}")]
    return []


def _some(names: list[str], most: int = 10) -> str:
    """The first `most` names, then how many more."""
    text = ", ".join(names[:most])
    return text + (f", ... ({len(names) - most} more)" if len(names) > most else "")
