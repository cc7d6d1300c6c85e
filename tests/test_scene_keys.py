"""simulation_keys / key_changes: the keys a run names when it simulates again, and a golden report names when
the scene differs from the golden's (by key and value, as the scene file writes them)."""
from fraytool.scene import load_scene, scene_hash
from fraytool.scene.load import key_changes, simulation_keys
from fraytool.scene.overrides import parse_assignment
import pytest

pytestmark = pytest.mark.fast  # `pytest -m fast` (docs/testing.md)


def _load(name, *sets):
    return load_scene(name, [parse_assignment(s) for s in sets])


def test_a_simulation_key_is_named_as_the_scene_file_writes_it():
    base = _load("seam_rip")
    changed = _load("seam_rip", "world.gravity_m_s2=[0.0, -8.5, 0.0]", "bodies.0.friction=0.9")
    lines = key_changes(simulation_keys(base), simulation_keys(changed))
    assert lines == ["bodies.0.friction: " + f"{base.bodies[0].friction} -> 0.9",
                     "world.gravity_m_s2: [0.0, -9.81, 0.0] -> [0.0, -8.5, 0.0]"], lines


def test_the_second_panel_is_cloth_1_and_picture_keys_are_not_simulation_keys():
    base = _load("seam_rip")
    assert "cloth.1.spacing_m" in simulation_keys(base) and "cloth.0.spacing_m" in simulation_keys(base)
    look = _load("seam_rip", "camera.fov_deg=20", "render.samples=0", "cloth.0.warp_color=[0.1, 0.2, 0.3]")
    assert key_changes(simulation_keys(base), simulation_keys(look)) == []
    assert scene_hash(base) == scene_hash(look)  # the same frames: a render reuses them


def test_many_changes_are_cut_with_a_count():
    before = {f"k{i}": i for i in range(12)}
    after = {f"k{i}": i + 1 for i in range(12)}
    lines = key_changes(before, after, limit=3)
    assert len(lines) == 4 and lines[-1] == "and 9 more keys"
    assert key_changes({"a": 1}, {"b": 2}) == ["a: 1 -> (unset)", "b: (unset) -> 2"]
