"""Spring-spring self-collision detection over one step: broad phase, then narrow phase per pair.

For the solver's collision response (docs/method.md §4.2): every candidate pair from
:func:`fraytool.collision.broadphase.find_candidate_pairs_kernel` (boxes inflated by the
thickness, so every pair that comes within the thickness is a candidate) is tested with
:func:`fraytool.collision.ccd.edge_edge_ccd_kernel`; the pairs that hit are returned with their
earliest contact time t in [0, 1] (conservative: never later than the true first contact).
"""
from __future__ import annotations

import numba
import numpy as np

from fraytool.collision.broadphase import _check_spring_arrays, find_candidate_pairs_kernel
from fraytool.collision.ccd import edge_edge_ccd_kernel


@numba.njit(cache=True, fastmath=False)
def detect_edge_edge_collisions_kernel(
    # state in
    x_start: np.ndarray,
    x_end: np.ndarray,
    spring_a: np.ndarray,
    spring_b: np.ndarray,
    spring_alive: np.ndarray,
    spring_yarn: np.ndarray,
    # parameters
    thickness: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Colliding spring pairs (K, 2) int32 (i < j, lexicographic) and their times (K,) float64.

    Positions (P, 3) float64 [m] at the step start / end; spring_a, spring_b (S,) int32;
    spring_alive (S,) bool; spring_yarn (S,) int32 (< 0: never collides); thickness [m].
    """
    # margin = thickness >= thickness / 2 needed: safe against rounding of the box bounds.
    cand = find_candidate_pairs_kernel(
        x_start, x_end, spring_a, spring_b, spring_alive, spring_yarn, thickness, 0.0
    )
    k_count = cand.shape[0]
    hit_flag = np.zeros(k_count, dtype=np.bool_)
    hit_t = np.empty(k_count)
    for p in range(k_count):
        i = cand[p, 0]
        j = cand[p, 1]
        ai, bi, aj, bj = spring_a[i], spring_b[i], spring_a[j], spring_b[j]
        hit, t = edge_edge_ccd_kernel(
            x_start[ai], x_start[bi], x_start[aj], x_start[bj],
            x_end[ai], x_end[bi], x_end[aj], x_end[bj],
            thickness,
        )
        hit_flag[p] = hit
        hit_t[p] = t
    n_hit = 0
    for p in range(k_count):
        if hit_flag[p]:
            n_hit += 1
    pairs_out = np.empty((n_hit, 2), dtype=np.int32)
    t_out = np.empty(n_hit)
    q = 0
    for p in range(k_count):
        if hit_flag[p]:
            pairs_out[q, 0] = cand[p, 0]
            pairs_out[q, 1] = cand[p, 1]
            t_out[q] = hit_t[p]
            q += 1
    return pairs_out, t_out


def detect_edge_edge_collisions(
    x_start: np.ndarray,
    x_end: np.ndarray,
    spring_a: np.ndarray,
    spring_b: np.ndarray,
    spring_alive: np.ndarray,
    thickness: float,
    spring_yarn: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Spring pairs that collide during the step and their earliest contact times.

    Args:
        x_start, x_end: particle positions at the step start / end [m], shape (P, 3).
        spring_a, spring_b: end particles per spring, shape (S,), int.
        spring_alive: live springs, shape (S,), bool.
        thickness: contact distance between yarn centre lines [m], >= 0.
        spring_yarn: yarn id per spring (-1: not a yarn segment, skipped), shape (S,); None: all.

    Returns:
        pairs: (K, 2) int32 spring slots, i < j, sorted lexicographically (pairs that share an
            end particle are never tested);
        t: (K,) float64 earliest contact time in [0, 1] of each pair.
    """
    if not thickness >= 0.0:
        raise ValueError(f"thickness must be >= 0, got {thickness}")
    xs, xe, sa, sb, alive, yarn = _check_spring_arrays(
        x_start, x_end, spring_a, spring_b, spring_alive, spring_yarn
    )
    return detect_edge_edge_collisions_kernel(xs, xe, sa, sb, alive, yarn, float(thickness))
