"""docs/scene-format.md documents every key and table of the schema (so the two cannot drift)."""
from pathlib import Path

import pytest

from fraytool.scene import schema

DOC = (Path(__file__).resolve().parent.parent / "docs" / "scene-format.md").read_text()


@pytest.mark.parametrize("table", sorted(schema.TOP))
def test_every_schema_key_is_documented(table):
    name = f"`[[{table}]]`" if table in schema.ARRAY_TABLES else f"`[{table}]`"
    heading = next((h for h in (f"\n## {name}", f"\n### {name}") if h in DOC), None)
    assert heading, f"no section for [{table}]"
    section = DOC.split(heading, 1)[1].split("\n## ", 1)[0].split("\n### ", 1)[0]
    for key in schema.TOP[table]:
        assert f"`{key}`" in section, f"[{table}] {key} is not documented"
