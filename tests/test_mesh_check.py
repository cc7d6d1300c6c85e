"""`fraytool check` describes each mesh body (triangles, welded vertices, closed or open, sharp edges, bounds,
a sequence's keys and files), warns of an open mesh, names a non-finite vertex as the file numbers it, and
reads a sequence numbered from anywhere with `sequence_start_s` (docs/meshes.md)."""
from __future__ import annotations

import json

import numpy as np
import pytest

from fraytool.commands.main import main
from fraytool.meshes import MeshTable
from fraytool.scene import load_scene
from fraytool.sim.builder import build_model
from test_mesh_bodies import SCENE as BASE_SCENE

trimesh = pytest.importorskip("trimesh")

SCENE = BASE_SCENE + """scale = [{scale}, {scale}, {scale}]
{extra}
"""


def _scene(tmp_path, file, scale=1.0, extra=""):
    path = tmp_path / "s.toml"
    path.write_text(SCENE.format(file=file, scale=scale, extra=extra))
    return path


def _check(path, capsys):
    code = main(["check", str(path), "--json"])
    captured = capsys.readouterr()
    return code, json.loads(captured.out), captured.err


def test_check_describes_a_closed_box_after_welding_and_scale(tmp_path, capsys):
    # a unit box written with split vertices (24: one per face corner, as for normals): 8 after welding
    box = trimesh.creation.box(extents=(1.0, 2.0, 4.0))
    faces = box.faces
    split_v = box.vertices[faces.reshape(-1)]
    split_f = np.arange(split_v.shape[0]).reshape(-1, 3)
    trimesh.Trimesh(split_v, split_f, process=False).export(tmp_path / "box.obj")
    code, info, err = _check(_scene(tmp_path, "box.obj", scale=0.1), capsys)
    assert code == 0
    [mesh] = info["mesh_bodies"]
    assert (mesh["triangles"], mesh["vertices"], mesh["closed"], mesh["border_edges"]) == (12, 8, True, 0)
    assert mesh["sharp_edges"] == 12  # the 12 edges of a box turn by 90 degrees; the face diagonals by 0
    lo, hi = np.array(mesh["bounds_m"])
    assert np.allclose(lo, (-0.05, -0.2, -0.2)) and np.allclose(hi, (0.05, 0.0, 0.2))  # scaled, then placed
    assert "open" not in err
    main(["check", str(tmp_path / "s.toml")])
    text = capsys.readouterr().out
    assert "mesh body 0 thing (box.obj): 12 triangles, 8 vertices after welding, closed, 12 sharp edges" in text


def test_an_obj_cut_off_in_its_face_list_is_an_open_mesh_warning(tmp_path, capsys):
    sphere = trimesh.creation.icosphere(subdivisions=2, radius=0.05)
    sphere.export(tmp_path / "whole.obj")
    lines = (tmp_path / "whole.obj").read_text().splitlines()
    faces = [i for i, ln in enumerate(lines) if ln.startswith("f ")]
    cut = faces[int(0.83 * len(faces))]
    (tmp_path / "cut.obj").write_text("\n".join(lines[:cut]) + "\n")  # 17 % of the faces gone
    code, info, err = _check(_scene(tmp_path, "whole.obj"), capsys)
    assert info["mesh_bodies"][0]["closed"] and "open" not in err
    code, info, err = _check(_scene(tmp_path, "cut.obj"), capsys)
    assert code == 0
    [mesh] = info["mesh_bodies"]
    assert not mesh["closed"] and mesh["triangles"] == len(faces) - (len(faces) - int(0.83 * len(faces)))
    assert mesh["border_edges"] > 0
    warnings = [ln for ln in err.splitlines() if "warning" in ln]
    assert len(warnings) == 1, err
    assert f"open ({mesh['border_edges']} border edges)" in warnings[0]
    assert "two-sided" in warnings[0] and "no push-out" in warnings[0] and "[bodies.0]" in warnings[0]


def test_a_non_finite_vertex_is_named_by_its_number_in_the_obj(tmp_path):
    # texture coordinates make trimesh split and reorder the vertices: its index would be 7, the file's is 5
    text = ("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nv 1 1 nan\nv 2 2 2\nvt 0 0\nvt 1 0\nvt 0 1\n"
            "f 4/1 5/2 6/3\nf 1/1 2/2 3/3\nf 1/2 3/3 4/1\nf 2/1 4/2 5/3\n")
    (tmp_path / "m.obj").write_text(text)
    import subprocess
    import sys

    run = subprocess.run([sys.executable, "-m", "fraytool", "check", str(_scene(tmp_path, "m.obj"))],
                         capture_output=True, text=True)
    assert run.returncode == 2
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1 and "vertex 5 (line 5" in lines[0] and "[bodies.0]" in lines[0], run.stderr


def _walk(tmp_path, first=1001, count=4):
    box = trimesh.creation.box(extents=(0.02, 0.02, 0.02))
    for k in range(count):
        moved = box.copy()
        moved.apply_translation((0.01 * k, 0.0, 0.0))
        moved.export(tmp_path / f"walk.{first + k}.obj")


def test_a_sequence_numbered_from_1001_with_its_first_file_before_time_0(tmp_path, capsys):
    _walk(tmp_path)
    scene = _scene(tmp_path, "walk.####.obj", extra="frame_time_s = 0.25\nsequence_start_s = -0.5\n")
    code, info, err = _check(scene, capsys)
    assert code == 0, err
    [mesh] = info["mesh_bodies"]
    assert (mesh["keys"], mesh["first_file"], mesh["last_file"]) == (4, "walk.1001.obj", "walk.1004.obj")
    assert mesh["first_key_s"] == -0.5 and mesh["duration_s"] == 0.75
    assert mesh["file_at_time_0"] == "walk.1003.obj"
    # and the simulation sees that file at time 0: x moved by 2 x 0.01 m
    model = build_model(load_scene(scene))
    assert MeshTable(model).vertices_at(0, 0.0).mean(axis=0)[0] == pytest.approx(0.02, abs=1e-12)
    main(["check", str(scene)])
    assert "walk.1001.obj .. walk.1004.obj, walk.1003.obj at 0 s" in capsys.readouterr().out


def test_between_two_files_and_after_start_s(tmp_path, capsys):
    _walk(tmp_path)
    scene = _scene(tmp_path, "walk.####.obj", extra="frame_time_s = 0.25\nsequence_start_s = -0.6\n")
    assert _check(scene, capsys)[1]["mesh_bodies"][0]["file_at_time_0"] == "between walk.1003.obj and walk.1004.obj"
    scene = _scene(tmp_path, "walk.####.obj", extra="frame_time_s = 0.25\nsequence_start_s = 0.5\nstart_s = 0.25\n")
    info = _check(scene, capsys)[1]["mesh_bodies"][0]
    assert info["first_key_s"] == 0.75 and info["file_at_time_0"].startswith("walk.1001.obj (held until 0.75 s)")


def test_sequence_start_s_is_for_meshes(tmp_path, capsys):
    path = tmp_path / "s.toml"
    path.write_text(SCENE.format(file="x", scale=1.0, extra="").replace('shape = "mesh"\nfile = "x"', 'shape = "sphere"\n'
                    'radius_m = 0.02').replace("scale = [1.0, 1.0, 1.0]", "sequence_start_s = 1.0"))
    assert main(["check", str(path)]) == 2
    err = capsys.readouterr().err
    assert "sequence_start_s" in err and "is for meshes" in err
