"""Broad phase of spring-spring self-collision: sweep and prune in grid columns over swept boxes.

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

Algorithm (deterministic, no comparison sort, no hashing; all work on the compact list of the n
taking part, int32 indices, scratch arrays of size O(n + entries)):
  1. sweep axis ``w``: the longest side of the boxes' bounding box; the other two axes ``(u, v)``
     are cut into square columns of side ``c`` = the mean box extent, at least 1/16 of the
     largest (or the caller's ``cell_size``), doubled while there would be more than 4 n + 1024
     columns or 64 n + 1024 (box, column) entries (far-flung boxes: fewer, fuller columns).
     Column of a coordinate ``x``: ``floor((x - origin) * (1 / c))``, a monotone function, so a
     box covers exactly the columns between those of its two corners.
  2. boxes are ordered by ``q(lo_w)``, their low side on the sweep axis quantised to 2 n steps
     over the scene, ``q(x) = min(int((x - origin_w) * (2 n / extent_w)), 2 n)`` (monotone,
     counting sort), then one entry per (box, covered column) is bucketed by column with a stable
     counting sort: inside a column, entries come in increasing ``q(lo_w)``.
  3. sweep inside each column: entry e0 meets the later entries e1 while
     ``q(lo_w[e1]) <= q(hi_w[e0])``; as q is monotone, a later box that overlaps e0's box on ``w``
     is never past that bound (a scene of zero or overflowing extent gets q = 0: no pruning).
     The pair is tested only by the column holding the corner ``(max(lo_u), max(lo_v))`` of the
     two boxes' intersection, which both boxes cover (one bit per axis per entry: "this column is
     the box's first on that axis"; the pair is owned when the two entries' bits cover both
     axes): every overlapping pair is reported exactly once, without a dedup pass. Then the
     shared-end test and the exact overlap test on all three axes.
  4. pairs (i < j) are sorted lexicographically: counting sort by i, insertion sort of each
     (short) run by j.

Cost on the 64 x 64 Fig. 7 cloth (about 8000 yarn segments, 1300 pairs): about 0.7 ms per call,
of which 0.1 ms is the boxes, 0.3 ms the sweep. Kernel notes, to keep it so: no array variable is
reassigned inside a loop (numba then adds atomic reference counting to every iteration: the pair
buffer is sized first and the sweep reruns in the rare case it was too small); scratch memory
stays small (int32, one entry key = ``q << 2 | bits``, so n < 2^28), as large fresh arrays cost
page faults on every call.
"""
from __future__ import annotations

import math

import numba
import numpy as np

from fraytool.collision.interval import round_down, round_up

_EMPTY_PAIRS = np.empty((0, 2), dtype=np.int32)


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


@numba.njit(cache=True, fastmath=False)
def _listed_boxes(x_start, x_end, spring_a, spring_b, segments, margin, box_out, ends_out, bounds_inout):
    """Swept boxes of the listed springs (rows lo_x, lo_y, lo_z, hi_x, hi_y, hi_z of ``box``, as
    in :func:`swept_boxes_kernel`) and their end particles. ``bounds`` gets the scene box (rows
    0-2 lo, 3-5 hi), the sum (row 6) and the maximum (row 7) of the box extents (largest side).
    Returns False if a coordinate is not finite."""
    finite = True
    for k in range(3):
        bounds_inout[k] = math.inf
        bounds_inout[3 + k] = -math.inf
    ext_sum = 0.0
    ext_max = 0.0
    for p in range(segments.shape[0]):
        s = segments[p]
        a = spring_a[s]
        b = spring_b[s]
        ends_out[p, 0] = a
        ends_out[p, 1] = b
        ext = 0.0
        for k in range(3):
            lo = min(min(x_start[a, k], x_start[b, k]), min(x_end[a, k], x_end[b, k]))
            hi = max(max(x_start[a, k], x_start[b, k]), max(x_end[a, k], x_end[b, k]))
            if margin > 0.0:
                lo = round_down(lo - margin)
                hi = round_up(hi + margin)
            box_out[p, k] = lo
            box_out[p, 3 + k] = hi
            bounds_inout[k] = min(bounds_inout[k], lo)
            bounds_inout[3 + k] = max(bounds_inout[3 + k], hi)
            ext = max(ext, hi - lo)
            finite = finite and math.isfinite(lo) and math.isfinite(hi)
        ext_sum += ext
        ext_max = max(ext_max, ext)
    bounds_inout[6] = ext_sum
    bounds_inout[7] = ext_max
    return finite


@numba.njit(cache=True, fastmath=False)
def _column_ranges(box, au, av, ou, ov, inv_cell, col_range_out) -> int:
    """First and last column of every box along u and v (``col_range`` rows: first u, first v,
    last u, last v); returns the number of (box, column) entries."""
    entries = 0
    for p in range(box.shape[0]):
        if inv_cell == 0.0:
            col_range_out[p, 0] = col_range_out[p, 1] = col_range_out[p, 2] = col_range_out[p, 3] = 0
            entries += 1
            continue
        c0 = int(math.floor((box[p, au] - ou) * inv_cell))
        c1 = int(math.floor((box[p, av] - ov) * inv_cell))
        d0 = int(math.floor((box[p, 3 + au] - ou) * inv_cell))
        d1 = int(math.floor((box[p, 3 + av] - ov) * inv_cell))
        col_range_out[p, 0] = c0
        col_range_out[p, 1] = c1
        col_range_out[p, 2] = d0
        col_range_out[p, 3] = d1
        entries += (d0 - c0 + 1) * (d1 - c1 + 1)
    return entries


@numba.njit(cache=True, fastmath=False)
def _sweep_columns(col_start, ent_box, ent_key, q_hi, box, ends, order, aw, au, av, pi_inout, pj_out) -> int:
    """Step 3 of the module docstring: the owned, overlapping, non-adjacent pairs of every column,
    as (min, max) of their indices in ``order``; stores up to len(pi) of them, returns how many."""
    cap = pi_inout.shape[0]
    count = 0
    for col in range(col_start.shape[0] - 1):
        q_end = col_start[col + 1]
        for q0 in range(col_start[col], q_end - 1):
            p0 = ent_box[q0]
            first0 = ent_key[q0] & 3
            stop = (q_hi[p0] << 2) | 3
            lw = box[p0, aw]
            hw = box[p0, 3 + aw]
            lu = box[p0, au]
            hu = box[p0, 3 + au]
            lv = box[p0, av]
            hv = box[p0, 3 + av]
            a0 = ends[p0, 0]
            b0 = ends[p0, 1]
            for q1 in range(q0 + 1, q_end):
                key = ent_key[q1]
                if key > stop:
                    break  # this and every later box start past e0's box on the sweep axis
                if ((key & 3) | first0) != 3:
                    continue  # another column owns the pair
                p1 = ent_box[q1]
                a1 = ends[p1, 0]
                b1 = ends[p1, 1]
                if a0 == a1 or a0 == b1 or b0 == a1 or b0 == b1:
                    continue  # shared end particle: neighbours by construction
                if (box[p1, au] > hu or lu > box[p1, 3 + au] or box[p1, av] > hv or lv > box[p1, 3 + av]
                        or box[p1, aw] > hw or lw > box[p1, 3 + aw]):
                    continue
                if count < cap:
                    o0 = order[p0]
                    o1 = order[p1]
                    pi_inout[count] = min(o0, o1)
                    pj_out[count] = max(o0, o1)
                count += 1
    return count


@numba.njit(cache=True, fastmath=False)
def _sorted_slot_pairs(pi, pj, count, segments) -> np.ndarray:
    """(count, 2) int32 spring slots sorted by (i, j) from pairs of indices into ``segments``
    (increasing, so the order carries over): counting sort by i, insertion sort of each run by j."""
    n = segments.shape[0]
    run_end = np.zeros(n + 1, dtype=np.int64)
    for k in range(count):
        run_end[pi[k] + 1] += 1
    for p in range(n):
        run_end[p + 1] += run_end[p]
    out = np.empty((count, 2), dtype=np.int32)
    for k in range(count):
        i = pi[k]
        q = run_end[i]
        out[q, 1] = pj[k]
        run_end[i] = q + 1
    q0 = 0
    for p in range(n):
        q1 = run_end[p]
        for q in range(q0 + 1, q1):
            v = out[q, 1]
            r = q - 1
            while r >= q0 and out[r, 1] > v:
                out[r + 1, 1] = out[r, 1]
                r -= 1
            out[r + 1, 1] = v
        for q in range(q0, q1):
            out[q, 0] = segments[p]
            out[q, 1] = segments[out[q, 1]]
        q0 = q1
    return out


@numba.njit(cache=True, fastmath=False)
def candidate_pairs_of_segments_kernel(
    # state in
    x_start: np.ndarray,
    x_end: np.ndarray,
    spring_a: np.ndarray,
    spring_b: np.ndarray,
    spring_alive: np.ndarray,
    segments: np.ndarray,
    # parameters
    margin: float,
    cell_size: float,
) -> np.ndarray:
    """:func:`find_candidate_pairs_kernel` over a given list of springs: ``segments`` (M,) int32,
    strictly increasing spring slots (dead ones among them are skipped), e.g. the yarn segments
    of a model, computed once. Raises ValueError if the list is not increasing or a live listed
    spring has a non-finite end position. Returns (K, 2) int32, i < j, sorted lexicographically."""
    m = segments.shape[0]
    live = np.empty(m, dtype=np.int32)
    n = 0
    increasing = True
    for k in range(m):
        s = segments[k]
        increasing = increasing and (k == 0 or s > segments[k - 1])
        if spring_alive[s]:
            live[n] = s
            n += 1
    if not increasing:
        raise ValueError("candidate_pairs_of_segments: segments must be strictly increasing")
    live = live[:n]

    # 1. boxes in slot order, sweep axis
    box_s = np.empty((n, 6))
    ends_s = np.empty((n, 2), dtype=np.int32)
    bounds = np.empty(8)
    if not _listed_boxes(x_start, x_end, spring_a, spring_b, live, margin, box_s, ends_s, bounds):
        raise ValueError("find_candidate_pairs: non-finite position of a live spring")
    if n < 2:
        return _EMPTY_PAIRS.copy()
    aw = 0
    for k in range(1, 3):
        if bounds[3 + k] - bounds[k] > bounds[3 + aw] - bounds[aw]:
            aw = k
    au = 1 if aw == 0 else 0
    av = 1 if aw == 2 else 2
    ow = bounds[aw]
    ou = bounds[au]
    ov = bounds[av]
    scene = bounds[3 + aw] - ow  # the longest side
    cell = cell_size if cell_size > 0.0 else max(bounds[6] / n, bounds[7] / 16.0)
    # At most 2^20 columns per axis (int32 column indices whatever the input), sizes positive; a
    # scene too wide for float64 (|coordinates| near 1e308) gets a single column.
    cell = max(cell, scene * 2.0**-20, 1e-300)

    # 2. boxes ordered by q(lo_w) (stable counting sort); columns; entries by column (stable)
    steps = 2 * n
    q_scale = steps / scene if 0.0 < scene < math.inf else 0.0
    q_lo_s = np.empty(n, dtype=np.int32)
    q_start = np.zeros(steps + 2, dtype=np.int32)
    for p in range(n):
        q = min(int((box_s[p, aw] - ow) * q_scale), steps) if q_scale > 0.0 else 0
        q_lo_s[p] = q
        q_start[q + 1] += 1
    for q in range(steps + 1):
        q_start[q + 1] += q_start[q]
    order = np.empty(n, dtype=np.int32)  # sorted position -> index into live
    for p in range(n):
        q = q_lo_s[p]
        order[q_start[q]] = p
        q_start[q] += 1
    box = np.empty((n, 6))
    ends = np.empty((n, 2), dtype=np.int32)
    q_lo = np.empty(n, dtype=np.int32)
    q_hi = np.empty(n, dtype=np.int32)
    for r in range(n):
        p = order[r]
        for k in range(6):
            box[r, k] = box_s[p, k]
        ends[r, 0] = ends_s[p, 0]
        ends[r, 1] = ends_s[p, 1]
        q_lo[r] = q_lo_s[p]
        q_hi[r] = min(int((box[r, 3 + aw] - ow) * q_scale), steps) if q_scale > 0.0 else 0
    col_range = np.empty((n, 4), dtype=np.int32)
    while True:
        inv_cell = 1.0 / cell if math.isfinite(scene) else 0.0
        gu = int(math.floor((bounds[3 + au] - ou) * inv_cell)) + 1 if inv_cell > 0.0 else 1
        gv = int(math.floor((bounds[3 + av] - ov) * inv_cell)) + 1 if inv_cell > 0.0 else 1
        if gu * gv <= 4 * n + 1024:
            entries = _column_ranges(box, au, av, ou, ov, inv_cell, col_range)
            if entries <= 64 * n + 1024:
                break
        cell *= 2.0
    columns = gu * gv
    col_start = np.zeros(columns + 1, dtype=np.int64)
    for r in range(n):
        for cu in range(col_range[r, 0], col_range[r, 2] + 1):
            base = cu * gv
            for cv in range(col_range[r, 1], col_range[r, 3] + 1):
                col_start[base + cv] += 1
    total = 0
    for col in range(columns + 1):  # exclusive prefix sums: first entry of each column
        c = col_start[col]
        col_start[col] = total
        total += c
    ent_box = np.empty(entries, dtype=np.int32)
    ent_key = np.empty(entries, dtype=np.int32)  # q(lo_w) << 2 | first-column bits (q <= 2 n < 2^29)
    for r in range(n):
        u0 = col_range[r, 0]
        v0 = col_range[r, 1]
        for cu in range(u0, col_range[r, 2] + 1):
            bit_u = 1 if cu == u0 else 0
            base = cu * gv
            for cv in range(v0, col_range[r, 3] + 1):
                e = col_start[base + cv]
                col_start[base + cv] = e + 1
                ent_box[e] = r
                ent_key[e] = (q_lo[r] << 2) | bit_u | (2 if cv == v0 else 0)
    for col in range(columns, 0, -1):  # col_start[col] is now the end of column col
        col_start[col] = col_start[col - 1]
    col_start[0] = 0

    # 3. sweep; the pair buffer grows (and the sweep reruns) in the rare case it is too small
    cap = 2 * n + 16
    while True:
        pi = np.empty(cap, dtype=np.int32)
        pj = np.empty(cap, dtype=np.int32)
        count = _sweep_columns(col_start, ent_box, ent_key, q_hi, box, ends, order, aw, au, av, pi, pj)
        if count <= cap:
            break
        cap = count

    # 4. lexicographic order of the spring slots
    return _sorted_slot_pairs(pi, pj, count, live)


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
    margin [m] added to every side of every box; cell_size [m] column side, a tuning knob that does
    not change the result (<= 0: the mean box extent, >= largest / 16).

    Returns: (K, 2) int32, i < j, sorted lexicographically.
    """
    spring_count = spring_a.shape[0]
    segments = np.empty(spring_count, dtype=np.int32)
    n = 0
    for s in range(spring_count):
        if spring_alive[s] and spring_yarn[s] >= 0:
            segments[n] = s
            n += 1
    return candidate_pairs_of_segments_kernel(x_start, x_end, spring_a, spring_b, spring_alive, segments[:n],
                                              margin, cell_size)


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
        cell_size: side of the sweep's grid columns [m], for speed only (the result does not
            depend on it); <= 0 picks the mean box extent (at least the largest / 16).

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
