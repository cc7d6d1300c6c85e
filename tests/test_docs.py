"""docs/scene-format.md documents every key and table of the schema, with the schema's defaults (so
the two cannot drift)."""
import tomllib
from pathlib import Path

import pytest

from fraytool.scene import schema

pytestmark = pytest.mark.fast  # `pytest -m fast` (docs/testing.md)

DOC = (Path(__file__).resolve().parent.parent / "docs" / "scene-format.md").read_text()


def _section(table: str) -> str:
    name = f"`[[{table}]]`" if table in schema.ARRAY_TABLES else f"`[{table}]`"
    heading = next((h for h in (f"\n## {name}", f"\n### {name}") if h in DOC), None)
    assert heading, f"no section for [{table}]"
    return DOC.split(heading, 1)[1].split("\n## ", 1)[0].split("\n### ", 1)[0]


def _documented_defaults(section: str) -> dict[str, str]:
    """key -> default cell, for the table rows that document one key."""
    out = {}
    for line in section.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) >= 3 and cells[0].count("`") == 2 and cells[0].startswith("`"):
            out[cells[0].strip("`")] = cells[2]
    return out


@pytest.mark.parametrize("table", sorted(schema.TOP))
def test_every_schema_key_is_documented(table):
    section = _section(table)
    for key in schema.TOP[table]:
        assert f"`{key}`" in section, f"[{table}] {key} is not documented"


@pytest.mark.parametrize("table", sorted(schema.TOP))
def test_documented_defaults_are_the_schema_defaults(table):
    """A default cell is "required", "—" (not given), a TOML value, or words (not checked)."""
    for key, cell in _documented_defaults(_section(table)).items():
        assert key in schema.TOP[table], f"[{table}] documents `{key}`, which is not a key"
        default = schema.TOP[table][key].default
        if cell == "required":
            assert default is schema.REQUIRED, f"[{table}] {key}: documented as required"
        elif cell == "—":
            assert default is None, f"[{table}] {key}: documented without a default, schema has {default!r}"
        else:
            try:
                value = tomllib.loads(f"v = {cell}")["v"]
            except tomllib.TOMLDecodeError:
                continue  # words, e.g. "file name"
            expected = list(default) if isinstance(default, tuple) else default
            assert default is not schema.REQUIRED and value == expected, \
                f"[{table}] {key}: documented default {cell}, schema default {default!r}"
