"""Is the cloth in the picture? The projected masses of a frame against the image (issue: every shipped shot
keeps its cloth in frame).

A mass is in frame when its clip-space position (the renderer's own projection: fraytool.render.camera, with the
camera at the frame's time) lies in front of the eye and inside the image, |x_ndc| <= 1 and |y_ndc| <= 1. The
figures of a frame: how many active masses are out, and the largest |x_ndc| and |y_ndc| over the active masses
(above 1: something is cut off; far below 1: the cloth is small in the picture)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fraytool.render.camera import Camera
from fraytool.scene.spec import CameraSpec


@dataclass(frozen=True)
class Framing:
    """One frame's figures."""

    time_s: float
    outside: int
    """Active masses outside the image (or behind the eye)."""
    masses: int
    """Active masses."""
    reach_x: float
    """Largest |x| in normalised device coordinates over the active masses (1: the image's side)."""
    reach_y: float
    """Largest |y| likewise (1: the image's top or bottom)."""


def framing(camera: CameraSpec, aspect: float, time_s: float, position_m: np.ndarray,
            active: np.ndarray) -> Framing:
    """The figures of one frame: masses at `position_m` (N, 3), those with `active` counted, seen by `camera` at
    `time_s` in an image of width / height `aspect`."""
    points = np.asarray(position_m, np.float64)[np.asarray(active, bool)]
    if not len(points):
        return Framing(float(time_s), 0, 0, 0.0, 0.0)
    clip = np.hstack([points, np.ones((len(points), 1))]) @ Camera(camera, time_s).view_proj(aspect).T
    w = clip[:, 3]
    front = w > 0.0
    ndc = clip[:, :2] / np.where(front, w, 1.0)[:, None]
    out = ~front | (np.abs(ndc) > 1.0).any(axis=1)
    reach = np.where(front[:, None], np.abs(ndc), np.inf).max(axis=0)
    return Framing(float(time_s), int(out.sum()), len(points), float(reach[0]), float(reach[1]))


def shot_framing(spec, records) -> list[Framing]:
    """The figures of every frame record of a shot of `spec` (its camera and [render] resolution)."""
    w, h = spec.render.resolution
    return [framing(spec.camera, w / h, r.time_s, r.particle_position_m, r.particle_active) for r in records]
