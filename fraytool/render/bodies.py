"""Rigid bodies and the ground plane as unit meshes plus a model matrix per body and frame.

Shapes come from the saved topology (`body_shape`, `body_radius_m`, `body_half_extents_m`,
`body_normal`); placement from each frame record (`body_position_m`, `body_rotation`). Spheres are
UV spheres, boxes (and bars, which are long boxes) are cubes with flat faces, planes are large
quads. A plane body lying in the optional ground plane is not drawn twice (that would z-fight).
Mesh bodies are their own triangles (`mesh_draw_vertices`), in the body's frame, drawn as "mesh<m>".
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import numpy as np

from fraytool.geometry.rotations import rotation_from_y

from fraytool.kinds import SHAPE_BOX, SHAPE_MESH, SHAPE_PLANE, SHAPE_SPHERE
from fraytool.meshes import MeshTable, vertex_normals


@dataclass(frozen=True)
class UnitMesh:
    vertices: np.ndarray
    """Position (3) and normal (3) per vertex, shape (V, 6), float32."""
    indices: np.ndarray
    """Triangles, shape (F * 3,), uint32, counter-clockwise from outside."""


def unit_sphere(rings: int = 24, segments: int = 48) -> UnitMesh:
    """Radius-1 UV sphere; normals equal positions."""
    theta = np.linspace(0.0, np.pi, rings + 1)
    phi = np.linspace(0.0, 2.0 * np.pi, segments + 1)
    th, ph = np.meshgrid(theta, phi, indexing="ij")
    p = np.stack([np.sin(th) * np.cos(ph), np.cos(th), -np.sin(th) * np.sin(ph)], axis=-1).reshape(-1, 3)
    r, s = np.meshgrid(np.arange(rings), np.arange(segments), indexing="ij")
    a = (r * (segments + 1) + s).ravel()
    b = a + 1
    c = a + segments + 1
    d = c + 1
    tri = np.stack([np.stack([a, c, b], -1), np.stack([b, c, d], -1)], axis=1).reshape(-1)
    v = np.concatenate([p, p], axis=1).astype(np.float32)
    return UnitMesh(v, tri.astype(np.uint32))


def unit_cube() -> UnitMesh:
    """Cube [-1, 1]^3 with flat face normals (24 vertices)."""
    verts, idx = [], []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            n = np.zeros(3)
            n[axis] = sign
            u = np.zeros(3)
            u[(axis + 1) % 3] = 1.0
            v = np.cross(n, u)
            base = len(verts)
            for cu, cv in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
                verts.append(np.concatenate([n + cu * u + cv * v, n]))
            idx += [base, base + 1, base + 2, base, base + 2, base + 3]
    return UnitMesh(np.asarray(verts, dtype=np.float32), np.asarray(idx, dtype=np.uint32))


def unit_quad() -> UnitMesh:
    """Square [-1, 1]^2 in the xz plane, normal +y."""
    p = np.array([[-1, 0, -1], [-1, 0, 1], [1, 0, 1], [1, 0, -1]], dtype=np.float32)
    n = np.tile(np.array([0, 1, 0], dtype=np.float32), (4, 1))
    return UnitMesh(np.concatenate([p, n], axis=1), np.array([0, 1, 2, 0, 2, 3], dtype=np.uint32))


@dataclass(frozen=True)
class BodyDraw:
    mesh: str
    """"sphere", "cube", "quad" or "mesh<m>" (mesh body m, fraytool.meshes)."""
    model: np.ndarray
    """Model matrix, (4, 4) float64."""
    normal_matrix: np.ndarray
    """Inverse-transpose of the model's 3x3 part, (3, 3)."""


class BodySet:
    """The drawable bodies of a run; `draws(positions, rotations)` places them for one frame."""

    def __init__(self, topology: Mapping[str, np.ndarray], plane_half_size_m: float,
                 ground: tuple[np.ndarray, float] | None = None):
        self.shape = np.asarray(topology.get("body_shape", np.zeros(0, np.int8)))
        self.radius = np.asarray(topology.get("body_radius_m", np.zeros(len(self.shape))))
        self.half = np.asarray(topology.get("body_half_extents_m", np.zeros((len(self.shape), 3))))
        self.normal = np.asarray(topology.get("body_normal", np.tile([0.0, 1.0, 0.0], (len(self.shape), 1))))
        self.plane_half_size_m = plane_half_size_m
        self.ground = ground
        self.meshes = MeshTable(topology)
        self.mesh_of_body = {int(b): m for m, b in enumerate(self.meshes.body)}

    def _in_ground(self, normal_world: np.ndarray, position: np.ndarray) -> bool:
        if self.ground is None:
            return False
        up, height = self.ground
        scale = max(self.plane_half_size_m, 1.0)
        return float(normal_world @ up) > 0.999 and abs(float(position @ up) - height) < 1e-6 * scale

    def draws(self, position_m: np.ndarray, rotation: np.ndarray) -> list[BodyDraw]:
        out = []
        for b, shape in enumerate(self.shape):
            R = np.asarray(rotation[b], dtype=np.float64)
            x = np.asarray(position_m[b], dtype=np.float64)
            if shape == SHAPE_SPHERE:
                mesh, S = "sphere", np.eye(3) * float(self.radius[b])
                M3 = R @ S
            elif shape == SHAPE_BOX:
                mesh, S = "cube", np.diag(self.half[b])
                M3 = R @ S
            elif shape == SHAPE_PLANE:
                n_world = R @ self.normal[b]
                n_world = n_world / np.linalg.norm(n_world)
                if self._in_ground(n_world, x):
                    continue
                mesh = "quad"
                M3 = rotation_from_y(n_world) @ np.diag([self.plane_half_size_m, 1.0, self.plane_half_size_m])
            elif shape == SHAPE_MESH and b in self.mesh_of_body:
                mesh, M3 = f"mesh{self.mesh_of_body[b]}", R
            else:
                continue
            model = np.eye(4)
            model[:3, :3] = M3
            model[:3, 3] = x
            try:
                nm = np.linalg.inv(M3).T
            except np.linalg.LinAlgError:  # zero-size body: nothing to draw
                continue
            out.append(BodyDraw(mesh, model, nm))
        return out


AUTO_SMOOTH_DEG = 40.0
"""A mesh corner takes its vertex's (smooth) normal where that turns from the face's by less than this,
else the face's own (a crease stays sharp)."""


def mesh_draw_vertices(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """A mesh body's triangles as (3 T, 6) float32 position + normal rows, one row per corner, drawn with
    indices 0, 1, 2, ... (smooth where the surface is, creased where it turns by AUTO_SMOOTH_DEG)."""
    v = np.asarray(vertices, np.float64)
    smooth = vertex_normals(v, triangles)
    face = np.cross(v[triangles[:, 1]] - v[triangles[:, 0]], v[triangles[:, 2]] - v[triangles[:, 0]])
    face /= np.maximum(np.linalg.norm(face, axis=1), 1e-300)[:, None]
    corner_n = smooth[triangles]  # (T, 3, 3)
    keep = np.einsum("tcj,tj->tc", corner_n, face) > np.cos(np.radians(AUTO_SMOOTH_DEG))
    normals = np.where(keep[..., None], corner_n, face[:, None, :])
    return np.concatenate([v[triangles].reshape(-1, 3), normals.reshape(-1, 3)], axis=1).astype(np.float32)


def body_bounding_radii(topology) -> np.ndarray:
    """Radius of each body's bounding sphere about its centre [m]; -1 for a plane (unbounded)."""
    shape = np.asarray(topology.get("body_shape", np.zeros(0, np.int8)))
    radius = np.asarray(topology.get("body_radius_m", np.zeros(len(shape))), float)
    half = np.asarray(topology.get("body_half_extents_m", np.zeros((len(shape), 3))), float).reshape(-1, 3)
    params = np.asarray(topology.get("body_params", np.zeros((len(shape), 3))), float).reshape(-1, 3)
    return np.where(shape == SHAPE_SPHERE, radius, np.where(shape == SHAPE_BOX, np.linalg.norm(half, axis=-1),
                                                              np.where(shape == SHAPE_MESH, params[:, 0], -1.0)))
