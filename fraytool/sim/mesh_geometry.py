"""A run's mesh bodies ready for contact: vertex sets at a step's two ends and refitted trees.

Derived from the Model (fraytool.meshes): built once per solver (the trees), advanced each step
(`at_step`). A static or rigidly moving mesh keeps its vertices and its refit from the start; an
animated one takes its vertices at the step's two times and refits its trees once per interval
between keys (docs/meshes.md, "Broad phase").
"""
from __future__ import annotations

import numpy as np

from fraytool.meshes import MeshTable
from fraytool.kinds import STRUCT_WARP, STRUCT_WEFT
from fraytool.sim.kernels import mesh_bvh
from fraytool.sim.kernels.mesh_clearance import empty_clearance
from fraytool.sim.kernels.mesh_contact import MeshesIn
from fraytool.sim.kernels.mesh_leaf_cache import NO_LIST, empty_leaf_cache

REACH_SPACINGS = 1.5
"""How far a clearance refresh looks (fraytool.sim.kernels.mesh_clearance), in yarn segment lengths (the
longest structural spring at rest) plus four margins: a segment is skipped when its two ends' bounds add
up to more than its length, so a shorter reach would seldom skip one."""


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
        self.edge_bvh = mesh_bvh.build(edge_centroids, [int(x) for x in t.edge_start[:-1]], median=False)
        self._refit_keys: list = [None] * t.count
        self.animated = [t.animated(m) for m in range(t.count)]
        self.leaf_cache = empty_leaf_cache(t.count, model.particle_count)
        """Per-mass lists of the triangle trees' leaves near it (fraytool.sim.kernels.mesh_leaf_cache), emptied
        for a mesh at each of its refits."""
        for m in range(t.count):
            self._refit(m, self.vertex_start_m, self.vertex_start_m)
        self.clearance = empty_clearance(t.count, model.particle_count, self._coordinate_scales(), self._reach(model))
        """Per-mass distance bounds the contact passes read and renew (fraytool.sim.kernels.mesh_clearance)."""
        self._step_times = None

    def _coordinate_scales(self) -> np.ndarray:
        t = self.table
        out = np.zeros(t.count)
        for m in range(t.count):
            keys = [t.key_vertices(m, k) for k in range(t.key_count(m))]
            out[m] = max(float(np.abs(k).max()) if k.size else 0.0 for k in keys)
        return out

    @staticmethod
    def _reach(model) -> float:
        return REACH_SPACINGS * longest_yarn_segment_m(model) + 2.0 * model.thickness_m

    def _refit(self, m: int, lo_vertices: np.ndarray, hi_vertices: np.ndarray) -> None:
        t = self.table
        mesh_bvh.refit_mesh(self.tri_bvh, m, t.triangles, t.triangle_start, lo_vertices, hi_vertices)
        mesh_bvh.refit_mesh(self.edge_bvh, m, t.sharp_edges, t.edge_start, lo_vertices, hi_vertices)
        self.leaf_cache.count[m] = NO_LIST  # the lists hold while the boxes do

    def at_step(self, t0_s: float, t1_s: float) -> None:
        """Animated meshes' vertices at t0_s and t1_s, their trees refitted for the keys around them, and
        their travel (fraytool.sim.kernels.mesh_clearance) counted once per step."""
        if self._step_times == (t0_s, t1_s):
            return  # (the step's second contact pass)
        self._step_times = (t0_s, t1_s)
        t = self.table
        travel, travel_start = self.clearance.travel_m, self.clearance.travel_start_m
        for m in range(t.count):
            if not self.animated[m]:
                continue
            rows = slice(int(t.vertex_start[m]), int(t.vertex_start[m + 1]))
            last_end = self.vertex_end_m[rows].copy()
            self.vertex_start_m[rows] = t.vertices_at(m, t0_s)
            self.vertex_end_m[rows] = t.vertices_at(m, t1_s)
            travel_start[m] = travel[m] + _largest_move(last_end, self.vertex_start_m[rows])
            travel[m] = travel_start[m] + _largest_move(self.vertex_start_m[rows], self.vertex_end_m[rows])
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


def longest_yarn_segment_m(model) -> float:
    """The longest yarn segment (structural spring) at rest [m]; the spacing where there is none."""
    structural = (model.spring_kind == STRUCT_WEFT) | (model.spring_kind == STRUCT_WARP)
    return float(model.spring_rest_length_m[structural].max()) if structural.any() else model.spacing_m


def _largest_move(a: np.ndarray, b: np.ndarray) -> float:
    """The largest distance [m] between matching rows of two vertex sets, rounded up."""
    return float(np.sqrt(((b - a) ** 2).sum(axis=1)).max()) * (1.0 + 1e-12) if a.size else 0.0
