"""Shadows from the key light: an orthographic depth map fitted to what casts shadows each frame.

The light looks along -light_direction (the key light is far away: parallel rays, an orthographic
projection). Its box is fitted to the casters of the frame -- the yarn tube vertices and the spheres
and boxes (planes receive, never cast) -- in the light's view space: across the light, a square around
their bounds; along it, from just in front of the nearest caster to just behind the farthest. A
receiver outside the box across the light has no caster between it and the light, and one behind
the box along the light compares at the far plane, where the cleared map (1.0) is farther: so the
ground needs no room of its own in the map; every ground point that can be in shadow lies under
the casters' box. To keep shadow edges from crawling between frames, the square's half-size is
rounded up to a step of 2^(1/4) and its centre snapped to whole texels (Williams 1978 for the
method; texel snapping as commonly done for cascaded maps).

Shaders sample the map with hardware 2x2 depth comparison (GL_LINEAR on a depth texture with
compare mode): the ground and bodies at four offsets a texel and a half apart (`shaders/shadow.glsl`),
percentage-closer filtering (Reeves, Salesin & Cook 1987) over 4 x 4 texels, the yarns, to which the
map is fitted, with one lookup (2 x 2 texels). `shadow_footprint` is where the light's box meets the
ground plane: the only part of the ground a shadow can reach (fraytool.render.renderer draws the
rest without lookups).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from fraytool.kinds import SHAPE_BOX, SHAPE_SPHERE
from fraytool.geometry.rotations import rotation_from_y

MARGIN_TEXELS = 4
"""Empty texels kept around the casters, so the PCF footprint at their edge reads cleared depth."""
NORMAL_OFFSET_TEXELS = 1.5
"""Receivers are looked up this many texels along their normal (against shadow acne)."""


@dataclass(frozen=True)
class LightFrame:
    view_proj: np.ndarray
    """World -> light clip space, (4, 4) float64 (orthographic)."""
    texel_m: float
    """World size of one shadow-map texel [m]."""


def light_view(direction: np.ndarray) -> np.ndarray:
    """Rotation rows (x, y, z) of the light's view: it looks down -z, along -direction."""
    d = np.asarray(direction, dtype=np.float64)
    z = d / np.linalg.norm(d)
    helper = np.array([0.0, 1.0, 0.0]) if abs(z[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    return np.stack([x, y, z])


def caster_points(yarn_positions: np.ndarray | tuple | None, body_shape: np.ndarray, body_position_m: np.ndarray,
                  body_radius_m: np.ndarray, body_half_extents_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Points and their radii that bound everything casting a shadow: the corners of the yarn vertices'
    bounding box (radius 0) and the spheres and boxes (their bounding spheres). Returns ((N, 3), (N,)).
    `yarn_positions`: (V, 3), or a tuple of such arrays (the yarns' and the far-field sheet's), bounded in
    their own precision (min and max are exact: float32 vertices are not widened to float64 first)."""
    pts, rad = [], []
    parts = [] if yarn_positions is None else (
        [yarn_positions] if isinstance(yarn_positions, np.ndarray) else list(yarn_positions))
    # coordinate rows: NumPy's min over axis 0 of an (N, 3) array is 20x slower than over rows
    parts = [np.ascontiguousarray(np.asarray(p).T) for p in parts if len(p)]
    if parts:
        lo = np.min([p.min(axis=1) for p in parts], axis=0).astype(np.float64)
        hi = np.max([p.max(axis=1) for p in parts], axis=0).astype(np.float64)
        corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
        pts.append(corners)
        rad.append(np.zeros(8))
    for b, shape in enumerate(np.asarray(body_shape)):
        if shape == SHAPE_SPHERE:
            r = float(body_radius_m[b])
        elif shape == SHAPE_BOX:
            r = float(np.linalg.norm(body_half_extents_m[b]))
        else:
            continue
        pts.append(np.asarray(body_position_m[b], dtype=np.float64)[None])
        rad.append(np.array([r]))
    if not pts:
        return np.zeros((0, 3)), np.zeros(0)
    return np.concatenate(pts), np.concatenate(rad)


def fit_light(direction: np.ndarray, points: np.ndarray, radii: np.ndarray, map_size: int) -> LightFrame | None:
    """The orthographic light box around `points` (each grown by its radius), or None if there is
    nothing to cast a shadow."""
    if len(points) == 0:
        return None
    R = light_view(direction)
    q = np.asarray(points, dtype=np.float64) @ R.T
    r = np.asarray(radii, dtype=np.float64)[:, None]
    lo, hi = (q - r).min(axis=0), (q + r).max(axis=0)
    half = 0.5 * float(max(hi[0] - lo[0], hi[1] - lo[1]))
    half = max(half, 1e-4) * map_size / (map_size - 2.0 * MARGIN_TEXELS)
    half = 2.0 ** (math.ceil(4.0 * math.log2(half)) / 4.0)          # a step of 2^(1/4)
    texel = 2.0 * half / map_size
    cx, cy = (np.round(0.5 * (lo[:2] + hi[:2]) / texel) * texel).tolist()
    depth_pad = 0.02 * float(hi[2] - lo[2]) + 4.0 * texel
    near_z, far_z = hi[2] + depth_pad, lo[2] - depth_pad           # view z of the near / far planes
    view = np.eye(4)
    view[:3, :3] = R
    ortho = np.eye(4)
    ortho[0, 0] = ortho[1, 1] = 1.0 / half
    ortho[0, 3], ortho[1, 3] = -cx / half, -cy / half
    ortho[2, 2] = 2.0 / (far_z - near_z)                             # view z = near_z -> -1, far_z -> +1
    ortho[2, 3] = -(far_z + near_z) / (far_z - near_z)
    return LightFrame(ortho @ view, texel)


def shadow_footprint(light: LightFrame | None, up: np.ndarray, height_m: float) -> np.ndarray | None:
    """Where the light's box meets the plane {p : up . p = height_m}: a model matrix (4, 4) taking the
    unit quad ([-1, 1]^2 in its xz plane, normal +y) to that parallelogram, its +y along `up`. The box
    is orthographic, so clip x, y are affine in the plane's coordinates; the quad's corners are the
    plane points at clip (+-1, +-1). None without a light, or when the light grazes the plane (the
    footprint would be unbounded)."""
    if light is None:
        return None
    axes3 = rotation_from_y(up)
    e1, n, e2 = axes3[:, 0], axes3[:, 1], axes3[:, 2]
    origin = height_m * n
    A = np.asarray(light.view_proj, dtype=np.float64)[:2]
    J = np.stack([A[:, :3] @ e1, A[:, :3] @ e2], axis=1)          # d(clip x, y) / d(s, t)
    if abs(np.linalg.det(J)) < 1e-6 * np.abs(J).max() ** 2:
        return None
    base = A[:, :3] @ origin + A[:, 3]                             # clip x, y at the origin
    Jinv = np.linalg.inv(J)
    st0 = Jinv @ -base                                             # plane coordinates of clip (0, 0)
    axes = np.stack([e1, e2], axis=1)                              # (3, 2)
    model = np.eye(4)
    model[:3, 0] = axes @ Jinv[:, 0]                               # clip x: -1 -> +1 across the quad
    model[:3, 1] = n
    model[:3, 2] = axes @ Jinv[:, 1]
    model[:3, 3] = origin + axes @ st0
    return model
