"""A Model built or edited in Python goes to disk, renders, exports and resumes without a scene file
(issue 35 item 4; fraytool.api, fraytool.sim.run.simulate_to_disk(model=...), docs/usage.md)."""
from __future__ import annotations

import dataclasses
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from fraytool.io.frame_store import FrameStore
from fraytool.scene import load_scene, scene_hash
from fraytool.scene.spec_io import spec_from_json, spec_to_json
from fraytool.sim import Model, Simulation, build_model
from fraytool.sim.run import load_shot, simulate_to_disk

from helpers import assert_arrays_equal, pulled_strip_text

ROOT = Path(__file__).resolve().parent.parent
SHIPPED = sorted(p.stem for p in (ROOT / "scenes").glob("*.toml"))


def _cli(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "fraytool", *map(str, args)], capture_output=True, text=True,
                          cwd=cwd, stdin=subprocess.DEVNULL, timeout=600)


def _strip(tmp_path: Path, frames: int = 8):
    """The pulled strip as a scene file in tmp_path (so that the test can delete it)."""
    text = pulled_strip_text("py_strip", yarn_level=True).replace("frames = 40", f"frames = {frames}")
    path = tmp_path / "py_strip.toml"
    path.write_text(text)
    return path, load_scene(path)


def _unplaced(spec):
    """The spec without where it was read from (a scene record keeps neither)."""
    return dataclasses.replace(spec, source="", source_file="")


def _weakened(spec) -> Model:
    """The scene's Model with the break strain of the springs around the strip's middle (x = 46 mm)
    lowered to 0.6 x: an edit no scene key makes."""
    model = build_model(spec)
    x = model.crossing_rest_position_m
    middle = 0.5 * (x[model.spring_crossing_a] + x[model.spring_crossing_b])
    model.spring_break_strain[np.abs(middle[:, 0] - 0.046) < 0.003] *= 0.6
    return model


@pytest.mark.parametrize("name", SHIPPED)
def test_every_shipped_scene_reads_back_from_its_json(name):
    spec = load_scene(name)
    assert spec_from_json(spec_to_json(spec)) == _unplaced(spec)


def test_a_damaged_scene_record_is_named():
    with pytest.raises(ValueError, match="cloth.springs: unknown field"):
        spec_from_json(spec_to_json(load_scene("drape")).replace('"damping"', '"dumping"'))
    with pytest.raises(ValueError, match="version"):
        spec_from_json('{"spec": {}}')


@pytest.mark.parametrize("name", ["seam_rip", "mannequin_snag", "fig7_square_grab"])
def test_a_model_reads_back_from_its_arrays(name):
    """Every field, names and per-body paths too, bit for bit (panels, meshes, grips)."""
    model = build_model(load_scene(name))
    back = Model.from_arrays(model.arrays())
    for f in dataclasses.fields(Model):
        a, b = getattr(model, f.name), getattr(back, f.name)
        if isinstance(a, np.ndarray):
            assert a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes(), f.name
        elif isinstance(a, tuple) and a and isinstance(a[0], np.ndarray):
            assert len(a) == len(b) and all(np.array_equal(p, q) for p, q in zip(a, b)), f.name
        else:
            assert a == b and type(a) is type(b), f.name
    assert back.digest() == model.digest()
    edited = Model.from_arrays(model.arrays())
    edited.spring_break_strain[0] *= 0.5
    assert edited.digest() != model.digest()


def test_an_edited_model_is_simulated_saved_and_resumed_without_its_scene_file(tmp_path):
    path, spec = _strip(tmp_path, frames=40)
    model = _weakened(spec)
    out = tmp_path / "shot"
    simulate_to_disk(spec, out, model=model, progress=False)
    # the frames are the edited model's: the same as stepping it in memory, and not the scene's own
    sim = Simulation(spec, model=model)
    expected = [sim.record()] + [sim.advance_frame() for _ in range(spec.time.frames - 1)]
    store = FrameStore(out)
    for rec in expected:
        assert_arrays_equal(rec.arrays(), store.load_frame(rec.frame).arrays())
    plain = Simulation(spec)
    for _ in range(spec.time.frames - 1):
        plain.advance_frame()
    assert plain.state.spring_broken.sum() != sim.state.spring_broken.sum()  # the edit tore it otherwise
    assert store.scene_hash() != scene_hash(spec)
    path.unlink()  # from here on, no scene file
    spec_back, model_back, digest = load_shot(out)
    assert _unplaced(spec_back) == _unplaced(spec) and digest == store.scene_hash()
    assert spec_back.source == str(store.dir / "topology.npz")
    assert np.array_equal(model_back.spring_break_strain, model.spring_break_strain)
    # a killed run: the last frames and the checkpoint gone; the render resumes it from the folder alone
    for f in (spec.time.frames - 2, spec.time.frames - 1):
        store.frame_path(f).unlink()
    (store.dir / "checkpoint.npz").unlink()
    r = _cli("render", out, "--no-mp4", "--png", "--resolution", "160x120")
    assert r.returncode == 0, r.stderr
    assert "re-simulating from frame 0" in r.stderr
    for rec in expected:
        assert_arrays_equal(rec.arrays(), store.load_frame(rec.frame).arrays())
    assert len(list((out / "png").glob("frame_*.png"))) == spec.time.frames


def test_the_python_api_renders_and_exports_a_folder(tmp_path):
    pytest.importorskip("pxr")
    from pxr import Usd

    from fraytool import api

    path, spec = _strip(tmp_path, frames=4)
    model = _weakened(spec)
    out = tmp_path / "api"
    api.simulate(spec, out, model=model, progress=False)
    path.unlink()
    assert api.render(out, png=True, video=False, resolution=(160, 120)) == out
    assert sorted(p.name for p in (out / "png").iterdir()) == [f"frame_{k:06d}.png" for k in range(4)]
    usd = api.export_usd(out, tmp_path / "api.usda")
    stage = Usd.Stage.Open(str(usd))
    assert stage.GetEndTimeCode() - stage.GetStartTimeCode() == 3


def test_a_folder_named_like_a_shipped_scene(tmp_path):
    """A folder in the working directory that holds no shot does not hide the shipped scene of its name
    (`simulate` never let it); a shot's folder of that name is the shot, and refusing --set there says how to
    name the shipped scene instead."""
    (tmp_path / "drape").mkdir()
    r = _cli("render", "drape", "--frames", "0:1", "--png", "--no-mp4", "--resolution", "160x90", "-o", "drape",
             cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "drape" / "png" / "frame_000000.png").is_file()
    r = _cli("render", "drape", "--set", "scene.seed=2", cwd=tmp_path)  # now ./drape is a shot
    assert r.returncode == 2 and "whose scene is fixed" in r.stderr and "give scenes/drape.toml" in r.stderr, r.stderr


def test_a_folder_refuses_set_and_an_old_folder_is_named(tmp_path):
    path, spec = _strip(tmp_path, frames=2)
    out = tmp_path / "shot"
    simulate_to_disk(spec, out, progress=False)
    r = _cli("render", out, "--set", "scene.seed=2")
    assert r.returncode == 2 and "whose scene is fixed" in r.stderr
    r = _cli("render", out, "--frames", "0:5")  # more frames than the shot has: not by --set here
    assert r.returncode == 2 and "the shot has 2 frames: for more, simulate its scene file again with --set " \
                                 "time.frames=5" in r.stderr, r.stderr
    r = _cli("export", tmp_path, "--usd", tmp_path / "x.usda")  # a folder, but no frames in it
    assert r.returncode == 2 and "a folder without simulated frames" in r.stderr
    # a folder written before the scene record existed: rewrite its topology without it
    store = FrameStore(out)
    topo = store.load_topology()
    topo.pop("scene_json")
    store._scene_hash = store.scene_hash()
    store.write_topology(topo)
    r = _cli("export", out, "--usd", tmp_path / "x.usda")
    assert r.returncode == 1 and "holds no scene record" in r.stderr, r.stderr


def test_a_scene_shot_folder_renders_as_its_scene(tmp_path):
    """Frames of a scene file (no model given) keep the scene's own digest, so the folder and the scene
    name the same frames; the folder holds the scene's own Model."""
    path, spec = _strip(tmp_path, frames=2)
    out = tmp_path / "shot"
    simulate_to_disk(spec, out, progress=False)
    spec_back, model, digest = load_shot(out)
    assert digest == scene_hash(spec) and _unplaced(spec_back) == _unplaced(spec)
    assert model.digest() == build_model(spec).digest()


def test_the_readme_python_example_runs(tmp_path):
    """The README's Python block, on 3 frames in a temporary folder."""
    block = re.search(r"## Python\n\n```python\n(.*?)```", (ROOT / "README.md").read_text(), re.S).group(1)
    assert 'load_scene("fig7_square_grab")' in block and "model=model" in block
    code = block.replace('load_scene("fig7_square_grab")', 'load_scene("fig7_square_grab", [("time.frames", 3)])') \
        .replace('api.render("outputs/weak_line", png=True)',
                 'api.render("outputs/weak_line", png=True, resolution=(160, 90))')
    pytest.importorskip("pxr")
    r = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    out = tmp_path / "outputs" / "weak_line"
    assert (out / "weak_line.usdc").is_file() and len(list((out / "png").glob("*.png"))) == 3
    spec, model, _ = load_shot(out)
    assert model is not None and (model.spring_break_strain < build_model(spec).spring_break_strain).any()


def test_the_usage_doc_python_example_runs(tmp_path):
    """docs/usage.md "A Model from Python, to disk", on 2 frames: the weak line and the edit reach the frames."""
    text = (ROOT / "docs" / "usage.md").read_text()
    block = re.search(r"### A Model from Python, to disk\n.*?```python\n(.*?)```", text, re.S).group(1)
    code = block.replace('load_scene("fig7_square_grab")', 'load_scene("fig7_square_grab", [("time.frames", 2)])') \
        .replace('"960x540"', '"160x90"')
    pytest.importorskip("pxr")
    r = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    spec, model, _ = load_shot(tmp_path / "outputs" / "mine")
    plain = build_model(spec)
    struct = plain.spring_kind == 0
    assert (model.spring_break_strain[struct] > plain.spring_break_strain[struct]).mean() > 0.9
    assert (tmp_path / "outputs" / "mine" / "mine.usdc").is_file()
