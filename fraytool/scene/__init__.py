"""Scene files: TOML -> validated SceneSpec (see docs/scene-format.md)."""
from fraytool.scene.load import load_scene, parse_scene, scene_hash
from fraytool.scene.spec import SceneSpec

__all__ = ["load_scene", "parse_scene", "scene_hash", "SceneSpec"]
