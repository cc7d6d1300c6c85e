"""Each class of bad scene input gives one clear message (file, key, value, what is allowed) and
exit code 2, never a traceback."""
import json
import re
import subprocess
from pathlib import Path
import sys

import pytest

from fraytool.commands.main import main
from helpers import small_scene_text

pytestmark = pytest.mark.fast  # `pytest -m fast` (docs/testing.md)

GOOD = small_scene_text()


def _with(old: str, new: str) -> str:
    assert old in GOOD
    return GOOD.replace(old, new)


_KINEMATIC = GOOD + '\n[[bodies]]\nname = "b"\nshape = "box"\nhalf_extents_m = [0.01, 0.01, 0.01]\nmotion = "kinematic"\n'
"""A kinematic box: keys of paths that turn go after it."""

CASES = {
    "unknown key": (GOOD.replace("[cloth]\n", "[cloth]\nwarp_yarn = 3\n"), ["[cloth] warp_yarn = 3", "unknown key", "warp_yarns"]),
    "unknown table": (GOOD + "\n[clothes]\nx = 1\n", ["[clothes]", "unknown table"]),
    "wrong type": (_with("spacing_m = 0.005", 'spacing_m = "5mm"'), ['[cloth] spacing_m = "5mm"', "a number"]),
    "zero spacing": (_with("spacing_m = 0.005", "spacing_m = 0.0"), ["[cloth] spacing_m = 0.0", ">= 1e-06"]),
    "negative mass": (_with("mass_per_crossing_kg = 2.0e-5", "mass_per_crossing_kg = -1.0"),
                      ["[cloth] mass_per_crossing_kg = -1.0", ">= 1e-12"]),
    "bad choice": (_with('weave = "plain"', 'weave = "knit"'), ['[cloth] weave = "knit"', '"plain"', '"twill"']),
    "bad twill": (_with('weave = "plain"', 'weave = "twill"\ntwill = "2-2"'), ['[cloth] twill = "2-2"', '"a/b"']),
    "missing key": (GOOD.replace("warp_yarns = 12\n", ""), ["[cloth]", "`warp_yarns` is missing or 0"]),
    "zero yarns": (_with("warp_yarns = 12\n", "warp_yarns = 0\n"), ["[cloth]", "`warp_yarns` is missing or 0",
                                                                    "a rectangle needs an integer >= 2"]),
    "yarns not a number": (_with("warp_yarns = 12\n", 'warp_yarns = "thirty"\n'),
                           ['[cloth] warp_yarns = "thirty"', "2 or more for a rectangle; 0 or left out"]),
    "misspelled sub-table": (GOOD + "\n[cloth.sprngs]\ndamping = 0.1\n", ["did you mean springs?"]),
    "missing table": (GOOD.split("[cloth.springs]")[0], ["[cloth.springs]", "missing required table"]),
    "vector length": (_with("origin_m = [-0.03, 0.1, -0.03]", "origin_m = [0.0, 0.1]"), ["[cloth] origin_m = [0.0, 0.1]", "3 numbers"]),
    "unknown body": (GOOD + '\n[[attachments]]\nbody = "ghost"\nedge = "left"\n', ['[attachments.0] body = "ghost"', "must name one of"]),
    "step above bound": (_with("step_s = 0.0004", "step_s = 0.01\nstability = \"refuse\""),
                         ["[time] step_s = 0.01", "stability bound", "use step_s <="]),
    "not toml": ("[cloth\nx=1", ["not valid TOML"]),
    "nan keyframe": (GOOD + '\n[[bodies]]\nname = "b"\nshape = "sphere"\nradius_m = 0.01\nmotion = "kinematic"\n'
                     'path = [[0.0, 0.0, 0.0, 0.0], [nan, 0.1, 0.0, 0.0]]\n', ["[bodies.0] path", "finite numbers"]),
    "damper without compliant limit": (_with("max_iterations = 30", "max_iterations = 30\ndamping_ratio = 1.0"),
                                       ["[cloth.strain] damping_ratio = 1.0", "needs stiffness_n_per_m > 0"]),
    "tiny step": (_with("step_s = 0.0004", "step_s = 5e-324"), ["[time] step_s = 5e-324", ">= 1e-09"]),
    "tiny fps": (_with("fps = 24\n", "fps = 1e-300\n"), ["[time] fps = 1e-300", ">= 1"]),
    "huge seed": (_with("seed = 1\n", "seed = 18446744073709551616\n"), ["[scene] seed = 18446744073709551616", "<= 9.22337e+18"]),
    "huge origin": (_with("origin_m = [-0.03, 0.1, -0.03]", "origin_m = [1e300, 0.1, -0.03]"),
                    ["[cloth] origin_m = [1e+300, 0.1, -0.03]", "each >= -10000 and <= 10000"]),
    "tiny mass": (_with("mass_per_crossing_kg = 2.0e-5", "mass_per_crossing_kg = 1e-320"),
                  ["[cloth] mass_per_crossing_kg = 1e-320", ">= 1e-12"]),
    "tiny spacing": (_with("spacing_m = 0.005", "spacing_m = 1e-300"), ["[cloth] spacing_m = 1e-300", ">= 1e-06"]),
    "integer too large for a float": (_with("seed = 1\n", "seed = 1" + "0" * 309 + "\n"), ["[scene] seed = 1000"]),
    "integer too long to parse": (_with("seed = 1\n", "seed = 1" + "0" * 5000 + "\n"), ["not valid TOML"]),
    "key nested too deeply": (GOOD + "\n" + ".".join(["a"] * 20000) + " = 1\n", ["nested 20000 levels deep"]),
    "path far away": (GOOD + '\n[[bodies]]\nname = "b"\nshape = "sphere"\nradius_m = 0.01\nmotion = "kinematic"\n'
                      'path = [[0.0, 0.0, 0.0, 0.0], [0.01, 1e300, 0.2, 0.0]]\n', ["[bodies.0] path", "positions"]),
    "orientation keys out of order": (_KINEMATIC + 'path_rotation_deg = [[0.1, 0.0, 0.0, 0.0], [0.05, 0.0, 90.0, 0.0]]\n',
                                      ["[bodies.0] path_rotation_deg", "times from 0 to 1e6 s and increasing"]),
    "zero quaternion": (_KINEMATIC + 'path_quaternion = [[0.0, 1.0, 0.0, 0.0, 0.0], [0.1, 0.0, 0.0, 0.0, 0.0]]\n',
                        ["[bodies.0] path_quaternion", "quaternions (w, x, y, z) of norm at least 1e-6"]),
    "quaternion key of 4 numbers": (_KINEMATIC + 'path_quaternion = [[0.0, 1.0, 0.0, 0.0]]\n',
                                    ["[bodies.0] path_quaternion", "[t, w, x, y, z]"]),
    "euler and quaternion keys": (_KINEMATIC + 'path_rotation_deg = [[0.0, 0.0, 0.0, 0.0]]\n'
                                  'path_quaternion = [[0.0, 1.0, 0.0, 0.0, 0.0]]\n',
                                  ["[bodies.0] path_quaternion", "give path_rotation_deg (Euler angles) or "
                                   "path_quaternion, not both"]),
    "orientation keys on a static body": (_KINEMATIC.replace('motion = "kinematic"\n', "")
                                          + 'path_rotation_deg = [[0.0, 0.0, 0.0, 0.0]]\n',
                                          ["[bodies.0] path_rotation_deg", 'need motion = "kinematic"']),
    "orientation keys with rotation_deg": (_KINEMATIC + 'rotation_deg = [0.0, 30.0, 0.0]\n'
                                           'path_rotation_deg = [[0.0, 0.0, 0.0, 0.0]]\n',
                                           ["[bodies.0] rotation_deg = [0.0, 30.0, 0.0]", "key it there"]),
    "catmull_rom on one key": (_KINEMATIC + 'interpolation = "catmull_rom"\npath = [[0.0, 0.0, 0.1, 0.0]]\n',
                               ["[bodies.0] path = [[0.0, 0.0, 0.1, 0.0]]", 'at least 2 keys with interpolation']),
    "catmull_rom without keys": (_KINEMATIC + 'interpolation = "catmull_rom"\n',
                                 ['[bodies.0] interpolation = "catmull_rom"', "is for path and orientation keys"]),
    "unknown interpolation": (_KINEMATIC + 'interpolation = "cubic"\n',
                              ['[bodies.0] interpolation = "cubic"', '"linear", "catmull_rom"']),
    "radius on a plane": (GOOD + '\n[[bodies]]\nname = "floor"\nshape = "plane"\nradius_m = 0.02\n',
                          ["[bodies.0] radius_m = 0.02", "is for spheres; a plane does not use it"]),
    "half extents on a sphere": (GOOD + '\n[[bodies]]\nname = "b"\nshape = "sphere"\nradius_m = 0.01\n'
                                 'half_extents_m = [0.01, 0.01, 0.01]\n',
                                 ["[bodies.0] half_extents_m = [0.01, 0.01, 0.01]", "is for boxes; a sphere"]),
    "cut outside the cloth": (GOOD + "\n[[cuts]]\nstart = [3.5, 100.0]\nend = [3.5, 2.0]\n",
                              ["[cuts.0] start = [3.5, 100.0]", "-1 <= j <="]),
    "weave table of booleans": (_with('weave = "plain"', 'weave = "table"\ntable = [[true, false], [false, true]]'),
                                ["[cloth] table = [[true, false], [false, true]]", "integers 0 and 1",
                                 "not true / false"]),
    "normal on a sphere": (GOOD + '\n[[bodies]]\nname = "b"\nshape = "sphere"\nradius_m = 0.01\nnormal = [1.0, 0.0, 0.0]\n',
                           ["[bodies.0] normal = [1.0, 0.0, 0.0]", "is for planes; a sphere does not use it"]),
    "non-finite wind": (_with("gravity_m_s2 = [0.0, -9.81, 0.0]", "gravity_m_s2 = [0.0, -9.81, 0.0]\nwind_m_s = [nan, 0.0, 0.0]"),
                        ["[world] wind_m_s = [NaN, 0.0, 0.0]", ">= -1000"]),
    "negative drag": (_with('weave = "plain"', 'weave = "plain"\ndrag_normal = -1.0'),
                      ["[cloth] drag_normal = -1.0", ">= 0"]),
    "gust length zero": (_with("gravity_m_s2 = [0.0, -9.81, 0.0]",
                               "gravity_m_s2 = [0.0, -9.81, 0.0]\ngust_strength_m_s = 1.0\ngust_length_m = 0.0"),
                         ["[world] gust_length_m = 0.0", ">= 0.0001"]),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_bad_scene_gives_clear_error_and_exit_2(case, tmp_path, capsys):
    text, expected = CASES[case]
    path = tmp_path / "bad.toml"
    path.write_text(text)
    code = main(["check", str(path)])
    err = capsys.readouterr().err
    assert code == 2, err
    assert str(path) in err
    assert len(err.splitlines()) == 1, err  # one line per problem
    for fragment in expected:
        assert fragment in err, f"{fragment!r} not in {err!r}"
    assert "Traceback" not in err


def test_step_above_bound_warns_by_default(tmp_path, capsys):
    path = tmp_path / "warn.toml"
    path.write_text(_with("step_s = 0.0004", "step_s = 0.01"))
    assert main(["check", str(path)]) == 0
    err = capsys.readouterr().err
    assert "warning" in err and "[time] step_s = 0.01" in err and "stability bound" in err


def test_missing_file_and_bad_flag_exit_2(tmp_path, capsys):
    assert main(["simulate", str(tmp_path / "nope.toml")]) == 2
    assert "scene file not found" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exc:
        main(["simulate", "drape", "--frames", "-3"])
    assert exc.value.code == 2
    with pytest.raises(SystemExit) as exc:
        main(["simulate", "drape", "--frames", "99999999999999999999"])
    assert exc.value.code == 2
    assert "at most 1000000" in capsys.readouterr().err


def test_cli_subprocess_prints_no_traceback(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text(_with("spacing_m = 0.005", "spacing_m = -2"))
    r = subprocess.run([sys.executable, "-m", "fraytool", "simulate", str(path)], capture_output=True, text=True,
                       stdin=subprocess.DEVNULL)
    assert r.returncode == 2
    assert "Traceback" not in r.stderr and "spacing_m = -2" in r.stderr


@pytest.mark.parametrize("name", ["/tmp/somewhere", "../../x", "..", ".", ".hidden", "a/b", "a\x00b", "x" * 101, ""])
def test_scene_name_is_a_name_never_a_path(name, tmp_path, capsys):
    text = re.sub(r'(?m)^name = ".*"$', lambda _: "name = " + json.dumps(name), GOOD, count=1)
    assert text != GOOD
    path = tmp_path / "scene.toml"
    path.write_text(text)
    code = main(["simulate", str(path), "-o", str(tmp_path / "out"), "--frames", "2"])
    err = capsys.readouterr().err
    if name == "":  # empty: the file name is the scene name
        assert code == 0, err
        return
    assert code == 2, err
    assert "[scene] name" in err and "never a path" in err
    assert not (tmp_path / "out").exists()


def test_a_foreign_frames_folder_survives(tmp_path, capsys):
    path = tmp_path / "scene.toml"
    path.write_text(GOOD)
    out = tmp_path / "out"
    (out / "frames").mkdir(parents=True)
    (out / "frames" / "precious.txt").write_text("not fraytool's")
    code = main(["simulate", str(path), "-o", str(out), "--frames", "2"])
    err = capsys.readouterr().err
    assert code == 1, err  # an output problem, not bad input
    assert "did not write" in err and "precious" not in err
    assert (out / "frames" / "precious.txt").read_text() == "not fraytool's"
    (out / "frames" / "precious.txt").unlink()
    (out / "frames").rmdir()
    (out / "frames").write_text("a file in the way")
    code = main(["simulate", str(path), "-o", str(out), "--frames", "2"])
    err = capsys.readouterr().err
    assert code == 1 and "in the way" in err, err
    assert (out / "frames").read_text() == "a file in the way"


def test_scene_text_the_parser_chokes_on_exits_2(tmp_path, capsys):
    latin1 = tmp_path / "latin1.toml"
    latin1.write_bytes(GOOD.encode() + "\n# caf\xe9\n".encode("latin-1"))
    assert main(["check", str(latin1)]) == 2
    err = capsys.readouterr().err
    assert "not UTF-8" in err and "0xe9" in err and "Traceback" not in err
    nested = tmp_path / "nested.toml"
    nested.write_text("x = " + "[" * 5000 + "]" * 5000 + "\n")
    assert main(["check", str(nested)]) == 2
    err = capsys.readouterr().err
    assert "nested too deeply" in err and "Traceback" not in err


def test_a_huge_value_is_not_echoed_whole(tmp_path, capsys):
    path = tmp_path / "huge.toml"
    path.write_text(GOOD.replace("origin_m = [-0.03, 0.1, -0.03]", "origin_m = [" + ", ".join(["1.0"] * 100000) + "]"))
    assert main(["check", str(path)]) == 2
    err = capsys.readouterr().err
    assert "[cloth] origin_m = [1.0, 1.0" in err and "(100000 items)" in err
    assert max(len(line) for line in err.splitlines()) < 300


def test_echoed_values_are_cut_at_80_characters_and_lines_stay_under_200(tmp_path, capsys, monkeypatch):
    """A long string, a long array and an unknown key with a long value: each echoed value is cut at 80
    characters or fewer (with its size), one line per problem, under 200 characters (the explanation cut
    at a word, pointing at docs/scene-format.md, where a line would be longer)."""
    monkeypatch.chdir(tmp_path)
    path = Path("long.toml")
    for text in (_with('weave = "plain"', 'weave = "' + "x" * 300 + '"'),
                 _with('weave = "plain"', 'weave = "table"\ntable = [[' + ", ".join(["1"] * 150) + "], [0, 1]]"),
                 GOOD.replace("[cloth]\n", "[cloth]\nno_such_key = \"" + "y" * 300 + "\"\n")):
        path.write_text(text)
        assert main(["check", str(path)]) == 2
        err = capsys.readouterr().err
        lines = err.splitlines()
        assert len(lines) == 1 and len(lines[0]) < 200, err
        echoed = re.search(r"= (.*?)\.\.\. \((\d+) (characters|items)\)", err)
        assert echoed and len(echoed.group(1)) <= 80, err
    assert "no_such_key" in err and "unknown key; the keys of this table: docs/scene-format.md" in err \
        and "sub-tables: multires" in err and "did you mean" not in err  # nothing close to suggest


def test_a_scene_too_big_for_the_memory_is_refused_with_the_estimate(tmp_path, capsys, monkeypatch):
    from fraytool.sim.memory import estimate_bytes
    from fraytool.scene import load_scene

    path = tmp_path / "scene.toml"
    path.write_text(GOOD)
    need = estimate_bytes(load_scene(str(path)))
    monkeypatch.setenv("FRAYTOOL_AVAILABLE_MEMORY_BYTES", str(need - 1))
    for argv in (["check", str(path)], ["simulate", str(path), "-o", str(tmp_path / "out")],
                 ["render", str(path), "-o", str(tmp_path / "out")]):
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert "[cloth] warp_yarns x weft_yarns = 12 x 12" in err and "needs about" in err and "--force" in err
    assert not (tmp_path / "out").exists()
    assert main(["check", str(path), "--force"]) == 0
    monkeypatch.setenv("FRAYTOOL_AVAILABLE_MEMORY_BYTES", str(need))
    assert main(["check", str(path)]) == 0


def test_memory_estimate_grows_with_the_grid_and_with_tearing():
    from fraytool.scene import parse_scene
    from fraytool.sim.memory import BASE_BYTES, estimate_bytes
    from helpers import small_scene_text

    small = estimate_bytes(parse_scene(small_scene_text(nx=10, ny=10), "a.toml"))
    big = estimate_bytes(parse_scene(small_scene_text(nx=100, ny=100), "b.toml"))
    torn = estimate_bytes(parse_scene(small_scene_text(nx=100, ny=100) + "[cloth.tearing]\nenabled = true\n", "c.toml"))
    assert BASE_BYTES < small < big < torn
    assert (big - BASE_BYTES) == 100 * (small - BASE_BYTES)  # linear in the crossings


def test_an_unknown_key_in_a_table_with_sub_tables_lists_them(tmp_path, capsys):
    """A misspelled sub-table ([cloth.sprngs] via --set) names the real ones, so the user sees what was meant."""
    scene = tmp_path / "s.toml"
    scene.write_text(small_scene_text())
    assert main(["check", str(scene), "--set", "cloth.sprngs.bend_n_per_m=1"]) == 2
    err = capsys.readouterr().err
    assert "[cloth] sprngs" in err and "sub-tables: multires, springs, strain, tearing" in err
