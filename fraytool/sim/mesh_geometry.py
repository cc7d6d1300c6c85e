"""A run's mesh bodies ready for contact: vertex sets at a step's two ends and refitted trees.

Derived from the Model (fraytool.meshes): built once per solver (the trees), advanced each step
(`at_step`). A static or rigidly moving mesh keeps its vertices and its refit from the start; an
animated one takes its vertices at the step's two times and refits its trees once per interval
between keys (docs/meshes.md, "Broad phase").
"""
from __future__ import annotations

import numpy as np

from fraytool.meshes import MeshTable
from fraytool.sim.kernels import mesh_bvh
from fraytool.sim.kernels.mesh_contact import MeshesIn


class MeshGeometry:
    def __init__(self, model):
        self.table = t = MeshTable(model)
        self.vertex_start_m = np.zeros((int(t.vertex_start[-1]), 3))
        for m in range(t.count):
            self.vertex_start_m[t.vertex_start[m]:t.vertex_start[m + 1]] = t.vertices_at(m, 0.0)
        self.vertex_end_m = self.vertex_start_m.copy()
        tri_centroids, edge_centroids = [], []
        for m in range(t.count):
            v = self.vertex_start_m
            tri = t.triangles[t.triangle_start[m]:t.triangle_start[m + 1]]
            edges = t.sharp_edges[t.edge_start[m]:t.edge_start[m + 1]]
            tri_centroids.append(v[tri].mean(axis=1))
            edge_centroids.append(v[edges].mean(axis=1) if edges.size else np.zeros((0, 3)))
        self.tri_bvh = mesh_bvh.build(tri_centroids, [int(x) for x in t.triangle_start[:-1]])
        self.edge_bvh = mesh_bvh.build(edge_centroids, [int(x) for x in t.edge_start[:-1]])
        self._tri_boxes = np.zeros((t.triangles.shape[0], 6))
        self._edge_boxes = np.zeros((t.sharp_edges.shape[0], 6))
        self._refit_keys: list = [None] * t.count
        self.animated = [t.animated(m) for m in range(t.count)]
        for m in range(t.count):
            self._refit(m, self.vertex_start_m, self.vertex_start_m)

    def _refit(self, m: int, lo_vertices: np.ndarray, hi_vertices: np.ndarray) -> None:
        t = self.table
        mesh_bvh.refit_mesh(self.tri_bvh, m, t.triangles, t.triangle_start, lo_vertices, hi_vertices, self._tri_boxes)
        mesh_bvh.refit_mesh(self.edge_bvh, m, t.sharp_edges, t.edge_start, lo_vertices, hi_vertices,
                            self._edge_boxes)

    def at_step(self, t0_s: float, t1_s: float) -> None:
        """Animated meshes' vertices at t0_s and t1_s, and their trees refitted for the keys around them."""
        t = self.table
        for m in range(t.count):
            if not self.animated[m]:
                continue
            rows = slice(int(t.vertex_start[m]), int(t.vertex_start[m + 1]))
            self.vertex_start_m[rows] = t.vertices_at(m, t0_s)
            self.vertex_end_m[rows] = t.vertices_at(m, t1_s)
            first, _, _ = t.bracket(m, t0_s)
            i1, j1, w1 = t.bracket(m, t1_s)
            last = j1 if w1 > 0.0 else i1
            if self._refit_keys[m] != (first, last):
                keys = np.stack([t.key_vertices(m, k) for k in range(first, max(last, first) + 1)])
                lo = self.vertex_start_m.copy()
                hi = self.vertex_start_m.copy()
                lo[rows] = keys.min(axis=0)
                hi[rows] = keys.max(axis=0)
                self._refit(m, lo, hi)
                self._refit_keys[m] = (first, last)

    def meshes_in(self, model) -> MeshesIn:
        t, tb, eb = self.table, self.tri_bvh, self.edge_bvh
        return MeshesIn(t.body, t.closed, t.triangles, t.sharp_edges, self.vertex_start_m, self.vertex_end_m,
                        tb.node_start, tb.child, tb.prim_range, tb.box, tb.order,
                        eb.node_start, eb.child, eb.prim_range, eb.box, eb.order)
