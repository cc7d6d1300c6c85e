"""`fraytool render --fit` / `[camera] fit = true`: frame the cloth over a whole shot.

The camera keeps its view direction (from `position_m` towards `target_m`), its up vector and its
field of view. The points to frame are every particle of every frame record of the shot plus the
bounding spheres of the spheres and boxes (planes are unbounded and left out). In the camera's
basis (s right, u up, f forward) the new target is the centre of those points' bounding box; a
point at offsets (x, y, z) from it is seen at depth D + z when the eye is D behind the target, and
lies inside the frame when |x| <= (D + z) tx and |y| <= (D + z) ty, with tx, ty the tangents of the
half fields of view shrunk by the margin. So the smallest distance that shows every point is

    D = max over points of (max(|x| / tx, |y| / ty) - z)

exactly (no bounding-sphere slack): the eye goes to target - D f.

A moving camera ([camera] keys, `fit_moving_camera`) keeps its move: the view direction, `up` and
field of view of every frame stay those of its keys at the frame's time. The whole move is shifted by one
translation T, which takes the mean of its targets over the frames to the centre of the world bounding
box of every frame's points, and every eye's distance D_k from its (shifted) target is scaled by one
factor s, the smallest with which each frame k shows its own points: with the formula above in frame k's
basis about its shifted target, D_k' = s D_k >= need_k for every k, so s = max_k need_k / D_k. The result
is keyed at every frame record's time (eye and target; the fov keys stay), so every frame is framed
exactly; between frames (motion blur's sub-frames) the camera moves on those keys.
"""
from __future__ import annotations

import dataclasses
import math
from typing import Iterable, Mapping

import numpy as np

from fraytool.render.camera import Camera, is_animated
from fraytool.scene.spec import CameraSpec


def shot_points(topology: Mapping[str, np.ndarray], records: Iterable) -> np.ndarray:
    """Every particle of every record, and for every sphere, box and mesh the 6 points of its bounding
    sphere along the world axes, as (N, 3) float64."""
    from fraytool.render.bodies import body_bounding_radii

    r = body_bounding_radii(topology)
    offsets = np.concatenate([np.eye(3), -np.eye(3)])
    out = []
    for record in records:
        out.append(np.asarray(record.particle_position_m, dtype=np.float64))
        body = np.asarray(record.body_position_m, dtype=np.float64)
        for b in np.nonzero(r >= 0)[0]:
            out.append(body[b] + r[b] * offsets)
    return np.concatenate(out) if out else np.zeros((0, 3))


def fit_camera(camera: CameraSpec, points: np.ndarray, aspect: float, margin: float | None = None) -> CameraSpec:
    """The camera moved along its view axis and re-targeted so that every point is in frame with
    `margin` (default the camera's fit_margin) of the half-frame free; fit is False in the result."""
    points = np.asarray(points, dtype=np.float64)
    if len(points) == 0:
        return dataclasses.replace(camera, fit=False)
    margin = camera.fit_margin if margin is None else margin
    view = Camera(camera).view
    s, u, f = view[0, :3], view[1, :3], -view[2, :3]
    basis = np.stack([s, u, f])
    local = points @ basis.T
    lo, hi = local.min(axis=0), local.max(axis=0)
    centre_local = 0.5 * (lo + hi)
    target = centre_local @ basis
    rel = local - centre_local
    distance = max(_distance_needed(rel, camera.fov_deg, aspect, margin),
                   1e-3 * max(float(np.linalg.norm(hi - lo)), 1e-3))
    eye = target - distance * f
    return dataclasses.replace(camera, position_m=tuple(float(x) for x in eye),
                               target_m=tuple(float(x) for x in target), fit=False)


def _distance_needed(rel: np.ndarray, fov_deg: float, aspect: float, margin: float) -> float:
    """The eye's distance from the centre that shows points at offsets `rel` (camera basis: right, up,
    forward) from it (module docstring), with every point beyond the near plane."""
    ty = math.tan(math.radians(fov_deg) / 2.0) * (1.0 - margin)
    tx = ty * aspect
    need = np.maximum(np.abs(rel[:, 0]) / tx, np.abs(rel[:, 1]) / ty) - rel[:, 2]
    need = np.maximum(need, -rel[:, 2] / 0.99)   # every point beyond the near plane (distance / 200)
    return float(need.max())


def fit_moving_camera(camera: CameraSpec, frames: list[tuple[float, np.ndarray]], aspect: float,
                      margin: float | None = None) -> CameraSpec:
    """A moving camera (keys) shifted and dollied so that every frame's points are in frame (module
    docstring); `frames`: (time [s], points (N, 3)) per frame. Keyed at the frames' times; fit is False."""
    margin = camera.fit_margin if margin is None else margin
    frames = [(float(t), np.asarray(p, dtype=np.float64).reshape(-1, 3)) for t, p in frames]
    every = np.concatenate([p for _, p in frames]) if frames else np.zeros((0, 3))
    if len(every) == 0:
        return dataclasses.replace(camera, fit=False)
    lo, hi = every.min(axis=0), every.max(axis=0)
    poses = [Camera(camera, t) for t, _ in frames]
    shift = 0.5 * (lo + hi) - np.mean([c.target for c in poses], axis=0)
    floor = 1e-3 * max(float(np.linalg.norm(hi - lo)), 1e-3)
    scale = 0.0
    for (t, points), c in zip(frames, poses):
        basis = np.stack([c.view[0, :3], c.view[1, :3], -c.view[2, :3]])
        distance = float(np.linalg.norm(c.target - c.eye))
        if len(points):
            rel = (points - (c.target + shift)) @ basis.T
            scale = max(scale, _distance_needed(rel, c.spec.fov_deg, aspect, margin) / distance)
        scale = max(scale, floor / distance)
    eyes, targets = [], []
    for (t, _), c in zip(frames, poses):
        target = c.target + shift
        eyes.append((t, *(float(x) for x in target - scale * (c.target - c.eye))))
        targets.append((t, *(float(x) for x in target)))
    return dataclasses.replace(camera, position_m=tuple(eyes[0][1:]), target_m=tuple(targets[0][1:]),
                               position_keys_m=tuple(eyes), target_keys_m=tuple(targets), fit=False)


def fitted_camera(spec, store) -> CameraSpec:
    """The scene's camera fitted to every frame record of the scene in `store` (a FrameStore holding the
    whole shot) at the aspect of its [render] resolution: one camera for the whole shot, or for a moving
    camera its move shifted and dollied to frame every frame (`fit_moving_camera`)."""
    topology = store.load_topology()
    records = (store.load_frame(f) for f in range(spec.time.frames))
    w, h = spec.render.resolution
    if is_animated(spec.camera):
        frames = [(float(r.time_s), shot_points(topology, [r])) for r in records]
        return fit_moving_camera(spec.camera, frames, w / h)
    return fit_camera(spec.camera, shot_points(topology, records), w / h)


def fitted_job(job, store):
    """The render job with its camera fitted to the whole shot (`fitted_camera`): the same camera for
    every frame range of the scene, so farm chunks and `fraytool render` agree."""
    return dataclasses.replace(job, spec=dataclasses.replace(job.spec, camera=fitted_camera(job.spec, store)))
