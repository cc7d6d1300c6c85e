"""A studio's files at their worst (issue 50, "Loaders that survive a studio's files"): each input below is
one line naming the file or key and what is wrong, exit 2, nothing written, in seconds - never a hang, a
traceback, a MemoryError or an unstable run. Classes: hangs (a 2,000-point outline, FIFOs where files are
read), memory (a large second panel, stitches 1e-9 m apart), tracebacks (an image header claiming 20,000 x
20,000 pixels, a wrap radius that folds neighbours together, a USD Mesh without points, damaged goldens),
wrong exits (a quaternion of norm 1e-200, panels 10 m apart sewn, a mesh file name over 255 bytes)."""
from __future__ import annotations

import json
import math
import os
import shutil
import struct
import subprocess
import sys
import zlib
from pathlib import Path

import numpy as np
import pytest

from test_seams import HEAD, PANEL, TEARING, seam
from test_tear_control import SCENE as TC_SCENE

pytestmark = pytest.mark.fast  # bad input: `pytest -m fast`

TESTS = Path(__file__).resolve().parent
LIMIT_S = 60


def fraytool(*args, cwd=None, env=None):
    return subprocess.run([sys.executable, "-m", "fraytool", *map(str, args)], capture_output=True, text=True,
                          cwd=cwd, env=env, stdin=subprocess.DEVNULL, timeout=LIMIT_S)


def one_line_exit_2(run, *needles):
    lines = [ln for ln in run.stderr.strip().splitlines() if ln.strip() and "warning" not in ln]
    assert run.returncode == 2, run.stderr
    assert len(lines) == 1, run.stderr
    assert "Traceback" not in run.stderr
    for needle in needles:
        assert needle in lines[0], lines[0]
    return lines[0]


def tc_scene(tmp_path, cloth="", extra=""):
    path = tmp_path / "s.toml"
    path.write_text(TC_SCENE.format(cloth=cloth, n=16, spread=0.02, seed=1, frames=2) + extra)
    return path


def image_scene(tmp_path, key):
    """The scene with map.png as its mask (the shape sets the grid) or as its tear map."""
    if key == "mask":
        scene = tc_scene(tmp_path, cloth='mask = "map.png"\nmask_size_m = [0.06, 0.06]')
        scene.write_text(scene.read_text().replace("warp_yarns = 16\nweft_yarns = 16\n", ""))
        return scene
    return tc_scene(tmp_path, cloth='tear_map = "map.png"\ntear_map_strain = [0.15, 0.3]')


def simulate_refused(tmp_path, scene, *needles, env=None):
    out = tmp_path / "out"
    line = one_line_exit_2(fraytool("simulate", scene, "-o", out, "--progress", "none", env=env), *needles)
    assert not out.exists(), "nothing is written for bad input"
    return line


# -- hangs --------------------------------------------------------------------------------------------------

def star_outline(points, radius=0.03, cross=False):
    t = np.linspace(0.0, 2.0 * math.pi, points, endpoint=False)
    r = radius * (1.0 + 0.02 * np.sin(37 * t))
    p = np.stack([r * np.cos(t) + radius, r * np.sin(t) + radius], axis=1)
    if cross:
        p[[100, 1100]] = p[[1100, 100]]  # two far corners swapped: edges across the panel
    return "outline_m = [" + ", ".join(f"[{u:.9g}, {v:.9g}]" for u, v in p) + "]"


def test_a_2000_point_outline_that_crosses_itself_is_refused_in_seconds(tmp_path):
    scene = tc_scene(tmp_path, cloth=star_outline(2000, cross=True)).read_text()
    scene = scene.replace("warp_yarns = 16\nweft_yarns = 16\n", "")
    (tmp_path / "s.toml").write_text(scene)
    simulate_refused(tmp_path, tmp_path / "s.toml", "outline_m", "cross")


@pytest.mark.parametrize("key", ["mask", "tear_map"])
def test_a_fifo_where_an_image_is_read_is_refused(tmp_path, key):
    os.mkfifo(tmp_path / "map.png")
    simulate_refused(tmp_path, image_scene(tmp_path, key), key, "FIFO")


def test_a_fifo_for_a_frame_or_the_manifest_is_named_not_waited_on(tmp_path):
    from fraytool.sim.run import simulate_to_disk
    from helpers import small_scene
    import io

    out = tmp_path / "shot"
    simulate_to_disk(small_scene(frames=4), out, frames=4, progress=False, stream=io.StringIO())
    frame = out / "frames" / "frame_000002.npz"
    frame.unlink()
    os.mkfifo(frame)
    run = fraytool("check", "--outputs", out)
    assert run.returncode == 1 and "frame_000002.npz" in run.stderr and "FIFO" in run.stderr, run.stderr
    (out / "frames" / "manifest.json").unlink()
    os.mkfifo(out / "frames" / "manifest.json")
    run = fraytool("check", "--outputs", out)
    assert run.returncode == 1 and "manifest" in run.stderr and "Traceback" not in run.stderr, run.stderr


# -- memory -------------------------------------------------------------------------------------------------

def two_panels(b_origin=(0.044, 0.0, 0.0), b_size=(10, 8), seams=""):
    text = HEAD.format(frames=2) + PANEL.format(name="a", origin=[0.0, 0.0, 0.0], w=10, h=8, mass=5e-6,
                                                weave="plain", extra="") + TEARING
    return text + PANEL.format(name="b", origin=list(b_origin), w=b_size[0], h=b_size[1], mass=5e-6, weave="plain",
                               extra="") + seams


def test_a_large_second_panel_counts_in_the_memory_estimate(tmp_path):
    (tmp_path / "s.toml").write_text(two_panels(b_size=(2000, 2000)))
    env = dict(os.environ, FRAYTOOL_AVAILABLE_MEMORY_BYTES=str(2 * 2**30))
    simulate_refused(tmp_path, tmp_path / "s.toml", "[cloth.1]", "b", "4000000 crossings", "--force", env=env)


def test_stitches_a_nanometre_apart_are_refused_before_they_are_placed(tmp_path):
    (tmp_path / "s.toml").write_text(two_panels(seams=seam(spacing=1e-9)))
    simulate_refused(tmp_path, tmp_path / "s.toml", "[seams.0]", "stitch_spacing_m = 1e-09")


# -- tracebacks ---------------------------------------------------------------------------------------------

def png_header_only(width, height):
    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)) + \
        chunk(b"IEND", b"")


@pytest.mark.parametrize("key", ["mask", "tear_map"])
def test_an_image_header_claiming_20000_pixels_square_is_refused(tmp_path, key):
    (tmp_path / "map.png").write_bytes(png_header_only(20000, 20000))
    simulate_refused(tmp_path, image_scene(tmp_path, key), key, "20000 x 20000")


def test_a_wrap_radius_that_folds_neighbours_together_is_refused(tmp_path):
    radius = 0.004 / (2.0 * math.pi)  # one spacing is a full turn: neighbours on one point
    simulate_refused(tmp_path, tc_scene(tmp_path, cloth=f"wrap_radius_m = {radius!r}"), "wrap_radius_m",
                     "four crossings round")


def test_a_usd_mesh_without_points_is_refused(tmp_path):
    pytest.importorskip("pxr")
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.CreateNew(str(tmp_path / "body.usda"))
    mesh = UsdGeom.Mesh.Define(stage, "/Root/Body")
    mesh.CreateFaceVertexCountsAttr([3])
    mesh.CreateFaceVertexIndicesAttr([0, 1, 2])
    stage.Save()
    body = '[[bodies]]\nname = "body"\nshape = "mesh"\nfile = "body.usda"\nprim = "/Root/Body"\n'
    simulate_refused(tmp_path, tc_scene(tmp_path, extra=body), "[bodies.0]", "has no points")


@pytest.fixture(scope="module")
def golden_folder(tmp_path_factory):
    root = tmp_path_factory.mktemp("golden")
    run = fraytool("golden", "update", TESTS / "scenes" / "golden_small.toml", "--dir", root / "g", "--work",
                   root / "w", "--threads", "1")
    assert run.returncode == 0, run.stderr
    return root


def _damage(folder: Path, case: str) -> None:
    meta_path = folder / "golden.json"
    meta = json.loads(meta_path.read_text())
    frame = meta["frames"][0]["frame"]
    png, npz = folder / f"frame_{frame:06d}.png", folder / f"yarns_{frame:06d}.npz"
    if case == "damaged png":
        data = bytearray(png.read_bytes())
        png.write_bytes(bytes(data[:len(data) // 2]))
    elif case == "json of the wrong shape":
        meta_path.write_text(json.dumps([1, 2, 3]))
    elif case == "json of the wrong types":
        meta["frames"][0]["frame"] = "zero"
        meta_path.write_text(json.dumps(meta))
    elif case == "empty npz":
        npz.write_bytes(b"")
    elif case == "truncated npz":
        npz.write_bytes(npz.read_bytes()[:100])
    elif case == "npz of the wrong shape":
        np.savez(npz, points_m=np.zeros((5, 2)), offsets=np.array([0, 5]))
    elif case == "frame 1000000":
        meta["frames"].append({"frame": 1_000_000, "torn_springs": 0})
        meta_path.write_text(json.dumps(meta))
    elif case == "json is a FIFO":
        meta_path.unlink()
        os.mkfifo(meta_path)


@pytest.mark.parametrize("case", ["damaged png", "json of the wrong shape", "json of the wrong types", "empty npz",
                                  "truncated npz", "npz of the wrong shape", "frame 1000000", "json is a FIFO"])
def test_a_damaged_golden_folder_is_one_line(golden_folder, tmp_path, case):
    g = tmp_path / "g"
    shutil.copytree(golden_folder / "g", g, symlinks=True)
    _damage(next(p for p in g.iterdir() if p.is_dir()), case)
    run = fraytool("golden", "check", TESTS / "scenes" / "golden_small.toml", "--dir", g, "--work",
                   golden_folder / "w")
    line = one_line_exit_2(run, "golden", "damaged")
    if case == "frame 1000000":
        assert "frame 1000000" in line


# -- wrong exits --------------------------------------------------------------------------------------------

def test_quaternion_keys_whose_norm_underflows_are_refused(tmp_path):
    body = ('[[bodies]]\nname = "bar"\nshape = "box"\nhalf_extents_m = [0.01, 0.01, 0.01]\nmotion = "kinematic"\n'
            'path_quaternion = [[0.0, 1e-200, 0.0, 0.0, 0.0], [1.0, 1.0, 0.0, 0.0, 0.0]]\n')
    simulate_refused(tmp_path, tc_scene(tmp_path, extra=body), "path_quaternion", "norm at least 1e-6")


def test_a_seam_between_panels_10_m_apart_is_refused(tmp_path):
    (tmp_path / "s.toml").write_text(two_panels(b_origin=(10.0, 0.0, 0.0), seams=seam()))
    simulate_refused(tmp_path, tmp_path / "s.toml", "[seams.0]", "too far apart to sew")


def test_a_mesh_file_name_over_255_bytes_is_the_meshes_problem(tmp_path):
    name = "m" * 300 + ".obj"
    body = f'[[bodies]]\nname = "thing"\nshape = "mesh"\nfile = "{name}"\n'
    line = simulate_refused(tmp_path, tc_scene(tmp_path, extra=body), "[bodies.0]", "file")
    assert "too long" in line and "output" not in line.lower()


def test_a_fifo_where_the_folders_lock_goes_is_named_not_waited_on(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    os.mkfifo(out / ".fraytool.lock")
    run = fraytool("simulate", tc_scene(tmp_path), "-o", out, "--progress", "none")
    assert run.returncode == 1 and "FIFO" in run.stderr and ".fraytool.lock" in run.stderr, run.stderr
    assert "Traceback" not in run.stderr and (out / ".fraytool.lock").exists()


def test_render_options_of_the_wrong_kind_are_input_errors(tmp_path):
    from fraytool import api
    from fraytool.errors import InputError

    with pytest.raises(InputError, match="--wireframe 'besides'"):
        api.render(tc_scene(tmp_path), out_dir=tmp_path / "o", png=True, wireframe="besides")
    with pytest.raises(InputError, match="--fov '30'"):
        api.render(tc_scene(tmp_path), out_dir=tmp_path / "o", png=True, fov="30")
    assert not (tmp_path / "o").exists()
