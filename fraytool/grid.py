"""Geometry of the crossing grid shared by the simulation (splits, §3.4) and the renderer (§5).

Pure NumPy on positions; no simulation or rendering state.
"""
from __future__ import annotations

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
    if neighbours is not None:
        x = np.asarray(crossing_position_m, dtype=np.float64)
        n = np.cross(x[neighbours[1]] - x[neighbours[0]], x[neighbours[3]] - x[neighbours[2]])
        return _normalised(n)
    x = np.asarray(crossing_position_m, dtype=np.float64).reshape(weft_yarns, warp_yarns, 3)
    du = np.empty_like(x)
    dv = np.empty_like(x)
    du[:, 1:-1] = x[:, 2:] - x[:, :-2]
    du[:, 0] = x[:, 1] - x[:, 0]
    du[:, -1] = x[:, -1] - x[:, -2]
    dv[1:-1] = x[2:] - x[:-2]
    dv[0] = x[1] - x[0]
    dv[-1] = x[-1] - x[-2]
    return _normalised(np.cross(du, dv).reshape(-1, 3))


def _normalised(n: np.ndarray) -> np.ndarray:
    """Rows of n made unit; zero rows get the mean direction (or +z)."""
    length = np.linalg.norm(n, axis=1)
    good = length > 1e-300
    n[good] /= length[good, None]
    if not good.all():
        mean = n[good].sum(axis=0) if good.any() else np.zeros(3)
        ml = np.linalg.norm(mean)
        n[~good] = mean / ml if ml > 0 else np.array([0.0, 0.0, 1.0])
    return n


def base_yarn_points(crossing_position_m: np.ndarray, normals: np.ndarray, weft_on_top: np.ndarray,
                     thickness_m: float) -> tuple[np.ndarray, np.ndarray]:
    """(weft point, warp point) of each base-level crossing: x ± (T/2) n_c, the weft going up where
    the weave puts it on top (docs/method.md §3.4 and §5)."""
    s = np.where(weft_on_top, 0.5 * thickness_m, -0.5 * thickness_m)[:, None]
    return crossing_position_m + s * normals, crossing_position_m - s * normals
