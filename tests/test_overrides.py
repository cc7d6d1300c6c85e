"""--set KEY=VALUE: an override is the same as editing the file, and is validated like the file."""
import pytest

from fraytool.commands.main import main
from fraytool.scene import load_scene, parse_scene, scene_hash
from helpers import BALL, small_scene_text

pytestmark = pytest.mark.fast  # `pytest -m fast` (docs/testing.md)



@pytest.fixture
def scene(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text(small_scene_text() + BALL)
    return path


@pytest.mark.parametrize("sets,edit", [
    (["scene.seed=7"], ("seed = 1", "seed = 7")),
    (["bodies.0.radius_m=0.03"], ("radius_m = 0.02", "radius_m = 0.03")),
    (["bodies.ball.radius_m=0.03"], ("radius_m = 0.02", "radius_m = 0.03")),   # by the body's name
    (["cloth.weave=twill"], ('weave = "plain"', 'weave = "twill"')),
    (["cloth.weave=\"twill\""], ('weave = "plain"', 'weave = "twill"')),
    (["world.gravity_m_s2=[0.0, -1.0, 0.0]"], ("gravity_m_s2 = [0.0, -9.81, 0.0]", "gravity_m_s2 = [0.0, -1.0, 0.0]")),
    (["cloth.tearing.enabled=true", "cloth.tearing.break_strain=0.3"],
     ("[cloth.strain]", "[cloth.tearing]\nenabled = true\nbreak_strain = 0.3\n\n[cloth.strain]")),
])
def test_set_equals_editing_the_file(sets, edit, scene, tmp_path):
    from fraytool.scene.overrides import parse_assignment

    text = scene.read_text()
    assert edit[0] in text
    edited = parse_scene(text.replace(edit[0], edit[1], 1), str(scene))
    overridden = load_scene(scene, [parse_assignment(a) for a in sets])
    assert scene_hash(overridden) == scene_hash(edited)
    assert overridden.cloth == edited.cloth and overridden.bodies == edited.bodies
    assert overridden.scene.name == edited.scene.name == "small"


@pytest.mark.parametrize("arg,needle", [
    ("cloth.tearing.break_strain=abc", '[cloth.tearing] break_strain = "abc": a number'),
    ("cloth.foo=1", "[cloth] foo = 1: unknown key"),
    ("bodies.3.radius_m=0.1", "[[bodies]] has 1 table(s); index 3 does not exist"),
    ("bodies.bal.radius_m=0.1", "no [[bodies]] table is named 'bal'; the names are 'ball'"),
    ("attachments.0.edge=left", "the scene has no [[attachments]] tables"),
    ("attachments.left.edge=left", "the scene has no [[attachments]] tables"),   # by a name, as by an index
    ("scene.seed", "expected KEY=VALUE"),
    ("scene..seed=1", "a dotted path of names"),
    ("cloth.spacing_m=-1", "[cloth] spacing_m = -1"),
    ("time.step_s=nan", "[time] step_s = nan"),
])
def test_bad_set_exits_2_naming_it(arg, needle, scene, capsys):
    assert main(["check", str(scene), "--set", arg]) == 2
    err = capsys.readouterr().err
    assert needle in err and "Traceback" not in err, err
    if "=" in arg and ".." not in arg and "does not exist" not in needle and "no [[" not in needle:
        assert "--set" in err  # the message says the value came from the command line


def test_the_message_echoes_each_set_as_toml_so_it_can_be_given_again(scene, capsys):
    """A bare word, a boolean and an array given with --set read back in TOML (not Python's 'abc', True)."""
    assert main(["check", str(scene), "--set", "cloth.tearing.break_strain=abc", "--set", "cloth.tearing.enabled=true",
                 "--set", "world.gravity_m_s2=[0.0, -1.0, 0.0]"]) == 2
    err = capsys.readouterr().err
    assert ('(with --set cloth.tearing.break_strain="abc", cloth.tearing.enabled=true, '
            "world.gravity_m_s2=[0.0, -1.0, 0.0])") in err, err


def test_set_reaches_simulate_and_render(scene, tmp_path, capsys):
    import json

    assert main(["simulate", str(scene), "-o", str(tmp_path / "a"), "--frames", "2", "--json",
                 "--set", "cloth.tearing.enabled=true"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert "pieces" in out  # only a tearing scene reports pieces
    assert main(["render", str(scene), "-o", str(tmp_path / "b"), "--frames", "0:1", "--resolution", "32x24",
                 "--set", "scene.name=renamed"]) == 0
    assert (tmp_path / "b" / "renamed_000000-000001.mp4").is_file()


def test_the_solver_revision_is_part_of_the_scene_hash(monkeypatch):
    """Frames simulated by an older solver (another SIM_REVISION) do not match the scene any more, so
    they are simulated again instead of resumed or reused."""
    import fraytool.scene.load as load

    spec = load_scene("drape")
    before = scene_hash(spec)
    monkeypatch.setattr(load, "SIM_REVISION", load.SIM_REVISION + 1)
    assert scene_hash(spec) != before
