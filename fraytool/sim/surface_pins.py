"""Crossings pinned to a mesh body's surface, carried by its animation (docs/garments.md, "Pinning").

An attachment to a mesh body holds each of its crossings at a place on the mesh's surface: the closest point
of the nearest triangle at rest (body frame, the mesh's first key), as barycentric weights (wa, wb, wc), and
the crossing's distance off that surface along the triangle's normal, d. At time t the crossing is at

    x(t) = c(t) + R(t) (wa a(t) + wb b(t) + wc c(t) + d n(t)),

with a, b, c the triangle's vertices at t (keys of a sequence or of USD points, linearly interpolated,
fraytool.meshes), n its unit normal and c(t), R(t) the body's pose (path and orientation keys). A waistband,
a strap or a collar follows the body as it moves and bends. With release_force_n > 0 a held crossing lets go
when the force its neighbours pull it with (and its weight) passes that force: it is then a free mass.
"""
from __future__ import annotations

import numpy as np

from fraytool.geometry.triangles import unit_normals
from fraytool.meshes import MeshTable
from fraytool.sim.kernels.surface_pins import nearest_triangles

REACH_SPACINGS = 5.0
"""A crossing is pinned to the surface when the mesh lies within this many yarn spacings of it at rest; further
off, the attachment is refused (the panel is not on the body)."""


def pin_to_surface(points_m: np.ndarray, vertices_m: np.ndarray, triangles: np.ndarray) -> tuple:
    """Each point's (body frame [m], (P, 3)) nearest triangle (index into `triangles`), barycentric weights of
    its closest point (P, 3), signed offset along the triangle's normal [m] (P,) and distance [m] (P,)."""
    points = np.ascontiguousarray(points_m, dtype=np.float64).reshape(-1, 3)
    tri = np.zeros(points.shape[0], np.int64)
    bary = np.zeros((points.shape[0], 3))
    dist = np.zeros(points.shape[0])
    if points.shape[0]:
        nearest_triangles(points, np.ascontiguousarray(vertices_m, np.float64),
                          np.ascontiguousarray(triangles, np.int64), tri, bary, dist)
    corners = vertices_m[triangles[tri]]  # (P, 3, 3)
    on_surface = np.einsum("pk,pkd->pd", bary, corners)
    normal = unit_normals(corners)
    offset = np.einsum("pd,pd->p", points - on_surface, normal)
    return tri, bary, offset, dist


class SurfacePins:
    """The surface-pinned attachments of a Model (Model.attachment_triangle >= 0), placed each step."""

    def __init__(self, model):
        self.model = model
        self.meshes = MeshTable(model)
        pinned = np.flatnonzero(model.attachment_triangle >= 0)
        self.pinned = pinned
        self.particle = model.attachment_particle[pinned]
        self.body = model.attachment_body[pinned]
        tri = model.attachment_triangle[pinned]
        self.mesh = np.searchsorted(self.meshes.triangle_start, tri, side="right") - 1
        self.corners = self.meshes.triangles[tri].astype(np.int64) - self.meshes.vertex_start[self.mesh][:, None]
        self.bary = model.attachment_barycentric[pinned]
        self.offset_m = model.attachment_normal_offset_m[pinned]

    def positions_m(self, time_s: float, body_position_m: np.ndarray, body_rotation: np.ndarray) -> np.ndarray:
        """Where the pinned crossings are at `time_s` with the bodies at the given pose, (P, 3) [m]."""
        local = np.zeros((self.pinned.size, 3))
        for m in np.unique(self.mesh):
            mine = self.mesh == m
            corners = self.meshes.vertices_at(int(m), time_s)[self.corners[mine]]
            local[mine] = (np.einsum("pk,pkd->pd", self.bary[mine], corners)
                           + self.offset_m[mine, None] * unit_normals(corners))
        rot = body_rotation[self.body]
        return body_position_m[self.body] + np.einsum("pij,pj->pi", rot, local)
