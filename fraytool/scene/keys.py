"""Key: the one declaration of a scene key -- its type, default, allowed range and meaning.

Every scene key is declared once, on the SceneSpec dataclass field it fills (fraytool.scene.spec):

    limit: float = key("float", 0.10, lo=0, lo_open=True, hi=10, doc="strain limit ...")

`key()` gives the field its default and records the Key in the field's metadata. From there
`fraytool.scene.schema` lays the keys out as TOML tables for the file loader, and
`fraytool.sim.builder.ModelBuilder` checks its keyword arguments against the same Keys, so a
default, a range or a meaning cannot differ between a scene file and a scene built in code.
"""
from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import dataclass
from typing import Any, Optional


class _Required:
    def __repr__(self) -> str:
        return "REQUIRED"


REQUIRED: Any = _Required()
"""Default of a key that must be given."""


@dataclass(frozen=True)
class Key:
    kind: str
    """"float", "int", "bool", "str", "vec3", "color", "int2", "float2", "points2", "ints", "path", "path_deg",
    "path_quat", "path_fov", "table2d"."""
    default: Any = REQUIRED
    """Value when the key is not given; REQUIRED if it must be; None for "not given" (optional)."""
    lo: Optional[float] = None
    hi: Optional[float] = None
    lo_open: bool = False
    """True: value must be > lo (not >=)."""
    hi_open: bool = False
    choices: Optional[tuple[str, ...]] = None
    doc: str = ""
    """What the key means, with its unit; shown in error messages."""

    def allowed(self) -> str:
        """Human-readable statement of what the key accepts."""
        if self.choices:
            return "one of " + ", ".join(f'"{c}"' for c in self.choices)
        what = {
            "float": "a number",
            "int": "an integer",
            "bool": "true or false",
            "str": "a string",
            "vec3": "an array of 3 numbers, each",
            "color": "an array of 3 numbers in [0, 1]",
            "int2": "an array of 2 integers",
            "float2": "an array of 2 numbers",
            "points2": "an array of [u, v] arrays of 2 finite numbers, each",
            "ints": "an array of integers, each",
            "path": "an array of [t, x, y, z] arrays of finite numbers, times from 0 to 1e6 s and increasing, "
                    "positions",
            "path_deg": "an array of [t, rx, ry, rz] arrays of finite numbers, times from 0 to 1e6 s and "
                        "increasing, angles [degrees]",
            "path_quat": "an array of [t, w, x, y, z] arrays of finite numbers, times from 0 to 1e6 s and "
                         "increasing, quaternions (w, x, y, z) of norm at least 1e-6",
            "path_fov": "an array of [t, value] arrays of finite numbers, times from 0 to 1e6 s and increasing, "
                        "values",
            "table2d": "equal-length rows of the integers 0 and 1 (not true / false)",
        }[self.kind]
        bounds = []
        if self.lo is not None:
            bounds.append(f"{'>' if self.lo_open else '>='} {self.lo:g}")
        if self.hi is not None:
            bounds.append(f"{'<' if self.hi_open else '<='} {self.hi:g}")
        return what + (" " + " and ".join(bounds) if bounds else "")

    def explain(self) -> str:
        """What is allowed, then the meaning: the tail of an error message."""
        return self.allowed() + (f" ({self.doc})" if self.doc else "")

    def in_range(self, x: float) -> bool:
        if not math.isfinite(x):
            return False
        if self.lo is not None and (x <= self.lo if self.lo_open else x < self.lo):
            return False
        if self.hi is not None and (x >= self.hi if self.hi_open else x > self.hi):
            return False
        return True

    def convert(self, value: Any) -> tuple[bool, Any]:
        """Check a value (from TOML, or a Python argument) and convert it to the key's Python type.

        Returns (ok, converted). Sequences may be lists (TOML), tuples or NumPy arrays (Python);
        vectors come back as tuples of floats. An integer too large for a float is simply out of range."""
        try:
            return self._convert(value)
        except OverflowError:
            return False, None

    def _convert(self, value: Any) -> tuple[bool, Any]:
        if hasattr(value, "tolist"):  # NumPy scalar or array from a Python caller
            value = value.tolist()
        k = self.kind
        if k == "float":
            if not _is_number(value) or not self.in_range(float(value)):
                return False, None
            return True, float(value)
        if k == "int":
            if not isinstance(value, int) or isinstance(value, bool) or not self.in_range(value):
                return False, None
            return True, int(value)
        if k == "bool":
            return (True, value) if isinstance(value, bool) else (False, None)
        if k == "str":
            if not isinstance(value, str) or (self.choices and value not in self.choices):
                return False, None
            return True, value
        if k in ("vec3", "color"):
            if not _is_seq(value) or len(value) != 3 or not all(_is_number(v) for v in value):
                return False, None
            out = tuple(float(v) for v in value)
            if not all(math.isfinite(v) for v in out):
                return False, None
            if k == "color" and not all(0.0 <= v <= 1.0 for v in out):
                return False, None
            if not all(self.in_range(v) for v in out):
                return False, None
            return True, out
        if k == "int2":
            if not _is_seq(value) or len(value) != 2:
                return False, None
            if not all(isinstance(v, int) and not isinstance(v, bool) for v in value):
                return False, None
            if not all(self.in_range(v) for v in value):
                return False, None
            return True, (int(value[0]), int(value[1]))
        if k == "float2":
            if not _is_seq(value) or len(value) != 2 or not all(_is_number(v) for v in value):
                return False, None
            pair = (float(value[0]), float(value[1]))
            if not all(self.in_range(v) for v in pair):
                return False, None
            return True, pair
        if k == "ints":
            if not _is_seq(value) or not all(isinstance(v, int) and not isinstance(v, bool) for v in value):
                return False, None
            if not all(self.in_range(v) for v in value):
                return False, None
            return True, tuple(int(v) for v in value)
        if k == "points2":
            if not _is_seq(value):
                return False, None
            points = []
            for row in value:
                if not _is_seq(row) or len(row) != 2 or not all(_is_number(v) for v in row):
                    return False, None
                points.append((float(row[0]), float(row[1])))
                if not all(self.in_range(v) for v in points[-1]):
                    return False, None
            return True, tuple(points)
        if k in PATH_WIDTHS:
            return self._convert_path(value)
        if k == "table2d":
            if not _is_seq(value) or not value:
                return False, None
            width = None
            for row in value:
                if not _is_seq(row) or not row or not all(v in (0, 1) and not isinstance(v, (float, bool))
                                                          for v in row):
                    return False, None
                width = len(row) if width is None else width
                if len(row) != width:
                    return False, None
            return True, [[int(v) for v in row] for row in value]
        raise AssertionError(k)

    def _convert_path(self, value: Any) -> tuple[bool, Any]:
        """Keys [t, value...] of a path kind (PATH_WIDTHS): finite, times in [0, PATH_MAX_TIME_S] and strictly
        increasing, values within hi, a quaternion not zero."""
        if not _is_seq(value):
            return False, None
        rows = []
        for row in value:
            if not _is_seq(row) or len(row) != PATH_WIDTHS[self.kind] or not all(_is_number(v) for v in row):
                return False, None
            rows.append(tuple(float(v) for v in row))
            if not all(math.isfinite(v) for v in rows[-1]) or rows[-1][0] > PATH_MAX_TIME_S \
                    or any(abs(v) > self.hi for v in rows[-1][1:] if self.hi is not None):
                return False, None
            if self.kind == "path_quat" and not math.hypot(*rows[-1][1:]) >= MIN_QUATERNION_NORM:
                return False, None
            if self.kind == "path_fov" and not self.in_range(rows[-1][1]):
                return False, None
        times = [r[0] for r in rows]
        if any(b <= a for a, b in zip(times, times[1:])) or any(t < 0 for t in times):
            return False, None
        return True, tuple(rows)


def key(kind: str, default: Any = REQUIRED, *, lo: Optional[float] = None, hi: Optional[float] = None,
        lo_open: bool = False, hi_open: bool = False, choices: Optional[tuple[str, ...]] = None,
        doc: str = "") -> Any:
    """A dataclass field that is a scene key: its default (none if REQUIRED) plus the Key in metadata."""
    k = Key(kind, default, lo=lo, hi=hi, lo_open=lo_open, hi_open=hi_open, choices=choices, doc=doc)
    if default is REQUIRED:
        return dataclasses.field(metadata={"key": k})
    return dataclasses.field(default=default, metadata={"key": k})


def keys_of(cls: type) -> dict[str, Key]:
    """The scene keys declared on a dataclass, in field order (fields that are not keys are left out)."""
    return {f.name: f.metadata["key"] for f in dataclasses.fields(cls) if "key" in f.metadata}


PATH_MAX_TIME_S = 1.0e6
"""Latest keyframe time of a path [s]."""
MIN_QUATERNION_NORM = 1e-6
"""Smallest norm of an orientation key (w, x, y, z) before it is normalised: a key of norm 1e-200 squares
to 0 and would turn the body into NaN."""
PATH_WIDTHS = {"path": 4, "path_deg": 4, "path_quat": 5, "path_fov": 2}
"""Numbers per key of each path kind: the time, then a position, Euler angles, a quaternion or one number
(a camera's field of view)."""

SHOW_MAX_CHARS = 80
"""Longest value echoed in a message; longer ones are cut, with their size (a 1,000,000-item array
once made a 3 MB error line)."""


def show(value: Any, max_chars: int = SHOW_MAX_CHARS) -> str:
    """A value as written in a scene file, for messages (at most about `max_chars` characters)."""
    if hasattr(value, "tolist"):
        value = value.tolist()
    if isinstance(value, str):
        text = json.dumps(value)
    elif isinstance(value, bool):
        return "true" if value else "false"
    elif isinstance(value, dict):
        return "{...}"
    elif isinstance(value, (list, tuple)):
        try:
            text = json.dumps(value, default=str)
        except (RecursionError, ValueError):
            return f"[... nested arrays, {len(value)} items]"
    else:
        text = repr(value)
    if len(text) <= max_chars:
        return text
    size = f"{len(value)} items" if isinstance(value, (list, tuple)) else f"{len(text)} characters"
    return f"{text[:max_chars]}... ({size})"


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _is_seq(v: Any) -> bool:
    return isinstance(v, (list, tuple))
