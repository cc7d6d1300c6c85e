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
def _swap(heap: np.ndarray, i: int, j: int) -> None:
    for k in range(ROW):
        tmp = heap[i, k]
        heap[i, k] = heap[j, k]
        heap[j, k] = tmp


@numba.njit(cache=True, fastmath=False)
def queue_push(
    heap: np.ndarray,
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
    if size == heap.shape[0]:
        bigger = np.empty((2 * heap.shape[0], ROW))
        bigger[:size] = heap[:size]
        heap = bigger
    heap[size, 0] = t0
    heap[size, 1] = t1
    heap[size, 2] = u0
    heap[size, 3] = u1
    heap[size, 4] = v0
    heap[size, 5] = v1
    heap[size, 6] = flag
    heap[size, 7] = seq
    i = size
    while i > 0:
        parent = (i - 1) // 2
        if not _before(heap, i, parent):
            break
        _swap(heap, i, parent)
        i = parent
    return heap


@numba.njit(cache=True, fastmath=False)
def queue_pop(heap: np.ndarray, size: int, out: np.ndarray) -> None:
    """Copy the first box into ``out`` (ROW,) and remove it (the caller decrements size)."""
    for k in range(ROW):
        out[k] = heap[0, k]
    last = size - 1
    for k in range(ROW):
        heap[0, k] = heap[last, k]
    i = 0
    while True:
        left = 2 * i + 1
        if left >= last:
            break
        best = left
        right = left + 1
        if right < last and _before(heap, right, left):
            best = right
        if not _before(heap, best, i):
            break
        _swap(heap, i, best)
        i = best
