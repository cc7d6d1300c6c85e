"""`fraytool preview`: the rest pose drawn before a run, each panel's world bounds in --json, and a scene
without a camera refused in one line."""
from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
from PIL import Image

from test_sewing import cylinder_obj, scene


def test_preview_draws_three_views_and_gives_each_panels_bounds(tmp_path):
    cylinder_obj(tmp_path / "post.obj")
    text = scene(0.3).replace("[self_collision]", "[camera]\nposition_m = [0.12, 0.12, 0.2]\n[self_collision]")
    (tmp_path / "s.toml").write_text(text)
    run = subprocess.run([sys.executable, "-m", "fraytool", "preview", str(tmp_path / "s.toml"), "-o",
                          str(tmp_path / "p.png"), "--json"], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    panels = json.loads(run.stdout)["panels"]
    assert [p["panel"] for p in panels] == ["front", "back"]
    np.testing.assert_allclose(panels[0]["min_m"], [-0.06, 0.0, 0.05], atol=1e-9)
    np.testing.assert_allclose(panels[1]["max_m"], [0.06, 0.048, -0.05], atol=1e-9)
    image = np.asarray(Image.open(tmp_path / "p.png").convert("RGB"))
    assert image.shape == (480, 1440, 3)
    shows = {(0, "front"): True, (0, "back"): True, (2, "front"): True, (2, "back"): True,
             (1, "back"): True, (1, "front"): False}  # from the front, the back panel is drawn over the front one
    for (view, panel), seen in shows.items():
        part = image[:, view * 480:(view + 1) * 480].reshape(-1, 3)
        colour = (220, 90, 60) if panel == "front" else (60, 140, 220)
        assert (part == colour).all(axis=1).any() == seen, (view, panel)
        assert (part == (255, 230, 80)).all(axis=1).any(), view  # the seams


def test_preview_of_a_scene_without_a_camera_is_one_line_and_exit_2(tmp_path):
    cylinder_obj(tmp_path / "post.obj")
    (tmp_path / "s.toml").write_text(scene(0.3))
    run = subprocess.run([sys.executable, "-m", "fraytool", "preview", str(tmp_path / "s.toml"), "-o",
                          str(tmp_path / "p.png")], capture_output=True, text=True)
    lines = [x for x in run.stderr.splitlines() if x.strip()]
    assert run.returncode == 2 and len(lines) == 1 and "has none: add a [camera] table" in lines[0], run.stderr
    assert not (tmp_path / "p.png").exists()
