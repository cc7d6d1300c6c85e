"""Triangle-mesh bodies as flat arrays: one table the simulation, the renderer and the exporters read.

A leaf module (numpy only), like fraytool.kinds, so that every layer reads a mesh body the same way
from the Model or from a run's topology.npz (docs/meshes.md, docs/architecture.md). Mesh m belongs to
body `mesh_body[m]`; its vertices are in the body's frame [m] (the body's position and rotation place
it), its triangles index the concatenated vertex rows. An animated mesh has keys: vertex sets at
times `mesh_key_time_s` [s, scene time], linearly interpolated between keys and held before the first
and after the last. A static mesh has one key.

    mesh_body          (M,)    int32   body index of mesh m
    mesh_closed        (M,)    bool    watertight and consistently oriented (outward normals)
    mesh_vertex_start  (M+1,)  int64   mesh m's vertices are rows [start[m], start[m+1]) of a key
    mesh_triangle_start(M+1,)  int64
    mesh_triangles     (T, 3)  int32   vertex indices into the concatenated vertex rows
    mesh_key_start     (M+1,)  int64   mesh m's keys are mesh_key_time_s[key_start[m]:key_start[m+1]]
    mesh_key_time_s    (K,)    float64
    mesh_key_vertex_m  (R, 3)  float64 key k of mesh m: vertices at key_vertex_row(m, k) on
    mesh_edge_start    (M+1,)  int64
    mesh_sharp_edges   (E, 2)  int32   edges where the yarns can catch (boundary or dihedral > SHARP_DEG)
"""
from __future__ import annotations

from typing import Any

import numpy as np

SHARP_DEG = 30.0
"""An edge whose two faces turn by more than this [degrees] (or with one face: an open mesh's border)
takes part in the yarn segments' edge contact (docs/meshes.md)."""

FIELDS = ("mesh_body", "mesh_closed", "mesh_vertex_start", "mesh_triangle_start", "mesh_triangles",
          "mesh_key_start", "mesh_key_time_s", "mesh_key_vertex_m", "mesh_edge_start", "mesh_sharp_edges")


def empty_fields() -> dict[str, np.ndarray]:
    """The mesh arrays of a scene without meshes."""
    return {"mesh_body": np.zeros(0, np.int32), "mesh_closed": np.zeros(0, bool),
            "mesh_vertex_start": np.zeros(1, np.int64), "mesh_triangle_start": np.zeros(1, np.int64),
            "mesh_triangles": np.zeros((0, 3), np.int32), "mesh_key_start": np.zeros(1, np.int64),
            "mesh_key_time_s": np.zeros(0), "mesh_key_vertex_m": np.zeros((0, 3)),
            "mesh_edge_start": np.zeros(1, np.int64), "mesh_sharp_edges": np.zeros((0, 2), np.int32)}


class MeshTable:
    """Read access to the mesh arrays of a Model (attributes) or of a topology.npz (a mapping)."""

    def __init__(self, source: Any):
        get = (lambda k: source[k]) if hasattr(source, "keys") else (lambda k: getattr(source, k))
        defaults = empty_fields()
        values = {}
        for k in FIELDS:
            try:
                values[k] = np.asarray(get(k))
            except (KeyError, AttributeError):
                values[k] = defaults[k]  # a run written before meshes existed has none
        self.body = values["mesh_body"].astype(np.int64)
        self.closed = values["mesh_closed"].astype(bool)
        self.vertex_start = values["mesh_vertex_start"].astype(np.int64)
        self.triangle_start = values["mesh_triangle_start"].astype(np.int64)
        self.triangles = values["mesh_triangles"].astype(np.int32).reshape(-1, 3)
        self.key_start = values["mesh_key_start"].astype(np.int64)
        self.key_time_s = values["mesh_key_time_s"].astype(np.float64)
        self.key_vertex_m = values["mesh_key_vertex_m"].astype(np.float64).reshape(-1, 3)
        self.edge_start = values["mesh_edge_start"].astype(np.int64)
        self.sharp_edges = values["mesh_sharp_edges"].astype(np.int32).reshape(-1, 2)

    @property
    def count(self) -> int:
        return int(self.body.shape[0])

    def vertex_count(self, m: int) -> int:
        return int(self.vertex_start[m + 1] - self.vertex_start[m])

    def key_count(self, m: int) -> int:
        return int(self.key_start[m + 1] - self.key_start[m])

    def animated(self, m: int) -> bool:
        return self.key_count(m) > 1

    def local_triangles(self, m: int) -> np.ndarray:
        """Mesh m's triangles indexing its own vertices, (T_m, 3) int32."""
        t0, t1 = self.triangle_start[m], self.triangle_start[m + 1]
        return self.triangles[t0:t1] - np.int32(self.vertex_start[m])

    def key_vertices(self, m: int, k: int) -> np.ndarray:
        """Vertices of mesh m at its key k, body frame [m], (V_m, 3) (a view)."""
        v = self.vertex_count(m)
        row = key_vertex_row(self.key_start, self.vertex_start, m, k)
        return self.key_vertex_m[row:row + v]

    def key_times(self, m: int) -> np.ndarray:
        return self.key_time_s[self.key_start[m]:self.key_start[m + 1]]

    def bracket(self, m: int, time_s: float) -> tuple[int, int, float]:
        """Keys (i, j) and weight w of key j at time_s: vertices = (1 - w) key i + w key j."""
        return key_bracket(self.key_times(m), time_s)

    def vertices_at(self, m: int, time_s: float) -> np.ndarray:
        """Vertices of mesh m at time_s [s], body frame [m], (V_m, 3), a new array."""
        i, j, w = self.bracket(m, time_s)
        if w == 0.0:
            return self.key_vertices(m, i).copy()
        return (1.0 - w) * self.key_vertices(m, i) + w * self.key_vertices(m, j)


def key_vertex_row(key_start: np.ndarray, vertex_start: np.ndarray, m: int, k: int) -> int:
    """First row of key k of mesh m in mesh_key_vertex_m (keys of a mesh follow each other)."""
    rows = 0
    for q in range(m):
        rows += int(key_start[q + 1] - key_start[q]) * int(vertex_start[q + 1] - vertex_start[q])
    return rows + k * int(vertex_start[m + 1] - vertex_start[m])


def key_bracket(times: np.ndarray, time_s: float) -> tuple[int, int, float]:
    """(i, j, w): time_s lies between keys i and j = i + 1 at weight w of j; held at both ends."""
    n = times.shape[0]
    if n <= 1 or time_s <= times[0]:
        return 0, 0, 0.0
    if time_s >= times[-1]:
        return n - 1, n - 1, 0.0
    j = int(np.searchsorted(times, time_s, side="right"))
    i = j - 1
    span = float(times[j] - times[i])
    return i, j, (float(time_s - times[i]) / span if span > 0.0 else 1.0)


def vertex_normals(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Area-weighted vertex normals (unit; +y where a vertex has no area), (V, 3)."""
    a, b, c = (vertices[triangles[:, q]] for q in range(3))
    face = np.cross(b - a, c - a)
    n = np.zeros_like(vertices)
    for q in range(3):
        np.add.at(n, triangles[:, q], face)
    length = np.linalg.norm(n, axis=1)
    n[length == 0.0] = (0.0, 1.0, 0.0)
    length[length == 0.0] = 1.0
    return n / length[:, None]


def tightest_bend_radius_m(vertices: np.ndarray, triangles: np.ndarray) -> float:
    """The smallest radius of curvature [m] across the mesh's edges shared by two faces: the distance
    between the faces' centroids over the angle between their normals (inf for a flat mesh). A thin rod's
    radius comes out about its own; a smooth body's, about its curvature's."""
    a, b, c = (vertices[triangles[:, q]] for q in range(3))
    normal = np.cross(b - a, c - a)
    length = np.linalg.norm(normal, axis=1)
    normal = normal / np.where(length > 0.0, length, 1.0)[:, None]
    centroid = (a + b + c) / 3.0
    edges = np.sort(np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]]), axis=1)
    face = np.tile(np.arange(triangles.shape[0]), 3)
    order = np.lexsort((edges[:, 1], edges[:, 0]))
    edges, face = edges[order], face[order]
    pair = np.flatnonzero((edges[1:] == edges[:-1]).all(axis=1))  # consecutive rows: one edge, two faces
    if not pair.size:
        return float("inf")
    f1, f2 = face[pair], face[pair + 1]
    angle = np.arccos(np.clip((normal[f1] * normal[f2]).sum(axis=1), -1.0, 1.0))
    distance = np.linalg.norm(centroid[f1] - centroid[f2], axis=1)
    turned = angle > 1e-9
    return float((distance[turned] / angle[turned]).min()) if turned.any() else float("inf")

