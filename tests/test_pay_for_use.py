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


def test_contact_before_the_strain_limit_only_where_a_tearing_cloth_meets_a_body():
    """The extra rigid-contact pass before strain limiting (RigidContactBeforeLimit) exists only in a
    scene that tears and has a colliding body, ahead of StrainLimiting; step 6's contact stays after
    the constraints, as in the paper's order."""
    from fraytool.scene import parse_scene
    from fraytool.sim import Simulation
    from helpers import pulled_strip_text

    def stage_names(text):
        return [type(s).__name__ for s in Simulation(parse_scene(text, "s.toml")).solver.stages]

    ball = ('[[bodies]]\nname = "ball"\nshape = "sphere"\nradius_m = 0.01\nposition_m = [0.04, 0.018, 0.01]\n')
    torn = stage_names(pulled_strip_text("strip", yarn_level=True, extra=ball))
    assert torn.index("RigidContactBeforeLimit") < torn.index("StrainLimiting") < torn.index("RigidContact")
    assert torn.index("RigidContact") < torn.index("TearingStage")
    assert "RigidContactBeforeLimit" not in stage_names(small_scene_text() + BODY)  # does not tear
    assert "RigidContactBeforeLimit" not in stage_names(pulled_strip_text("strip", yarn_level=True))  # no ball
