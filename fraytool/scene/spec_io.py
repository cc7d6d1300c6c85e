"""A SceneSpec as JSON and back: what a frames folder keeps of the scene (`frames/scene.json`), so that a
render, an export or a resume of a shot needs no scene file (a model built in Python has none).

The JSON is `dataclasses.asdict` of the spec without where it was read from (`source`, `source_file`: one
scene gives the same record from any path, so two runs of it write the same topology); reading it back
rebuilds each dataclass from its field types (tuples stay tuples, optional tables stay None), so
`spec_from_json(spec_to_json(s)) == replace(s, source="", source_file="")`.
"""
from __future__ import annotations

import dataclasses
import json
import types
import typing
from functools import lru_cache
from typing import Any

from fraytool.scene.spec import SceneSpec

SPEC_JSON_VERSION = 1
"""Raised when the JSON layout changes in a way an older reader would misread."""


def spec_to_json(spec: SceneSpec) -> str:
    """The spec as JSON text (keys sorted, one stable text for one spec)."""
    spec = dataclasses.replace(spec, source="", source_file="")
    return json.dumps({"version": SPEC_JSON_VERSION, "spec": dataclasses.asdict(spec)}, sort_keys=True, indent=1)


def spec_from_json(text: str, source: str = "") -> SceneSpec:
    """The SceneSpec written by spec_to_json, with `source` (what messages name it by). Raises ValueError
    naming what does not fit."""
    data = json.loads(text)
    if not isinstance(data, dict) or data.get("version") != SPEC_JSON_VERSION or "spec" not in data:
        raise ValueError(f"not a fraytool scene record of version {SPEC_JSON_VERSION}")
    return dataclasses.replace(_build(SceneSpec, data["spec"], "spec"), source=source)


@lru_cache(maxsize=None)
def _hints(cls) -> dict[str, Any]:
    return typing.get_type_hints(cls)


def _build(cls, raw: Any, where: str):
    """The dataclass `cls` from its asdict form."""
    if not isinstance(raw, dict):
        raise ValueError(f"{where}: expected a table, got {type(raw).__name__}")
    hints = _hints(cls)
    names = {f.name for f in dataclasses.fields(cls)}
    unknown = set(raw) - names
    if unknown:
        raise ValueError(f"{where}: unknown field(s) {sorted(unknown)}")
    return cls(**{name: _convert(hints[name], value, f"{where}.{name}") for name, value in raw.items()})


def _convert(hint: Any, value: Any, where: str):
    """`value` (from JSON) as the type `hint` says: dataclasses, tuples (fixed or variable length),
    Optional, and the leaves (bool, int, float, str) as they are."""
    origin = typing.get_origin(hint)
    if dataclasses.is_dataclass(hint):
        return _build(hint, value, where)
    if origin in (typing.Union, types.UnionType):
        args = typing.get_args(hint)
        if value is None and type(None) in args:
            return None
        inner = [a for a in args if a is not type(None)]
        return _convert(inner[0], value, where)
    if origin is tuple:
        args = typing.get_args(hint)
        if not isinstance(value, (list, tuple)):
            raise ValueError(f"{where}: expected a list, got {type(value).__name__}")
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(_convert(args[0], v, f"{where}[{k}]") for k, v in enumerate(value))
        if len(args) != len(value):
            raise ValueError(f"{where}: expected {len(args)} values, got {len(value)}")
        return tuple(_convert(a, v, f"{where}[{k}]") for k, (a, v) in enumerate(zip(args, value)))
    if hint is float and isinstance(value, int) and not isinstance(value, bool):
        return float(value)
    return value
