"""Every shipped shot keeps its cloth in frame: each active mass of every frame projects inside the image, seen by
the scene's camera at the frame's time (fraytool.render.framing, the renderer's own projection).

Each scene runs its whole shot, except shirt_snag, which runs its first SHIRT_FRAMES frames here (2.6 s a
frame simulated); `python benchmarks/framing.py --scenes shirt_snag` checks its whole shot."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from fraytool.render.framing import framing, shot_framing
from fraytool.scene import load_scene
from fraytool.scene.spec import CameraSpec
from fraytool.sim import Simulation
from pinned_figures import ROOT, SHIRT_FRAMES

SCENES = sorted(p.stem for p in (ROOT / "scenes").glob("*.toml"))


@pytest.mark.parametrize("scene", SCENES)
def test_shipped_scene_keeps_its_cloth_in_frame(scene):
    spec = load_scene(ROOT / "scenes" / f"{scene}.toml")
    frames = SHIRT_FRAMES if scene == "shirt_snag" else spec.time.frames
    figures = shot_framing(spec, Simulation(spec).frames(frames))
    assert len(figures) == frames
    frame_s = spec.time.step_s * spec.time.steps_per_frame
    out = [(round(f.time_s / frame_s), f.outside, round(max(f.reach_x, f.reach_y), 3)) for f in figures if f.outside]
    assert not out, f"{scene}: (frame, masses outside, reach) {out[:10]}"
    assert max(max(f.reach_x, f.reach_y) for f in figures) > 0.4  # the cloth is not a speck in the picture


def test_framing_counts_what_leaves_the_picture_and_what_is_behind_the_eye():
    camera = CameraSpec(position_m=(0.0, 0.0, 1.0), target_m=(0.0, 0.0, 0.0), fov_deg=90.0)
    # at distance 1 with a 90 degree fov, the image spans y in [-1, 1] and x in [-2, 2] at aspect 2
    points = np.array([[0.0, 0.0, 0.0], [1.9, 0.0, 0.0], [2.1, 0.0, 0.0], [0.0, -1.05, 0.0], [0.0, 0.0, 2.0],
                       [5.0, 5.0, 0.0]])
    f = framing(camera, 2.0, 0.0, points, np.array([True, True, True, True, True, False]))
    assert (f.outside, f.masses) == (3, 5)  # right of the image, below it, behind the eye; the inactive one skipped
    assert f.reach_x == f.reach_y == np.inf  # behind the eye
    f = framing(camera, 2.0, 0.0, points[:4], np.ones(4, bool))
    assert f.outside == 2 and f.reach_x == pytest.approx(2.1 / 2.0) and f.reach_y == pytest.approx(1.05)
    moving = dataclasses.replace(camera, position_keys_m=((0.0, 0.0, 0.0, 1.0), (1.0, 3.0, 0.0, 1.0)),
                                 target_keys_m=((0.0, 0.0, 0.0, 0.0), (1.0, 3.0, 0.0, 0.0)))
    assert framing(moving, 2.0, 0.0, points[:1], [True]).outside == 0
    assert framing(moving, 2.0, 1.0, points[:1], [True]).outside == 1  # the camera has moved 3 m to the right
