"""Priority queue of (t, u, v) boxes for the CCD search, earliest ``T.lo`` first (numba kernels).

A binary min-heap stored in a float64 array, one row per box:
``[t0, t1, u0, u1, v0, v1, flag, seq]`` where ``flag`` is caller data and ``seq`` the insertion
number. Order: smaller ``t0`` first; among equal ``t0`` the most recently pushed first (larger
``seq``), so that splits in u or v are explored depth first and the queue stays short. The order
is total, hence the search is deterministic.
"""
from __future__ import annotations

import numba
import numpy as np

ROW = 8
"""Floats per box row."""


@numba.njit(cache=True, fastmath=False, inline="always")
def _before(heap: np.ndarray, i: int, j: int) -> bool:
    """Row i comes out before row j."""
    if heap[i, 0] != heap[j, 0]:
        return heap[i, 0] < heap[j, 0]
    return heap[i, 7] > heap[j, 7]


@numba.njit(cache=True, fastmath=False, inline="always")
def _swap(heap_inout: np.ndarray, i: int, j: int) -> None:
    for k in range(ROW):
        tmp = heap_inout[i, k]
        heap_inout[i, k] = heap_inout[j, k]
        heap_inout[j, k] = tmp


@numba.njit(cache=True, fastmath=False)
def queue_push(
    heap_inout: np.ndarray,
    size: int,
    seq: int,
    t0: float,
    t1: float,
    u0: float,
    u1: float,
    v0: float,
    v1: float,
    flag: float,
) -> np.ndarray:
    """Insert a box at position ``size`` (the caller increments size); returns the heap array,
    reallocated with twice the rows when full."""
    if size == heap_inout.shape[0]:
        bigger = np.empty((2 * heap_inout.shape[0], ROW))
        bigger[:size] = heap_inout[:size]
        heap_inout = bigger
    heap_inout[size, 0] = t0
    heap_inout[size, 1] = t1
    heap_inout[size, 2] = u0
    heap_inout[size, 3] = u1
    heap_inout[size, 4] = v0
    heap_inout[size, 5] = v1
    heap_inout[size, 6] = flag
    heap_inout[size, 7] = seq
    i = size
    while i > 0:
        parent = (i - 1) // 2
        if not _before(heap_inout, i, parent):
            break
        _swap(heap_inout, i, parent)
        i = parent
    return heap_inout


@numba.njit(cache=True, fastmath=False)
def queue_pop(heap_inout: np.ndarray, size: int, out_out: np.ndarray) -> None:
    """Copy the first box into ``out`` (ROW,) and remove it (the caller decrements size)."""
    for k in range(ROW):
        out_out[k] = heap_inout[0, k]
    last = size - 1
    for k in range(ROW):
        heap_inout[0, k] = heap_inout[last, k]
    i = 0
    while True:
        left = 2 * i + 1
        if left >= last:
            break
        best = left
        right = left + 1
        if right < last and _before(heap_inout, right, left):
            best = right
        if not _before(heap_inout, best, i):
            break
        _swap(heap_inout, i, best)
        i = best
