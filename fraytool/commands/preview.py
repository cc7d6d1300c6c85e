"""`fraytool preview SCENE -o OUT.png`: where everything lands before a run (docs/garments.md "Laying out").

Three views of the rest pose side by side, drawn with Pillow (no simulation, no GL): from the scene's
[camera], from the front (looking along -z) and from the side (along -x). Each panel's crossings in its
own colour with its name at its centre and its grain (the weft's direction) as an arrow; each seam as lines
between its first and last stitches' ends, with its index and stitch count; held crossings ringed; mesh
bodies as their edges, spheres and boxes as outlines. `--json` prints each panel's world bounds."""
from __future__ import annotations

import json
import math
import sys
import tomllib
from pathlib import Path

import numpy as np

from fraytool.errors import InputError

VIEW_PX = 480
PANEL_COLOURS = [(220, 90, 60), (60, 140, 220), (90, 180, 90), (200, 160, 40), (170, 90, 200), (40, 180, 180)]


def panel_bounds(model) -> list[dict]:
    out = []
    for k, name in enumerate(model.panel_names):
        x = model.crossing_rest_position_m[model.crossing_panel == k]
        out.append({"panel": name, "crossings": int(x.shape[0]), "min_m": x.min(axis=0).round(6).tolist(),
                    "max_m": x.max(axis=0).round(6).tolist()})
    return out


def _camera_projector(spec):
    """World -> pixel for the scene's perspective camera (fraytool.render.camera.look_at, vertical fov); a
    moving camera as it is at time 0 (the rest pose's time)."""
    from fraytool.render.camera import camera_at, look_at

    cam = camera_at(spec.camera, 0.0)
    view = look_at(cam.position_m, cam.target_m, cam.up)
    scale = 0.5 * VIEW_PX / math.tan(math.radians(cam.fov_deg) / 2)

    def project(x):
        v = np.asarray(x, float) @ view[:3, :3].T + view[:3, 3]  # the camera looks down -z
        depth = np.maximum(-v[..., 2], 1e-6)
        return np.stack([VIEW_PX / 2 + scale * v[..., 0] / depth, VIEW_PX / 2 - scale * v[..., 1] / depth], axis=-1)
    return project


def _ortho_projector(points, axes):
    """World -> pixel for an orthographic view along the unused axis, fitted to `points` with a margin."""
    lo, hi = points[:, axes].min(axis=0), points[:, axes].max(axis=0)
    span = float(max(hi - lo)) * 1.15 or 1.0
    centre = 0.5 * (lo + hi)

    def project(x):
        p = np.asarray(x, float)[..., axes]
        return np.stack([VIEW_PX / 2 + (p[..., 0] - centre[0]) / span * VIEW_PX,
                         VIEW_PX / 2 - (p[..., 1] - centre[1]) / span * VIEW_PX], axis=-1)
    return project


def _draw_view(draw, project, model, title, dx):
    from fraytool.meshes import MeshTable

    rest = model.crossing_rest_position_m
    meshes = MeshTable(model)
    for m in range(meshes.count):  # mesh bodies: their edges at rest, in the body's place
        b = int(meshes.body[m])
        v = model.body_initial_position_m[b] + meshes.key_vertices(m, 0) @ model.body_rotation[b].T
        tri = meshes.local_triangles(m)
        step = max(1, tri.shape[0] // 3000)
        for t in tri[::step]:
            p = project(v[t])
            draw.line([tuple(p[0] + (dx, 0)), tuple(p[1] + (dx, 0)), tuple(p[2] + (dx, 0))], fill=(150, 150, 160))
    for b, shape in enumerate(model.body_shape):
        if shape == 0:  # a sphere: its outline at its centre's depth
            c = project(model.body_initial_position_m[b])
            edge = project(model.body_initial_position_m[b] + np.array([model.body_params[b][0], 0, 0]))
            r = float(np.linalg.norm(edge - c))
            draw.ellipse([c[0] - r + dx, c[1] - r, c[0] + r + dx, c[1] + r], outline=(120, 120, 200))
    for k, name in enumerate(model.panel_names):
        mine = model.crossing_panel == k
        p = project(rest[mine])
        colour = PANEL_COLOURS[k % len(PANEL_COLOURS)]
        for x, y in p[:: max(1, len(p) // 4000)]:
            draw.rectangle([x + dx - 1, y - 1, x + dx + 1, y + 1], fill=colour)
        centre = project(rest[mine].mean(axis=0))
        draw.text((centre[0] + dx, centre[1]), name, fill=(255, 255, 255))
        weft = model.weft_structural_spring[model.weft_structural_spring >= 0]
        weft = weft[mine[model.spring_crossing_a[weft]]]
        if weft.size:  # the grain: the weft's direction, an arrow from the centre
            d = rest[model.spring_crossing_b[weft]] - rest[model.spring_crossing_a[weft]]
            tip = project(rest[mine].mean(axis=0) + 0.25 * np.ptp(rest[mine], axis=0).max() * d.mean(axis=0)
                          / max(np.linalg.norm(d.mean(axis=0)), 1e-12))
            draw.line([(centre[0] + dx, centre[1]), (tip[0] + dx, tip[1])], fill=colour, width=2)
    seam_of = np.asarray(model.spring_seam)
    for s in np.unique(seam_of[seam_of >= 0]):
        mine = np.flatnonzero(seam_of == s)
        for end in (mine[0], mine[-1]):
            a, b = project(rest[model.spring_crossing_a[end]]), project(rest[model.spring_crossing_b[end]])
            draw.line([(a[0] + dx, a[1]), (b[0] + dx, b[1])], fill=(255, 230, 80), width=2)
        mid = project(rest[model.spring_crossing_a[mine]].mean(axis=0))
        draw.text((mid[0] + dx, mid[1] + 10), f"seam {s}: {mine.size} stitches", fill=(255, 230, 80))
    for p in project(rest[model.attachment_particle % model.crossing_count]):
        draw.ellipse([p[0] - 3 + dx, p[1] - 3, p[0] + 3 + dx, p[1] + 3], outline=(255, 255, 255))
    draw.text((dx + 8, 8), title, fill=(230, 230, 230))


def preview_command(args, load, stream=None) -> int:
    """`load(scene, sets=...)`: the command line's scene loader (shipped names, --set)."""
    from PIL import Image, ImageDraw

    from fraytool.sim.builder import build_model

    spec = load(args.scene, sets=args.sets)
    if spec.source_file and Path(spec.source_file).is_file():
        with open(spec.source_file, "rb") as fh:
            has_camera = "camera" in tomllib.load(fh)
        if not has_camera:
            raise InputError(f"{spec.source}: preview draws the scene from its [camera], and the scene has none: "
                             "add a [camera] table (position_m, target_m, fov_deg; docs/scene-format.md)")
    model = build_model(spec)
    if args.json:
        print(json.dumps({"scene": spec.name, "panels": panel_bounds(model)}))
    if args.out is None:
        return 0
    image = Image.new("RGB", (3 * VIEW_PX, VIEW_PX), (24, 26, 32))
    draw = ImageDraw.Draw(image)
    from fraytool.meshes import MeshTable

    meshes = MeshTable(model)
    points = np.concatenate([model.crossing_rest_position_m, model.body_initial_position_m]
                            + [model.body_initial_position_m[int(meshes.body[m])]
                               + meshes.key_vertices(m, 0) @ model.body_rotation[int(meshes.body[m])].T
                               for m in range(meshes.count)])
    views = ((_camera_projector(spec), "scene camera"), (_ortho_projector(points, [0, 1]), "front (x right, y up)"),
             (_ortho_projector(points, [2, 1]), "side (z right, y up)"))
    for k, (project, title) in enumerate(views):
        _draw_view(draw, project, model, title, k * VIEW_PX)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    image.save(args.out)
    print(f"fraytool: wrote {args.out}", file=stream or sys.stderr)
    return 0
