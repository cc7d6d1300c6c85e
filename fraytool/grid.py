"""Geometry of the crossing grid shared by the simulation (splits, §3.4) and the renderer (§5).

NumPy and numba on positions; no simulation or rendering state. The renderer calls these on every
frame for every crossing (a 512 x 512 cloth: 262,144), so the per-crossing work is one numba loop
each, with the arithmetic of the NumPy expressions they replaced (cross product and normalisation
term by term, no fused multiply-add), so the results are the same to the bit.
"""
from __future__ import annotations

import math

import numba
import numpy as np


def yarn_neighbours(crossing_weft_springs: np.ndarray, crossing_warp_springs: np.ndarray,
                    spring_crossing_a: np.ndarray, spring_crossing_b: np.ndarray) -> np.ndarray:
    """(i-1, i+1, j-1, j+1) neighbour of every crossing through its structural spring slots, the crossing
    itself where it has none (the border, a shaped panel's too): shape (4, C), int64."""
    c = np.arange(crossing_weft_springs.shape[0])
    out = np.empty((4, c.size), np.int64)
    for k, (springs, side) in enumerate(((crossing_weft_springs, 0), (crossing_weft_springs, 1),
                                         (crossing_warp_springs, 0), (crossing_warp_springs, 1))):
        s = springs[:, side]
        end = (spring_crossing_a if side == 0 else spring_crossing_b)[np.maximum(s, 0)]
        out[k] = np.where(s >= 0, end, c)
    return out


def crossing_normals(crossing_position_m: np.ndarray, warp_yarns: int, weft_yarns: int,
                     neighbours: np.ndarray | None = None) -> np.ndarray:
    """Unit cloth normal n_c at every crossing (docs/method.md §3.3, Fig. 3a).

    n_c = normalise((x_{i+1,j} - x_{i-1,j}) x (x_{i,j+1} - x_{i,j-1})), with one-sided differences
    at the border. Degenerate crossings (neighbours collinear) get (0, 0, 0) replaced by the mean
    normal of the cloth, or +z if that is degenerate too. Shape (C, 3) in, (C, 3) out, float64.
    A shaped panel (not every place of the grid a crossing) gives `neighbours` (yarn_neighbours).
    """
    x = np.ascontiguousarray(crossing_position_m, dtype=np.float64).reshape(-1, 3)
    n = np.empty_like(x)
    if neighbours is None:
        nb = np.zeros((4, 0), np.int64)
        if x.shape[0] != warp_yarns * weft_yarns:
            raise ValueError(f"{x.shape[0]} crossings on a {warp_yarns} x {weft_yarns} grid")
    else:
        nb = np.ascontiguousarray(neighbours, dtype=np.int64)
    if len(x):
        _raw_normals(x, int(warp_yarns), int(weft_yarns), nb, n)
    return _normalised(n)


@numba.njit(cache=True)
def _raw_normals(x, W, H, neighbours, n_out):  # pragma: no cover - numba
    """(x_{i+1} - x_{i-1}) x (x_{j+1} - x_{j-1}) per crossing into n_out: through `neighbours` (4, C)
    when it has columns, else over the full W x H grid with one-sided differences at its border."""
    C = x.shape[0]
    full = neighbours.shape[1] == 0
    for c in range(C):
        if full:
            j, i = c // W, c % W
            u0 = c - 1 if i > 0 else c
            u1 = c + 1 if i < W - 1 else c
            v0 = c - W if j > 0 else c
            v1 = c + W if j < H - 1 else c
        else:
            u0, u1, v0, v1 = neighbours[0, c], neighbours[1, c], neighbours[2, c], neighbours[3, c]
        a0, a1, a2 = x[u1, 0] - x[u0, 0], x[u1, 1] - x[u0, 1], x[u1, 2] - x[u0, 2]
        b0, b1, b2 = x[v1, 0] - x[v0, 0], x[v1, 1] - x[v0, 1], x[v1, 2] - x[v0, 2]
        n_out[c, 0] = a1 * b2 - a2 * b1
        n_out[c, 1] = a2 * b0 - a0 * b2
        n_out[c, 2] = a0 * b1 - a1 * b0


@numba.njit(cache=True)
def _normalise_rows(n_inout):  # pragma: no cover - numba
    """Rows of n_inout made unit in place where their length exceeds 1e-300; returns how many did not."""
    bad = 0
    for c in range(n_inout.shape[0]):
        x, y, z = n_inout[c, 0], n_inout[c, 1], n_inout[c, 2]
        length = math.sqrt(x * x + y * y + z * z)
        if length > 1e-300:
            n_inout[c, 0] /= length
            n_inout[c, 1] /= length
            n_inout[c, 2] /= length
        else:
            bad += 1
    return bad


def _normalised(n: np.ndarray) -> np.ndarray:
    """Rows of n made unit; zero rows get the mean direction (or +z)."""
    if _normalise_rows(n) == 0:
        return n
    good = np.linalg.norm(n, axis=1) > 1e-300
    mean = n[good].sum(axis=0) if good.any() else np.zeros(3)
    ml = np.linalg.norm(mean)
    n[~good] = mean / ml if ml > 0 else np.array([0.0, 0.0, 1.0])
    return n


def base_yarn_points(crossing_position_m: np.ndarray, normals: np.ndarray, weft_on_top: np.ndarray,
                     thickness_m: float) -> tuple[np.ndarray, np.ndarray]:
    """(weft point, warp point) of each base-level crossing: x ± (T/2) n_c, the weft going up where
    the weave puts it on top (docs/method.md §3.4 and §5). Each (C, 3) float64."""
    x = np.ascontiguousarray(crossing_position_m, dtype=np.float64).reshape(-1, 3)
    weft, warp = np.empty_like(x), np.empty_like(x)
    _base_points(x, np.ascontiguousarray(normals, dtype=np.float64).reshape(-1, 3),
                 np.ascontiguousarray(weft_on_top, dtype=np.bool_).ravel(), float(thickness_m), weft, warp)
    return weft, warp


@numba.njit(cache=True)
def _base_points(x, n, weft_on_top, thickness_m, weft_out, warp_out):  # pragma: no cover - numba
    for c in range(x.shape[0]):
        s = 0.5 * thickness_m if weft_on_top[c] else -0.5 * thickness_m
        for k in range(3):
            weft_out[c, k] = x[c, k] + s * n[c, k]
            warp_out[c, k] = x[c, k] - s * n[c, k]
