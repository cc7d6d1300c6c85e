"""Broad phase of spring-spring self-collision: a spatial hash of swept bounding boxes.

Each candidate spring s (end particles ``spring_a[s]``, ``spring_b[s]``) gets the axis-aligned box
of its four end positions at the start and the end of the step, inflated by ``margin`` on every
side (outward rounded when ``margin > 0``) -- it contains every point of the moving segment and
everything within ``margin`` of it. Two springs are a candidate pair when their boxes overlap
(closed intervals on all three axes), so any pair whose centre lines come within ``2 * margin``
during the step is reported.

Pair rule (exact):
  * a spring takes part only if ``spring_alive[s]`` and, when ``spring_yarn`` is given,
    ``spring_yarn[s] >= 0`` (-1 marks non-yarn springs such as bend or shear springs);
  * a pair (i, j) is skipped when the springs share an end particle
    (``{a_i, b_i}`` meets ``{a_j, b_j}``): adjacent segments of one yarn, and yarns meeting at a
    common crossing mass, touch by construction.

Algorithm (uniform grid, hashed, deterministic; O(n) work besides the pair tests inside cells):
  1. cell size ``c`` = the mean box extent, at least 1/16 of the largest (or the caller's
     ``cell_size``): a typical box covers 1-2 cells per axis and none more than 17, so a few long
     (stretched, flailing) springs do not crowd every cell; cell of a coordinate ``x``: ``floor((x - origin) * (1 / c))``, a
     monotone function, so a box covers exactly the cells between those of its two corners.
  2. one entry (spring, cell) per covered cell; entries are bucketed by a hash of the cell with a
     stable counting sort over a power-of-two table (no comparison sort, no randomness).
  3. inside a bucket, entries of the same cell are tested pairwise. A pair is emitted only by the
     cell holding the minimum corner of the two boxes' intersection, ``max(lo_i, lo_j)``, which
     both boxes cover: every overlapping pair is emitted exactly once, without a dedup pass.
  4. pairs (i < j) are sorted lexicographically by two stable counting sorts (by j, then by i).

Reference: M. Teschner, B. Heidelberger, M. Mueller, D. Pomeranets, M. Gross, "Optimized Spatial
Hashing for Collision Detection of Deformable Objects", VMV 2003 (hash function and grid).
"""
from __future__ import annotations

import math

import numba
import numpy as np

from fraytool.collision.interval import round_down, round_up


@numba.njit(cache=True, fastmath=False)
def swept_boxes_kernel(
    # state in
    x_start: np.ndarray,
    x_end: np.ndarray,
    spring_a: np.ndarray,
    spring_b: np.ndarray,
    # parameters
    margin: float,
    # out
    box_lo_out: np.ndarray,
    box_hi_out: np.ndarray,
) -> None:
    """Swept box of every spring [m], shape (S, 3) each: min/max of the 4 end positions -/+ margin."""
    for s in range(spring_a.shape[0]):
        a = spring_a[s]
        b = spring_b[s]
        for k in range(3):
            lo = min(min(x_start[a, k], x_start[b, k]), min(x_end[a, k], x_end[b, k]))
            hi = max(max(x_start[a, k], x_start[b, k]), max(x_end[a, k], x_end[b, k]))
            if margin > 0.0:
                lo = round_down(lo - margin)
                hi = round_up(hi + margin)
            box_lo_out[s, k] = lo
            box_hi_out[s, k] = hi


@numba.njit(cache=True, fastmath=False, inline="always")
def _cell_hash(cx: int, cy: int, cz: int, mask: int) -> int:
    """Bucket of a cell (Teschner et al. 2003 primes), wrapping 64-bit arithmetic."""
    h = (cx * 73856093) ^ (cy * 19349663) ^ (cz * 83492791)
    return h & mask


@numba.njit(cache=True, fastmath=False)
def _sort_pairs(pi: np.ndarray, pj: np.ndarray, count: int, spring_count: int) -> np.ndarray:
    """(count, 2) int32 pairs sorted by (i, j): stable counting sort by j, then by i."""
    tmp = np.empty(count, dtype=np.int64)
    out = np.empty((count, 2), dtype=np.int32)
    for pass_ in range(2):
        key = pj if pass_ == 0 else pi
        start = np.zeros(spring_count + 1, dtype=np.int64)
        for p in range(count):
            start[key[p] + 1] += 1
        for s in range(spring_count):
            start[s + 1] += start[s]
        if pass_ == 0:
            for p in range(count):
                k = key[p]
                tmp[start[k]] = p
                start[k] += 1
        else:
            for p in range(count):
                q = tmp[p]
                k = key[q]
                out[start[k], 0] = pi[q]
                out[start[k], 1] = pj[q]
                start[k] += 1
    return out


@numba.njit(cache=True, fastmath=False)
def find_candidate_pairs_kernel(
    # state in
    x_start: np.ndarray,
    x_end: np.ndarray,
    spring_a: np.ndarray,
    spring_b: np.ndarray,
    spring_alive: np.ndarray,
    spring_yarn: np.ndarray,
    # parameters
    margin: float,
    cell_size: float,
) -> np.ndarray:
    """Candidate spring pairs whose swept boxes overlap; see the module docstring for the rule.

    Args: positions (P, 3) float64 [m] at step start/end; spring_a, spring_b (S,) int32;
    spring_alive (S,) bool; spring_yarn (S,) int32 (< 0: not a yarn segment, never collides);
    margin [m] added to every side of every box; cell_size [m] (<= 0: the mean box extent, >= largest / 16).

    Returns: (K, 2) int32, i < j, sorted lexicographically.
    """
    spring_count = spring_a.shape[0]
    box_lo = np.empty((spring_count, 3))
    box_hi = np.empty((spring_count, 3))
    swept_boxes_kernel(x_start, x_end, spring_a, spring_b, margin, box_lo, box_hi)

    # Candidate springs, in increasing slot order (keeps every later step deterministic).
    active = np.empty(spring_count, dtype=np.int64)
    n = 0
    for s in range(spring_count):
        # Early return per spring: dead springs and non-yarn springs never collide.
        if not spring_alive[s] or spring_yarn[s] < 0:
            continue
        for k in range(3):
            if not (math.isfinite(box_lo[s, k]) and math.isfinite(box_hi[s, k])):
                raise ValueError("find_candidate_pairs: non-finite position of a live spring")
        active[n] = s
        n += 1
    if n < 2:
        return np.empty((0, 2), dtype=np.int32)

    origin = np.empty(3)
    top = np.empty(3)
    extent = 0.0
    extent_sum = 0.0
    for k in range(3):
        origin[k] = math.inf
        top[k] = -math.inf
    for p in range(n):
        s = active[p]
        box_extent = 0.0
        for k in range(3):
            origin[k] = min(origin[k], box_lo[s, k])
            top[k] = max(top[k], box_hi[s, k])
            box_extent = max(box_extent, box_hi[s, k] - box_lo[s, k])
        extent = max(extent, box_extent)
        extent_sum += box_extent
    scene = 0.0
    for k in range(3):
        scene = max(scene, top[k] - origin[k])
    # Cell: the mean box extent, so a typical box covers 1-2 cells per axis and a cell holds a
    # few boxes, whatever a handful of long (stretched, flailing) springs do; at least 1/16 of the
    # largest extent, so no box covers more than 17 cells per axis.
    cell = cell_size if cell_size > 0.0 else max(extent_sum / n, extent / 16.0)
    # Keep cell coordinates below 2^40 (and the size positive) for degenerate inputs.
    cell = max(cell, scene * 2.0**-40, 1e-300)
    inv_cell = 1.0 / cell

    # Cell ranges per active spring and the number of entries.
    c_lo = np.empty((n, 3), dtype=np.int64)
    c_hi = np.empty((n, 3), dtype=np.int64)
    entry_count = 0
    for p in range(n):
        s = active[p]
        cnt = 1
        for k in range(3):
            c_lo[p, k] = int(math.floor((box_lo[s, k] - origin[k]) * inv_cell))
            c_hi[p, k] = int(math.floor((box_hi[s, k] - origin[k]) * inv_cell))
            cnt *= c_hi[p, k] - c_lo[p, k] + 1
        entry_count += cnt

    table = 1
    while table < 2 * entry_count:
        table *= 2
    mask = table - 1
    ent_p = np.empty(entry_count, dtype=np.int64)
    ent_cell = np.empty((entry_count, 3), dtype=np.int64)
    ent_bucket = np.empty(entry_count, dtype=np.int64)
    e = 0
    for p in range(n):
        for cx in range(c_lo[p, 0], c_hi[p, 0] + 1):
            for cy in range(c_lo[p, 1], c_hi[p, 1] + 1):
                for cz in range(c_lo[p, 2], c_hi[p, 2] + 1):
                    ent_p[e] = p
                    ent_cell[e, 0] = cx
                    ent_cell[e, 1] = cy
                    ent_cell[e, 2] = cz
                    ent_bucket[e] = _cell_hash(cx, cy, cz, mask)
                    e += 1

    # Stable counting sort of the entries by bucket.
    start = np.zeros(table + 1, dtype=np.int64)
    for e in range(entry_count):
        start[ent_bucket[e] + 1] += 1
    for b in range(table):
        start[b + 1] += start[b]
    order = np.empty(entry_count, dtype=np.int64)
    fill = start[:table].copy()
    for e in range(entry_count):
        b = ent_bucket[e]
        order[fill[b]] = e
        fill[b] += 1

    cap = max(16, 4 * n)
    pi = np.empty(cap, dtype=np.int64)
    pj = np.empty(cap, dtype=np.int64)
    count = 0
    for b in range(table):
        for q0 in range(start[b], start[b + 1]):
            e0 = order[q0]
            p0 = ent_p[e0]
            s0 = active[p0]
            for q1 in range(q0 + 1, start[b + 1]):
                e1 = order[q1]
                # different cells that share a bucket (hash collision)
                if (
                    ent_cell[e0, 0] != ent_cell[e1, 0]
                    or ent_cell[e0, 1] != ent_cell[e1, 1]
                    or ent_cell[e0, 2] != ent_cell[e1, 2]
                ):
                    continue
                p1 = ent_p[e1]
                s1 = active[p1]  # s0 < s1: entries are stable-sorted in slot order
                overlap = True
                owner = True
                for k in range(3):
                    if box_lo[s0, k] > box_hi[s1, k] or box_lo[s1, k] > box_hi[s0, k]:
                        overlap = False
                        break
                    # only the cell holding max(lo_0, lo_1) reports the pair
                    corner = max(c_lo[p0, k], c_lo[p1, k])
                    if corner != ent_cell[e0, k]:
                        owner = False
                if not overlap or not owner:
                    continue
                a0 = spring_a[s0]
                b0 = spring_b[s0]
                a1 = spring_a[s1]
                b1 = spring_b[s1]
                if a0 == a1 or a0 == b1 or b0 == a1 or b0 == b1:
                    continue  # shared end particle: neighbours by construction
                if count == cap:
                    cap *= 2
                    pi_new = np.empty(cap, dtype=np.int64)
                    pj_new = np.empty(cap, dtype=np.int64)
                    pi_new[:count] = pi[:count]
                    pj_new[:count] = pj[:count]
                    pi = pi_new
                    pj = pj_new
                pi[count] = s0
                pj[count] = s1
                count += 1
    return _sort_pairs(pi, pj, count, spring_count)


def _check_spring_arrays(
    x_start: np.ndarray,
    x_end: np.ndarray,
    spring_a: np.ndarray,
    spring_b: np.ndarray,
    spring_alive: np.ndarray,
    spring_yarn: np.ndarray | None,
) -> tuple[np.ndarray, ...]:
    """Convert to the kernel dtypes and check shapes and index ranges; raises ValueError."""
    xs = np.ascontiguousarray(x_start, dtype=np.float64)
    xe = np.ascontiguousarray(x_end, dtype=np.float64)
    if xs.ndim != 2 or xs.shape[1] != 3 or xe.shape != xs.shape:
        raise ValueError(f"x_start, x_end must both have shape (P, 3), got {xs.shape}, {xe.shape}")
    sa = np.ascontiguousarray(spring_a, dtype=np.int32)
    sb = np.ascontiguousarray(spring_b, dtype=np.int32)
    alive = np.ascontiguousarray(spring_alive, dtype=np.bool_)
    count = sa.shape[0]
    if sa.ndim != 1 or sb.shape != sa.shape or alive.shape != sa.shape:
        raise ValueError(
            f"spring_a, spring_b, spring_alive must have one shape (S,), got {sa.shape}, "
            f"{sb.shape}, {alive.shape}"
        )
    if spring_yarn is None:
        yarn = np.zeros(count, dtype=np.int32)
    else:
        yarn = np.ascontiguousarray(spring_yarn, dtype=np.int32)
        if yarn.shape != sa.shape:
            raise ValueError(f"spring_yarn must have shape {sa.shape}, got {yarn.shape}")
    used = alive & (yarn >= 0)
    if count and used.any():
        ends = np.concatenate([sa[used], sb[used]])
        if ends.min() < 0 or ends.max() >= xs.shape[0]:
            raise ValueError(f"spring end index out of range [0, {xs.shape[0]})")
        if not (np.isfinite(xs[ends]).all() and np.isfinite(xe[ends]).all()):
            raise ValueError("non-finite position at an end of a live spring")
    return xs, xe, sa, sb, alive, yarn


def find_candidate_pairs(
    x_start: np.ndarray,
    x_end: np.ndarray,
    spring_a: np.ndarray,
    spring_b: np.ndarray,
    spring_alive: np.ndarray,
    margin: float = 0.0,
    spring_yarn: np.ndarray | None = None,
    cell_size: float = 0.0,
) -> np.ndarray:
    """Spring pairs whose swept boxes (inflated by ``margin``) overlap during the step.

    Args:
        x_start, x_end: particle positions at the step start / end [m], shape (P, 3).
        spring_a, spring_b: end particles of each spring, shape (S,), int.
        spring_alive: live springs, shape (S,), bool.
        margin: added to every side of every box [m] (use the contact thickness).
        spring_yarn: yarn id per spring, shape (S,), -1 for non-yarn springs (skipped);
            None: every live spring takes part.
        cell_size: grid cell [m]; <= 0 picks the mean box extent (at least the largest / 16).

    Returns:
        (K, 2) int32 array of spring slots (i < j), sorted lexicographically; pairs sharing an
        end particle are left out (see the module docstring).
    """
    if not margin >= 0.0:
        raise ValueError(f"margin must be >= 0, got {margin}")
    xs, xe, sa, sb, alive, yarn = _check_spring_arrays(
        x_start, x_end, spring_a, spring_b, spring_alive, spring_yarn
    )
    return find_candidate_pairs_kernel(xs, xe, sa, sb, alive, yarn, float(margin), float(cell_size))
