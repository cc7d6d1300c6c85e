"""`--set KEY=VALUE`: override any scene key before validation, so an override is checked exactly
like the file (wedges and batch jobs use the same).

KEY is the dotted path of a key as the file nests it: `scene.seed`, `cloth.tearing.break_strain`,
`bodies.0.radius_m` (the first [[bodies]] table) or `bodies.ball.radius_m` (the one with name =
"ball"), `camera.position_m`. VALUE is a TOML value
(`0.3`, `true`, `[0.0, 1.0, 0.0]`, `"twill"`); a bare word that is not TOML is taken as a string
(`--set cloth.weave=twill`). Missing tables on the way are created; a key or table that the schema
does not have is reported by validation, with the file and the --set it came from.
"""
from __future__ import annotations

import tomllib
from typing import Any, Sequence

from fraytool.errors import InputError
from fraytool.scene.keys import show
from fraytool.scene.schema import ARRAY_TABLES

MAX_KEY_CHARS = 200


def parse_assignment(text: str, flag: str = "--set") -> tuple[str, Any]:
    """'KEY=VALUE' -> (key, value as TOML)."""
    key, eq, raw = text.partition("=")
    key = key.strip()
    if not eq or not key:
        raise InputError(f"{flag} {text[:MAX_KEY_CHARS]!r}: expected KEY=VALUE, e.g. {flag} cloth.tearing.break_strain=0.3")
    parts = key.split(".")
    if len(key) > MAX_KEY_CHARS or not all(p and (p.isidentifier() or p.isdigit()) for p in parts):
        raise InputError(f"{flag} {key[:MAX_KEY_CHARS]!r}: a key is a dotted path of names, e.g. cloth.tearing.break_strain "
                         "or bodies.0.radius_m")
    return key, parse_value(raw.strip())


def parse_value(raw: str) -> Any:
    try:
        return tomllib.loads(f"v = {raw}")["v"]
    except (tomllib.TOMLDecodeError, RecursionError):
        return raw  # a bare word: a string


def apply_overrides(doc: dict, overrides: Sequence[tuple[str, Any]], flag: str = "--set") -> dict:
    """The scene document (parsed TOML) with each (dotted key, value) set, in order; `doc` is changed."""
    for key, value in overrides:
        node: Any = doc
        parts = key.split(".")
        for i, part in enumerate(parts[:-1]):
            where = ".".join(parts[: i + 1])
            if isinstance(node, list):
                node = _table_of(node, part, key, ".".join(parts[:i]), flag)
            elif isinstance(node, dict):
                if part not in node and (parts[i + 1].isdigit() or where in ARRAY_TABLES):
                    raise InputError(f"{flag} {key}=...: the scene has no [[{where}]] tables")
                node = node.setdefault(part, {})
            else:
                raise InputError(f"{flag} {key}=...: {where} is a value, not a table")
        if isinstance(node, list) or not isinstance(node, dict):
            raise InputError(f"{flag} {key}=...: {'.'.join(parts[:-1])} is not a table")
        node[parts[-1]] = value
    return doc


def _table_of(tables: list, part: str, key: str, where: str, flag: str) -> dict:
    """The table of an array of tables ([[bodies]]) that `part` names: its index, or its `name`."""
    if part.isdigit():
        if int(part) < len(tables):
            return tables[int(part)]
        raise InputError(f"{flag} {key}=...: [[{where}]] has {len(tables)} table(s); index {part} does not exist")
    named = [t for t in tables if isinstance(t, dict) and t.get("name") == part]
    if len(named) == 1:
        return named[0]
    names = ", ".join(repr(t.get("name")) for t in tables if isinstance(t, dict) and isinstance(t.get("name"), str))
    if named:
        raise InputError(f"{flag} {key}=...: {len(named)} [[{where}]] tables are named {part!r}; use the index (0 to "
                         f"{len(tables) - 1})")
    raise InputError(f"{flag} {key}=...: no [[{where}]] table is named {part!r}; the names are {names or 'none'} "
                     f"(or use the index, 0 to {len(tables) - 1})")


def describe(overrides: Sequence[tuple[str, Any]]) -> str:
    """How the source of an overridden scene is named in messages: each value as TOML writes it (true, "twill",
    [0.0, 1.0]), so it can be given again as it reads."""
    shown = ", ".join(f"{k[:60]}={show(v, 60)}" for k, v in overrides[:4])
    more = f" and {len(overrides) - 4} more" if len(overrides) > 4 else ""
    return f" (with --set {shown}{more})"
