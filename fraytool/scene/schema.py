"""The TOML scene layout: which table holds which keys.

The keys themselves (type, default, range, meaning) are declared once, on the SceneSpec dataclass
fields (`fraytool.scene.spec`); this module only lays them out as the tables of a scene file.
`fraytool.scene.load` walks a parsed TOML document against these tables and reports every problem
as "file: [table] key = value: what is allowed"; docs/scene-format.md documents the same tables for
people, and tests/test_docs.py checks that every key here is documented there.
"""
from __future__ import annotations

from fraytool.scene import spec
from fraytool.scene.keys import REQUIRED, Key, keys_of

__all__ = ["REQUIRED", "Key", "TOP", "REQUIRED_TABLES", "ARRAY_TABLES", "WEAVE_TABLE"]

WEAVE_TABLE = Key("table2d", None, doc='with weave = "table": 1 weft on top, 0 warp on top')
"""[cloth] table: the one key that is not a SceneSpec field (it becomes ClothSpec.weave_table)."""

TOP: dict[str, dict[str, Key]] = {
    "scene": keys_of(spec.SceneInfo),
    "time": keys_of(spec.TimeSpec),
    "world": keys_of(spec.SceneSpec),  # the scene's own key: gravity_m_s2
    "cloth": {**keys_of(spec.ClothSpec), "table": WEAVE_TABLE},
    "cloth.springs": keys_of(spec.SpringSpec),
    "cloth.strain": keys_of(spec.StrainSpec),
    "cloth.tearing": keys_of(spec.TearingSpec),
    "cloth.multires": keys_of(spec.MultiresSpec),
    "self_collision": keys_of(spec.SelfCollisionSpec),
    "bodies": keys_of(spec.BodySpec),
    "attachments": keys_of(spec.AttachmentSpec),
    "cuts": keys_of(spec.CutSpec),
    "weak_lines": keys_of(spec.WeakLineSpec),
    "seams": keys_of(spec.SeamSpec),
    "camera": keys_of(spec.CameraSpec),
    "render": keys_of(spec.RenderSpec),
    "output": keys_of(spec.OutputSpec),
    "checks": keys_of(spec.CheckSpec),
    "golden": keys_of(spec.GoldenSpec),
}
"""Table name (dotted for sub-tables) -> key name -> Key."""
REQUIRED_TABLES = ("time", "cloth", "cloth.springs")
ARRAY_TABLES = ("bodies", "attachments", "cuts", "weak_lines", "seams")
"""Tables written [[name]], any number of times."""
