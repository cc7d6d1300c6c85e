"""A scene pays only for what it uses: kernels of passes it lacks are never compiled or loaded."""
import json
import subprocess
import sys

from helpers import small_scene_text

PROBE = """
import json, sys
from fraytool.scene import parse_scene
from fraytool.sim import Simulation
from fraytool.sim.kernels import attachments, rigid_contact
sim = Simulation(parse_scene(open(sys.argv[1]).read(), sys.argv[1]))
for _ in sim.frames(3):
    pass
print(json.dumps({
    "rigid": len(rigid_contact.collide_rigid.signatures),
    "attach": len(attachments.apply_attachments.signatures),
    "solver_has_rigid": any(s.name == "collisions" for s in sim.solver.stages),
    "tearing": sim.solver.tearing is not None,
    "self_collision": sim.solver.self_collision is not None,
    "modules": sorted(m for m in sys.modules if m.startswith("fraytool.sim.tearing") or m.startswith("fraytool.collision")),
}))
"""

BODY = """
[[bodies]]
name = "ball"
shape = "sphere"
radius_m = 0.01
position_m = [0.0, 0.0, 0.0]

[[attachments]]
body = "ball"
corner = "top_left"
"""


def _probe(tmp_path, text):
    scene = tmp_path / "s.toml"
    scene.write_text(text)
    r = subprocess.run([sys.executable, "-c", PROBE, str(scene)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout.strip().splitlines()[-1])


def test_plain_cloth_compiles_no_rigid_or_attachment_kernel(tmp_path):
    out = _probe(tmp_path, small_scene_text())
    assert out == {"rigid": 0, "attach": 0, "solver_has_rigid": False, "tearing": False,
                   "self_collision": False, "modules": []}


def test_bodies_and_attachments_do_compile_their_kernels(tmp_path):
    out = _probe(tmp_path, small_scene_text() + BODY)
    assert out["rigid"] == 1 and out["attach"] == 1 and out["solver_has_rigid"]
