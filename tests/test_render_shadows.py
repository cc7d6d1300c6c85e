"""Shadows, the fill light and --fit, checked against geometry worked out here, not by the renderer:
a ground point whose ray to the key light meets the ball (and that the camera sees past the ball)
must get darker when shadows are on, one whose ray misses must not; the fitted camera must see every
point of the shot, tightly, in the original view direction."""
from __future__ import annotations

import dataclasses
import math
from types import SimpleNamespace

import numpy as np
import pytest

from fraytool.errors import SceneError
from fraytool.render.camera import Camera
from fraytool.render.fit import fit_camera, shot_points
from fraytool.render.geometry import GeometryBuilder, YarnStyle
from fraytool.render.renderer import Renderer
from fraytool.scene import load_scene
from fraytool.scene.overrides import parse_assignment
from fraytool.scene.spec import CameraSpec

BALL_CENTRE = np.array([0.0, 0.02, 0.0])   # tests/scenes/golden_small.toml
BALL_RADIUS = 0.035
GROUND_Y = -0.015
LIGHT = np.array([1.0, 1.0, 0.0]) / math.sqrt(2.0)


def _ray_miss_m(origin: np.ndarray, direction: np.ndarray) -> float:
    """How far the ray passes from the ball's surface [m]: < 0 it goes through the ball."""
    d = direction / np.linalg.norm(direction)
    oc = BALL_CENTRE - origin
    t = float(oc @ d)
    if t <= 0:
        return math.inf
    return math.sqrt(max(float(oc @ oc) - t * t, 0.0)) - BALL_RADIUS


def _render_ball_only(gl_ctx, posed_cloth, shadows: bool) -> tuple[np.ndarray, Camera]:
    record = posed_cloth.copy()
    record.particle_position_m[:] += np.array([5.0, 0.0, 0.0], np.float32)   # cloth out of view: ball + ground
    render = dataclasses.replace(posed_cloth.spec.render, light_direction=tuple(LIGHT), shadows=shadows,
                                 resolution=(320, 240))
    r = Renderer(gl_ctx, (320, 240), 4, render, posed_cloth.spec.camera, posed_cloth.topology)
    try:
        b = GeometryBuilder(posed_cloth.topology, YarnStyle.from_spec(render, posed_cloth.topology), r.camera, 240)
        return r.render(b.build(record)).astype(np.float64), r.camera
    finally:
        r.release()


def _pixel(camera: Camera, p: np.ndarray, size=(320, 240)) -> tuple[int, int]:
    clip = camera.view_proj(size[0] / size[1]) @ np.r_[p, 1.0]
    x, y = clip[:2] / clip[3]
    return int((y * -0.5 + 0.5) * size[1]), int((x * 0.5 + 0.5) * size[0])


def test_the_ball_shadow_darkens_the_ground_where_its_ray_to_the_light_meets_the_ball(gl_ctx, posed_cloth):
    off, camera = _render_ball_only(gl_ctx, posed_cloth, shadows=False)
    on, _ = _render_ball_only(gl_ctx, posed_cloth, shadows=True)
    shaded, lit = [], []
    for x in np.linspace(-0.09, 0.06, 16):
        for z in np.linspace(-0.05, 0.05, 11):
            p = np.array([x, GROUND_Y, z])
            if _ray_miss_m(camera.eye, p - camera.eye) < 0.003:
                continue   # the camera sees the ball there (or its edge), not the ground
            row, col = _pixel(camera, p)
            if not (2 <= row < 238 and 2 <= col < 318):
                continue
            ratio = on[row, col].mean() / off[row, col].mean()
            miss = _ray_miss_m(p, LIGHT)
            if miss < -0.004:
                shaded.append(ratio)
            elif miss > 0.004:     # PCF blurs the edge between
                lit.append(ratio)
    assert len(shaded) >= 5 and len(lit) >= 20, (len(shaded), len(lit))
    # shadowed ground keeps only the ambient light: ambient / (ambient + I cos 45deg), about 0.26 in
    # linear light, 0.55 in sRGB; PCF softens the edge, so the median is checked, and the worst lit point
    assert np.median(shaded) < 0.7, shaded
    assert min(lit) > 0.9 and np.median(lit) > 0.99, lit


def _project(camera: CameraSpec, points: np.ndarray, aspect: float) -> np.ndarray:
    """Normalised image coordinates (x / half-width, y / half-height) by a look-at built here."""
    eye, target, up = (np.asarray(v, float) for v in (camera.position_m, camera.target_m, camera.up))
    f = (target - eye) / np.linalg.norm(target - eye)
    s = np.cross(f, up)
    s /= np.linalg.norm(s)
    u = np.cross(s, f)
    rel = points - eye
    depth = rel @ f
    assert (depth > 0).all()
    t = math.tan(math.radians(camera.fov_deg) / 2)
    return np.stack([(rel @ s) / (depth * t * aspect), (rel @ u) / (depth * t)], axis=1)


def _shot(rng) -> list:
    records = []
    for k in range(5):
        p = rng.normal(size=(400, 3)) * [0.2, 0.05, 0.1] + [0.3 * k, 0.1, -0.05 * k]
        records.append(SimpleNamespace(particle_position_m=p.astype(np.float32),
                                       body_position_m=np.array([[0.3 * k, 0.3, 0.0]], np.float32)))
    return records


def test_fit_puts_every_point_of_the_shot_in_frame_tightly_in_the_same_direction():
    rng = np.random.default_rng(4)
    records = _shot(rng)
    topology = {"body_shape": np.array([0], np.int8), "body_radius_m": np.array([0.02]),
                "body_half_extents_m": np.zeros((1, 3))}
    from fraytool.kinds import SHAPE_SPHERE
    topology["body_shape"][0] = SHAPE_SPHERE
    cam = CameraSpec(position_m=(3.0, 2.0, 9.0), target_m=(0.0, 0.0, 0.0), fov_deg=35.0, fit=True, fit_margin=0.05)
    fitted = fit_camera(cam, shot_points(topology, records), 16 / 9)
    pts = np.concatenate([r.particle_position_m for r in records]).astype(float)
    balls = np.concatenate([r.body_position_m for r in records]).astype(float)
    ndc = _project(fitted, np.concatenate([pts, balls + [0, 0.02, 0], balls - [0, 0.02, 0]]), 16 / 9)
    assert np.abs(ndc).max() <= 0.95 + 1e-9          # inside, with the 5 % margin
    assert np.abs(ndc).max() >= 0.95 - 1e-6          # and tight: something touches the margin
    before = np.subtract(cam.target_m, cam.position_m)
    after = np.subtract(fitted.target_m, fitted.position_m)
    assert np.allclose(before / np.linalg.norm(before), after / np.linalg.norm(after))
    assert fitted.fov_deg == cam.fov_deg and fitted.fit is False


def test_a_zero_fill_direction_is_refused_naming_the_key():
    from pathlib import Path

    scene = Path(__file__).resolve().parent / "scenes" / "golden_small.toml"
    with pytest.raises(SceneError, match="fill_direction"):
        load_scene(scene, [parse_assignment("render.fill_direction=[0,0,0]")])


def test_the_shadow_footprint_is_where_the_light_box_meets_the_ground():
    """The quad drawn with shadow lookups: its corners lie on the ground plane and the light's clip
    space puts them at (+-1, +-1), so it covers exactly the map; a light along the plane has none."""
    from fraytool.render.shadow import fit_light, shadow_footprint

    rng = np.random.default_rng(2)
    up = np.array([0.2, 1.0, -0.1])
    up /= np.linalg.norm(up)
    light = fit_light(np.array([0.4, 1.0, 0.3]), rng.normal(size=(50, 3)) * 0.1, np.zeros(50), 1024)
    model = shadow_footprint(light, up, -0.25)
    corners = np.array([[x, 0.0, z, 1.0] for x in (-1.0, 1.0) for z in (-1.0, 1.0)]) @ model.T
    assert np.allclose(corners[:, :3] @ up, -0.25)
    clip = corners @ light.view_proj.T
    assert np.allclose(np.abs(clip[:, :2]), 1.0)
    assert len({tuple(np.sign(c[:2])) for c in clip}) == 4                     # all four corners
    normal = np.linalg.inv(model[:3, :3]).T @ [0.0, 1.0, 0.0]                  # as the shader's normal matrix
    assert np.allclose(normal / np.linalg.norm(normal), up)
    grazing = fit_light(np.cross(up, [1.0, 0.0, 0.0]), rng.normal(size=(50, 3)), np.zeros(50), 1024)
    assert shadow_footprint(grazing, up, 0.0) is None
    assert shadow_footprint(None, up, 0.0) is None


def test_the_ground_drawn_in_two_parts_matches_one_shadowed_draw(gl_ctx, posed_cloth, monkeypatch):
    """The ground outside the shadow footprint is drawn without lookups: the picture must be the one
    the shadowed ground program gives everywhere (the seam invisible), with the ball's and the torn
    cloth's shadows on it."""
    import fraytool.render.renderer as renderer_module

    render = dataclasses.replace(posed_cloth.spec.render, light_direction=(0.6, 1.0, 0.2), shadows=True,
                                 resolution=(320, 240))

    def draw():
        r = Renderer(gl_ctx, (320, 240), 4, render, posed_cloth.spec.camera, posed_cloth.topology)
        try:
            b = GeometryBuilder(posed_cloth.topology, YarnStyle.from_spec(render, posed_cloth.topology), r.camera, 240)
            return r.render(b.build(posed_cloth.torn())).astype(np.int64)
        finally:
            r.release()

    split = draw()
    monkeypatch.setattr(renderer_module, "shadow_footprint", lambda *a: None)
    whole = draw()
    no_shadows = dataclasses.replace(render, shadows=False)
    render = no_shadows
    unshadowed = draw()
    assert (np.abs(whole - unshadowed).max(axis=2) > 24).mean() > 0.01             # there are shadows to keep
    diff = np.abs(split - whole).max(axis=2)
    assert diff.max() <= 2, diff.max()
