"""Nearest triangle of a mesh to each of a set of points (the rest pose of crossings pinned to a mesh body's
surface; fraytool.sim.surface_pins). Brute force over the triangles: it runs once, when an attachment is added."""
from __future__ import annotations

import numba as nb
import numpy as np

from fraytool.geometry.triangles import closest_on_triangle


@nb.njit(cache=True, fastmath=False)
def nearest_triangles(points_m, vertices_m, triangles, triangle_out, barycentric_out, distance_m_out):
    """For each point p (P, 3): the triangle (index into `triangles`, (T, 3) into `vertices_m`) whose closest
    point to p is nearest, that point's barycentric weights (P, 3) and its distance [m] (P,)."""
    for p in range(points_m.shape[0]):
        best = np.inf
        px, py, pz = points_m[p, 0], points_m[p, 1], points_m[p, 2]
        for t in range(triangles.shape[0]):
            a, b, c = triangles[t, 0], triangles[t, 1], triangles[t, 2]
            qx, qy, qz, wa, wb, wc = closest_on_triangle(
                px, py, pz, vertices_m[a, 0], vertices_m[a, 1], vertices_m[a, 2], vertices_m[b, 0],
                vertices_m[b, 1], vertices_m[b, 2], vertices_m[c, 0], vertices_m[c, 1], vertices_m[c, 2])
            d = (px - qx) * (px - qx) + (py - qy) * (py - qy) + (pz - qz) * (pz - qz)
            if d < best:
                best = d
                triangle_out[p] = t
                barycentric_out[p, 0] = wa
                barycentric_out[p, 1] = wb
                barycentric_out[p, 2] = wc
        distance_m_out[p] = np.sqrt(best)
